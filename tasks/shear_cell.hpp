#pragma once
// The `shear_cell` task kind (docs/method.md, step 3): one microscale shear cell per site
// slot and powder load.
//
// Parameters: tasks::shear_cells_params (shear_cell, materials, interactions, media, dem.seed) plus
// slot {region, index}: the site "<region>-<index>" of the sites task, the one upstream task.
// The planner knows the regions and the sites per region but not which sites exist, so a slot may
// be empty (a region with fewer cells than sites, or none) or its site unusable (shear rate or
// normal stress not positive); the task then finishes at once with
//   {skipped: reason, slot, powder_load}.
// Otherwise a dem::ShearCell at the site's shear rate and normal stress. Translation:
//   media diameter   the mass-weighted mean of /media (as the macro run's);
//   contacts         tasks::interaction_spec of the campaign interaction of each pair; a
//                    collision-time stiffness is for the pair's two reference particles (media
//                    balls of that diameter, powder grains of diameter_ratio x it);
//   boundary         "walls" -> rough walls, "lees_edwards" -> Lees-Edwards;
//   servo gain       /shear_cell/stress_control/gain;
//   time step        t_c / /shear_cell/steps_per_collision (not /dem's: the cells' energy
//                    balance needs finer steps than the macro runs, see campaigns/README.md);
//   seed             tasks::macro_seed(dem.seed, task key);
//   stiffness        /shear_cell/stiffness (apply_stiffness_policy below), logged and stored in
//                    the result as stiffness {by pair: k_n_n_m, kappa, given_n_m,
//                    static_bound_n_m, impact_bound_n_m}.
// Run: a dem::ShearCellRun of shear_cell_protocol (warm-up in windows of warmup_strain /
// kWarmupWindows until stationary or max_warmup_strain, then measure_strain measured and on to
// convergence up to convergence/max_strain). The stop token is polled every kStepsBetweenPolls
// steps (compaction runs whole); on a stop, and every /shear_cell/checkpoint_interval_s of wall
// time, the run is saved to cell.ckpt in the work directory (the format is beside
// dem::ShearCellRun), and the next attempt continues from it with the same bits. A checkpoint that
// cannot be read (truncated, altered, of another cell) is logged and removed, and the cell starts
// again from scratch. The file goes when the cell is done. Result JSON: see measurements_json, plus
// site (the sites task's entry), slot, powder_load, media_count, powder_count, wall_ball_count.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dem/shear_cell.hpp"
#include "dem/stiffness_policy.hpp"
#include "engine/task.hpp"

namespace millflow::tasks {

// Bump whenever the results of the same parameters change (tests/tasks/golden/shear_cell.json).
inline constexpr const char* kShearCellVersion = "7";
inline constexpr int kWarmupWindows = 4;
inline constexpr std::uint64_t kStepsBetweenPolls = 100;

// The site id of a slot: "<region>-<index>".
std::string slot_site_id(const nlohmann::json& slot);

// The site of a slot in a sites task's result, or the reason there is none to shear.
struct SlotSite {
  nlohmann::json site;  // null when there is no usable site
  std::string skipped;  // empty when `site` can drive a cell
};
SlotSite find_slot_site(const nlohmann::json& sites_result, const nlohmann::json& slot);

// The cell of a shear_cell task's parameters at a site. Throws engine::InvalidInput or
// nlohmann::json::exception for missing values, std::invalid_argument for unusable ones.
dem::ShearCellSetup shear_cell_setup(const nlohmann::json& params, const nlohmann::json& site,
                                     const std::string& task_key);

// The shear_cell block's stiffness policy (/shear_cell/stiffness, docs/shear_cells.md) applied to
// a setup: "overlap_bound" raises each pair's k_n (dem::apply_overlap_bound), "campaign" keeps
// them. Returns what was derived for the result's "stiffness" and the log.
std::vector<dem::PairStiffness> apply_stiffness_policy(const nlohmann::json& params,
                                                       dem::ShearCellSetup& setup);
nlohmann::json stiffness_json(const std::vector<dem::PairStiffness>& pairs);
std::string stiffness_log(const std::vector<dem::PairStiffness>& pairs,
                          const dem::ShearCellSetup& setup);

// The measurements in SI units: strain, duration_s, steps, *_shear_rate_per_s (target, bulk,
// nominal), wall_speed_m_s, wall_slip_m_s, gap_m, volume_m3, shear_stress_pa, normal_stress_pa,
// friction (tau / p_yy), friction_mean_pressure (tau / p), stresses {xx, yy, zz, xy, xz, yz,
// mean_pressure_pa, p_yy_pa} (compression positive), inertial_number (imposed rate in LE),
// inertial_number_measured_rate, media/powder/total solid_fraction, power_density_w_m3,
// dissipation_w_m3 {by contact type, total}, powder_dissipation_w_m3 (every type involving
// powder), collisions {by contact type, media, powder: count, rate_per_m3_s}, spectra
// {bin_edges_j, media, powder: dissipated energy histograms}, energy {work_in_j,
// kinetic_change_j, elastic_change_j, dissipated_j, stress_control_work_j (in work_in_j),
// balance_error}, steady_state {shear_stress_first_half_pa, shear_stress_second_half_pa,
// deviation, steady (the halves agree)}, steady (stationary and the halves agree),
// stationary_strain (null when the warm-up never passed the test), converged, standard_errors
// {friction, friction_mean_pressure, shear_stress_pa, normal_stress_pa, power_density_w_m3,
// powder_dissipation_w_m3, dissipation_w_m3 {by contact type, total}, blocks, batch_blocks},
// overlap {by contact type that touched: mean_fraction, p95_fraction, max_fraction,
// contact_samples}, overlap_{mean,p95,max}_fraction (the type with the largest p95; 0 without
// contacts), overlap_ok. docs/shear_cells.md gives the rules. The measured window's wall time and
// particle-steps per second go to the task's log only.
nlohmann::json measurements_json(const dem::ShearCellMeasurements& m);

// The warm-up and measurement of a shear_cell task's parameters.
dem::ShearCellProtocol shear_cell_protocol(const nlohmann::json& params);

// A cell that ran also leaves the artifact cell.vtp: its particles at the end of the measurement
// (dem::write_particles_vtp; media and powder told apart by "material"), for ParaView.
engine::TaskOutcome run_shear_cell(engine::TaskContext& context);

}  // namespace millflow::tasks
