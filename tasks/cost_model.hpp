#pragma once
// What the method's tasks cost before they run: particles, time steps and CPU-seconds of one
// core per task, for `millflow estimate`, the dry run and the progress line's ETA. The figures
// and how they were calibrated: docs/cost_model.md.
//
// A task's CPU time is particles x steps / throughput, the throughput in particle-steps per
// CPU-second of the scene it runs:
//   macro        balls of the mill set-up (dem::balls_per_class) x the steps of its schedule:
//                settle_time / dt + (warm-up + measured revolutions) x 2 pi / (omega dt), with
//                dt = the shortest ball-ball (lightest pair) or ball-liner (lightest ball) contact
//                duration / dem.steps_per_collision, as the run sets it;
//   shear_cell   media N_m = phi_m A H / (pi d^3 / 6) and powder N_p = U (1 - phi_m) A H
//                phi_bed / (pi d_p^3 / 6) (dem/shear_cell.hpp; plus the wall balls of a walled
//                cell) x the steps of compaction and of shear; dt = the shortest contact
//                duration of the pairs present, after the stiffness policy at the site's normal
//                stress and shear rate (tasks::apply_stiffness_policy) / steps_per_collision.
//                Shear steps: the strain over (gdot dt), between the least the protocol runs
//                (warmup_strain + measure_strain) and its caps (max_warmup_strain + the larger
//                of measure_strain and convergence/max_strain). Compaction: the loose placement
//                closed at the barostat's speed limit, the population's compaction distance
//                (dem::ShearCellPopulation; the steps a cell's progress expects,
//                dem::ShearCell::expected_compaction_steps), at kCompactionSpeedup times the
//                cell's throughput.
// The site of a cell is the sites task's once it is known. Before, the typical site of the
// cell's region in a mill of that diameter, fill and speed: shear rate = a x omega and normal
// stress = b x rho_media x g x D x J, a and b per region measured on quick.json's sites.
// average, sites, upscale and report have no model (seconds each; the ETA takes their kind's
// mean task time).
#include <array>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/task.hpp"

namespace millflow::tasks {

// Particle-steps per CPU-second of one core at 1 thread, each from a measurement
// (docs/cost_model.md gives them all; docs/benchmarks.md the benches).
//
// A mill charge: the example campaigns' own macro runs (their contacts last 0.5 ms, dt 25 us),
// each timed in the same hour as bench_dem's mill_1m and scaled by mill_1m's 12.39 M of 5
// December (the host's speed moves by up to 2.5x from day to day): quick.json's 726-ball runs at
// 0.61 of mill_1m, 7.6 M on that scale (its 415-ball runs 0.67); cement_ball_mill.json's 11,835-
// ball run (4 m, 24 lifters; shortened to half a revolution of warm-up and half measured; its
// measured phase) at 0.53, 6.6 M. bench_dem's mills, the figures
// until then (12.6 M and 9.40 M), have contacts of 0.1 ms: stiffer than the campaigns', they
// cost less per particle-step (docs/cost_model.md, "7 December: the macro runs at the campaigns'
// own contacts"). A larger charge walks more memory per step.
// Between the two ball counts the cost per particle-step is interpolated in log(balls); below and
// above, the nearer figure.
inline constexpr double kMacroThroughput = 7.6e6;
inline constexpr double kMacroBalls = 726.0;
inline constexpr double kLargeMillThroughput = 6.6e6;
inline constexpr double kLargeMillBalls = 11835.0;
// A shear cell of balls only: quick.json's own 131-ball cell at its site bulk-0 (2.10 1/s,
// 7.62 kPa; `millflow cell`), the CPU time of 2 more strains measured (76,190 steps), timed at
// one thread beside mill_1m in 5 rounds and scaled by mill_1m's 12.39 M: 9.3 M (12.3 M until 7
// December, from the first calibration's whole run, "7.3 M loaded x 687 / 1158"). The cement
// campaign's 303-ball cell at the bench's dense site (bench_cells' cement_load00, 1.77 contacts
// per particle) runs 7.8 M once scaled: its 180 load-0 cells cost about 1.2 times what this
// figure gives them. Since the pair pass runs its contacts in force four at a time in lanes, the
// same cell runs 1.165x the build the figure was made with (the median of 12 paired whole runs;
// cement_load00 1.173x in 12 rounds): 10.8 M (docs/cost_model.md, "7 December (night)").
inline constexpr double kMediaCellThroughput = 10.8e6;
// A shear cell of balls and powder: a step costs more as the powder's contacts grow, with the
// powder load U and with how fine the powder is (d_p / d). Three families of powder size, each at
// the loads kPowderLoads, at the stiffness a campaign's cell runs: the contacts the stiffness
// policy raises at the site (tasks::apply_stiffness_policy; docs/cost_model.md gives every
// figure's run):
// - fine, 0.125 d (the cement campaign's): bench_cells' cement_load05, cement_load10 and
//   cement_load15 (38,322 to 114,359 particles), timed at the campaign file's contacts (steady,
//   quiet machine: 12.5 M, 5.28 M, 4.18 M), times the median ratio of the same cell at the
//   policy's stiffness to it, timed in the same rounds: 1.97 at U = 0.5 (8 rounds), 2.02 at U = 1
//   and 1.22 at U = 1.5 (5 rounds each; 0.055, 0.25 and 1.28 contacts per particle against 0.32,
//   1.49 and 2.22: up to U = 1 the powder at the policy's stiffness holds no network of its own);
// - 0.25 d: bench_cells' cement_load05_d025, 10_d025 and 15_d025 (5,055 to 14,560 particles) at
//   the file's contacts, the fine family's figure at each load times the median ratio of the two
//   cells' throughputs timed in the same rounds (the host's speed varies from hour to hour)
//   (15.0 M, 11.3 M, 6.60 M), times the policy's gain at each load (3 rounds: 1.30, 1.36, 1.39);
// - coarse, 0.5 d (quick.json's): quick.json's own 647-particle cell at load 1 (7.6 M loaded x
//   687 / 1158 = 12.8 M) and cement_load05 agree at 12.5 M, taken up to load 1; at 1.5 the figure
//   at 1 times what bench_cells' cement_load15_d05 and 10_d05 gave in the same rounds. At the
//   benches' site the policy leaves this powder's contacts as the file gives them (the same
//   time step; 0.99-1.01 of the file's throughput in 5 rounds).
// Between the loads, and between the families in log(d_p / d), the cost per particle-step is
// interpolated; outside them, the nearer figure. Across the sites up to I = 0.16, at the policy's
// stiffness, a cell's figure moved by less than 6% on the 0.25 d powder (docs/cost_model.md,
// "7 December: the cells at the campaign's own sites, and at their own stiffness"), and at the
// shoulder's I = 0.40 it ran 1.01-1.27x faster (fewer contacts; the fine powder at load 0.5
// 0.87x, about 0.1% of the cement campaign), so one figure serves every site. The fine gains,
// timed again over 1,000 steps with the contact store kept in pair order, came out the same
// (1.86, 2.04, 1.23; "7 December (midday)"). Since the drift, the kicks and the sleeping pairs'
// test run on four lanes the fine load-0.5 cell runs 1.15-1.25x faster than its figure (about 1% of
// the cement campaign; not raised, "7 December (afternoon)"); with the pair pass on one register
// per 3-vector too, the load-1 cell at the policy's stiffness ran 1.058x the build its figure was
// made with: 11.3 M, was 10.7 M ("7 December (evening)"); load 1.5 not timed again. With a
// block's contacts in force four at a time in lanes (7 December, night) the fine cells ran no
// faster beyond the noise and keep their figures; the 0.25 d cells at the policy's stiffness ran
// 1.057, 1.063 and 1.095x the build before (8 rounds each), quick.json's own coarse cell at load 1
// 1.151x (6 paired whole runs) and cement_load15_d05 1.160x (8 rounds): the 0.25 d figures and the
// coarse ones times those gains (the earlier builds' gains on these two families not taken in,
// so their figures stay on the side of cost; "7 December (night)").
inline constexpr std::array<double, 3> kPowderLoads = {0.5, 1.0, 1.5};
struct PowderFamily {
  double diameter_ratio = 0.0;            // d_p / d
  std::array<double, 3> throughput = {};  // at kPowderLoads
};
inline constexpr std::array<PowderFamily, 3> kPowderFamilies = {{
    {.diameter_ratio = 0.125, .throughput = {24.6e6, 11.3e6, 5.10e6}},
    {.diameter_ratio = 0.25, .throughput = {20.6e6, 16.4e6, 10.1e6}},
    {.diameter_ratio = 0.5, .throughput = {14.4e6, 14.4e6, 13.2e6}},
}};
// A cell's compaction runs this many times its cell's throughput above (the bed is loose for
// most of it): the median of 1.68, 2.14 and 1.95 measured on the cement campaign's cell at
// loads 0.5, 1 and 1.5 (per the model's compaction steps, which came within 0.87-1.08 of those
// taken; docs/cost_model.md).
inline constexpr double kCompactionSpeedup = 1.95;

// The throughputs above as the model uses them: a macro run of `balls`, a cell of balls only
// (powder_load 0) or with powder at `powder_load` of `powder_diameter_ratio` (d_p / d).
double macro_throughput(double balls);
double cell_throughput(double powder_load, double powder_diameter_ratio);

struct TaskCost {
  double particles = 0.0;
  double steps = 0.0;          // the least the task runs
  double steps_at_caps = 0.0;  // the most (= steps but for shear cells' strain caps)
  double core_seconds = 0.0;   // at `steps`
  double core_seconds_at_caps = 0.0;
};

// A macro run of macro-task parameters (tasks::macro_params).
struct MacroRunSize {
  std::size_t balls = 0;
  double time_step_s = 0.0;
  double steps = 0.0;
};
MacroRunSize macro_run_size(const nlohmann::json& macro_params);
TaskCost macro_cost(const nlohmann::json& macro_params);

// The typical site of a region (one of /sites/regions) in the mill of macro-task parameters, as
// a site JSON {shear_rate_per_s, normal_stress_pa}.
nlohmann::json typical_site(const nlohmann::json& macro_params, const std::string& region);

// A shear cell of shear_cell-task parameters at a site ({shear_rate_per_s, normal_stress_pa}).
struct ShearCellSize {
  std::size_t media = 0, powder = 0, wall_balls = 0;
  // The setup's U and d_p / d: the throughput's keys.
  double powder_load = 0.0;
  double powder_diameter_ratio = 0.0;
  double time_step_s = 0.0;
  double compaction_steps = 0.0;
  double shear_steps = 0.0, shear_steps_at_caps = 0.0;
};
ShearCellSize shear_cell_size(const nlohmann::json& cell_params, const nlohmann::json& site);
TaskCost shear_cell_cost(const nlohmann::json& cell_params, const nlohmann::json& site);

// A task of the DAG: macro and shear_cell tasks (a cell from its sites task's result when known,
// else from its region's typical site; a slot without a usable site costs nothing); none for
// the other kinds.
std::optional<TaskCost> task_cost(const engine::TaskSpec& spec, const engine::TaskLookup& lookup);

// Gives the macro and shear_cell kinds their cost model (CPU-seconds midway between the least
// and the caps).
void register_cost_models(engine::KindRegistry& kinds);

// Per kind over a plan's tasks: how many, how many have an estimate, particles and steps per
// task (least and most) and CPU-seconds in all (least and at the caps).
struct KindEstimate {
  int tasks = 0;
  int estimated = 0;
  int sized = 0;  // of them, those that step particles (the ranges below are theirs)
  double particles_min = 0.0, particles_max = 0.0;
  double steps_min = 0.0, steps_max = 0.0;
  double core_seconds = 0.0, core_seconds_at_caps = 0.0;
  double longest_task_s = 0.0;  // CPU-seconds of the costliest task at its caps
};
// `counted` (all when empty) picks the tasks counted; the others are only looked up (the tasks
// above a cell). `result_of` (none when empty) gives a task's stored result by key, or null: a
// cell whose sites task has one is priced at its own site, the others at their region's typical
// site.
std::map<std::string, KindEstimate> estimate_plan(
    const std::vector<engine::TaskSpec>& tasks,
    const std::function<bool(const engine::TaskSpec&)>& counted = {},
    const std::function<const nlohmann::json*(const std::string& key)>& result_of = {});
// The table `millflow estimate` prints, then per kind with a model a Slurm time limit (twice
// its costliest task at the caps on one CPU, in whole minutes) as an /executor/slurm/per_kind
// block to paste into the campaign.
std::string format_estimate(const std::map<std::string, KindEstimate>& by_kind);

}  // namespace millflow::tasks
