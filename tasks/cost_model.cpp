#include "tasks/cost_model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "dem/material.hpp"
#include "dem/mill_setup.hpp"
#include "method/sites.hpp"
#include "tasks/macro_setup.hpp"
#include "tasks/shear_cell.hpp"
#include "util/sphere.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

double contact_duration(const dem::InteractionSpec& spec, double effective_mass) {
  return dem::collision_duration(spec.normal_stiffness, effective_mass,
                                 dem::damping_ratio_for_restitution(spec.restitution));
}

// A region's typical site relative to its mill: shear rate / omega (the harmonic mean: a cell's
// steps go as 1 / shear rate) and normal stress / (rho_media g D J) (the geometric mean), over
// the 38 sites of quick.json's four macro runs (D = 1 m, J = 0.2 and 0.35, 65% and 80% of
// critical; docs/cost_model.md). Any other region: the means over all 38.
struct RegionScale {
  const char* region;
  double shear_rate_per_omega;
  double normal_stress_per_rho_g_d_j;
};
constexpr std::array<RegionScale, 6> kRegionScales{{
    {"near_liner", 0.421, 0.177},
    {"toe", 1.90, 0.0845},
    {"shoulder", 1.68, 0.0096},
    {"cascading", 2.46, 0.116},
    {"bulk", 1.19, 0.188},
    {"", 1.03, 0.0885},
}};

const RegionScale& region_scale(const std::string& region) {
  for (const RegionScale& scale : kRegionScales)
    if (region == scale.region) return scale;
  return kRegionScales.back();
}

// A cell's particle-steps at a throughput of its scene.
TaskCost cell_task_cost(const ShearCellSize& size) {
  TaskCost cost;
  cost.particles = static_cast<double>(size.media + size.powder + size.wall_balls);
  cost.steps = size.compaction_steps + size.shear_steps;
  cost.steps_at_caps = size.compaction_steps + size.shear_steps_at_caps;
  const double throughput =
      cell_throughput(size.powder > 0 ? size.powder_load : 0.0, size.powder_diameter_ratio);
  const double compaction =
      cost.particles * size.compaction_steps / (kCompactionSpeedup * throughput);
  cost.core_seconds = compaction + cost.particles * size.shear_steps / throughput;
  cost.core_seconds_at_caps = compaction + cost.particles * size.shear_steps_at_caps / throughput;
  return cost;
}

// The macro task above a task (through its upstream chain), or null.
const engine::TaskSpec* macro_above(const engine::TaskSpec& spec,
                                    const engine::TaskLookup& lookup) {
  for (const auto& key : spec.upstream) {
    const engine::KnownTask above = lookup(key);
    if (above.spec == nullptr) continue;
    if (above.spec->kind == "macro") return above.spec;
    if (const engine::TaskSpec* found = macro_above(*above.spec, lookup)) return found;
  }
  return nullptr;
}

std::optional<TaskCost> cell_cost_in_dag(const engine::TaskSpec& spec,
                                         const engine::TaskLookup& lookup) {
  const json& slot = spec.params.at("slot");
  const engine::KnownTask sites = lookup(spec.upstream.at(0));
  if (sites.result != nullptr) {
    const SlotSite found = find_slot_site(*sites.result, slot);
    if (!found.skipped.empty()) return TaskCost{};
    return shear_cell_cost(spec.params, found.site);
  }
  const engine::TaskSpec* macro = macro_above(spec, lookup);
  if (macro == nullptr) return std::nullopt;
  return shear_cell_cost(spec.params,
                         typical_site(macro->params, slot.at("region").get<std::string>()));
}

std::string engineering(double value) {
  if (value >= 1e9) return fmt::format("{:.3g} G", value / 1e9);
  if (value >= 1e6) return fmt::format("{:.3g} M", value / 1e6);
  if (value >= 1e4) return fmt::format("{:.3g} k", value / 1e3);
  return fmt::format("{:.0f}", value);
}

std::string hours(double seconds) {
  const double value = seconds / 3600.0;
  // Whole hours from 100 up, but no run of digits for a campaign nobody could run.
  return value >= 100.0 && value < 1e7 ? fmt::format("{:.0f}", value)
                                       : fmt::format("{:.3g}", value);
}

std::string range(double low, double high) {
  if (engineering(low) == engineering(high)) return engineering(low);
  return engineering(low) + " - " + engineering(high);
}

// How far x lies of the way from `from` to `to` (0 at from, 1 at to; not clamped), in x and in
// log(x).
double fraction(double x, double from, double to) {
  return (x - from) / (to - from);
}
double log_fraction(double x, double from, double to) {
  return std::log(x / from) / std::log(to / from);
}

// The throughput a fraction t (clamped to [0, 1]) of the way from `from` to `to`, interpolating
// the cost per particle-step (1 / throughput), not the throughput.
double throughput_between(double t, double from, double to) {
  t = std::clamp(t, 0.0, 1.0);
  return 1.0 / ((1.0 - t) / from + t / to);
}

// The throughput of values[k] measured at grid[k] (ascending), at x: the cost per particle-step
// interpolated in position(x, from, to) between the two points around x; outside, the nearer.
template <class Values, class Position>
double throughput_on_grid(double x, const std::array<double, 3>& grid, const Values& values,
                          Position position) {
  std::size_t k = 1;
  while (k + 1 < grid.size() && x > grid[k]) ++k;
  return throughput_between(position(x, grid[k - 1], grid[k]), values(k - 1), values(k));
}

// The powder families' sizes, d_p / d: the grid across them.
constexpr std::array<double, 3> kPowderRatios = [] {
  std::array<double, 3> ratios{};
  for (std::size_t f = 0; f < ratios.size(); ++f) ratios[f] = kPowderFamilies[f].diameter_ratio;
  return ratios;
}();

}  // namespace

double macro_throughput(double balls) {
  return throughput_between(log_fraction(balls, kMacroBalls, kLargeMillBalls), kMacroThroughput,
                            kLargeMillThroughput);
}

double cell_throughput(double powder_load, double powder_diameter_ratio) {
  if (powder_load <= 0.0) return kMediaCellThroughput;
  const auto at_load = [&](std::size_t family) {
    const std::array<double, 3>& measured = kPowderFamilies[family].throughput;
    return throughput_on_grid(
        powder_load, kPowderLoads, [&](std::size_t k) { return measured[k]; }, fraction);
  };
  return throughput_on_grid(powder_diameter_ratio, kPowderRatios, at_load, log_fraction);
}

MacroRunSize macro_run_size(const json& macro_params) {
  const method::MacroSettings settings = macro_settings(macro_params, "");
  const dem::MillSetup& mill = settings.mill;
  MacroRunSize size;
  const auto counts = dem::balls_per_class(mill);
  const auto classes = dem::ball_size_classes(mill);
  double smallest = std::numeric_limits<double>::infinity();
  for (std::size_t c = 0; c < counts.size(); ++c) {
    size.balls += counts[c];
    if (counts[c] > 0) smallest = std::min(smallest, classes[c].diameter);
  }
  const double lightest = mill.media.density * util::sphere_volume_of_diameter(smallest);
  const double contact = std::min(contact_duration(mill.ball_ball, 0.5 * lightest),
                                  contact_duration(mill.ball_liner, lightest));
  size.time_step_s = contact / settings.steps_per_collision;
  const double omega =
      mill.speed_fraction *
      dem::critical_speed(2.0 * mill.shell.radius, dem::mean_ball_diameter(mill), mill.gravity);
  const double revolutions = settings.warmup_revolutions + settings.measure_revolutions;
  size.steps =
      (settings.settle_time + revolutions * 2.0 * std::numbers::pi / omega) / size.time_step_s;
  return size;
}

TaskCost macro_cost(const json& macro_params) {
  const MacroRunSize size = macro_run_size(macro_params);
  TaskCost cost;
  cost.particles = static_cast<double>(size.balls);
  cost.steps = cost.steps_at_caps = size.steps;
  cost.core_seconds = cost.core_seconds_at_caps =
      cost.particles * cost.steps / macro_throughput(cost.particles);
  return cost;
}

json typical_site(const json& macro_params, const std::string& region) {
  const method::MacroSettings settings = macro_settings(macro_params, "");
  const dem::MillSetup& mill = settings.mill;
  const double diameter = 2.0 * mill.shell.radius;
  const double omega = mill.speed_fraction *
                       dem::critical_speed(diameter, dem::mean_ball_diameter(mill), mill.gravity);
  const RegionScale& scale = region_scale(region);
  return method::CellDrive{.shear_rate = scale.shear_rate_per_omega * omega,
                           .normal_stress = scale.normal_stress_per_rho_g_d_j * mill.media.density *
                                            mill.gravity * diameter * mill.fill};
}

ShearCellSize shear_cell_size(const json& cell_params, const json& site) {
  dem::ShearCellSetup setup = shear_cell_setup(cell_params, site, "");
  apply_stiffness_policy(cell_params, setup);
  const double d = setup.media_diameter, d_p = setup.powder_diameter_ratio * d;
  const dem::ShearCellPopulation population = dem::shear_cell_population(setup);
  ShearCellSize size;
  size.media = population.media;
  size.powder = population.powder;
  size.powder_load = setup.powder_load;
  size.powder_diameter_ratio = setup.powder_diameter_ratio;
  size.wall_balls = population.wall_balls;
  const bool walls = setup.boundary == dem::ShearCellSetup::Boundary::RoughWalls;
  const double media_mass = setup.media.density * util::sphere_volume_of_diameter(d);
  const double powder_mass = setup.powder.density * util::sphere_volume_of_diameter(d_p);
  const double media_contact = contact_duration(setup.media_media, 0.5 * media_mass);
  double shortest = media_contact;
  if (walls) shortest = std::min(shortest, contact_duration(setup.media_media, media_mass));
  if (size.powder > 0) {
    shortest = std::min(
        {shortest,
         contact_duration(setup.media_powder, dem::effective_mass(media_mass, powder_mass)),
         contact_duration(setup.powder_powder, 0.5 * powder_mass)});
    if (walls) shortest = std::min(shortest, contact_duration(setup.media_powder, powder_mass));
  }
  size.time_step_s = shortest / setup.steps_per_collision;

  const json& cell = cell_params.at("shear_cell");
  const double strain_step = setup.shear_rate * size.time_step_s;
  size.shear_steps =
      (cell.at("warmup_strain").get<double>() + cell.at("measure_strain").get<double>()) /
      strain_step;
  size.shear_steps_at_caps = (cell.at("max_warmup_strain").get<double>() +
                              std::max(cell.at("measure_strain").get<double>(),
                                       cell.at("convergence").at("max_strain").get<double>())) /
                             strain_step;
  // Compaction: the barostat (or the servo) closes the loose fill at its speed limit.
  size.compaction_steps = population.compaction_distance /
                          dem::boundary_speed_limit(setup, media_contact) / size.time_step_s;
  return size;
}

TaskCost shear_cell_cost(const json& cell_params, const json& site) {
  return cell_task_cost(shear_cell_size(cell_params, site));
}

std::optional<TaskCost> task_cost(const engine::TaskSpec& spec, const engine::TaskLookup& lookup) {
  if (spec.kind == "macro") return macro_cost(spec.params);
  if (spec.kind == "shear_cell") return cell_cost_in_dag(spec, lookup);
  return std::nullopt;
}

void register_cost_models(engine::KindRegistry& kinds) {
  for (const char* kind : {"macro", "shear_cell"}) {
    kinds.set_cost_model(kind, [](const engine::TaskSpec& spec, const engine::TaskLookup& lookup) {
      const auto cost = task_cost(spec, lookup);
      return cost ? std::optional<double>(0.5 * (cost->core_seconds + cost->core_seconds_at_caps))
                  : std::nullopt;
    });
  }
}

std::map<std::string, KindEstimate> estimate_plan(
    const std::vector<engine::TaskSpec>& tasks,
    const std::function<bool(const engine::TaskSpec&)>& counted,
    const std::function<const json*(const std::string& key)>& result_of) {
  std::map<std::string, const engine::TaskSpec*> by_key;
  for (const auto& spec : tasks) by_key[spec.key] = &spec;
  const engine::TaskLookup lookup = [&by_key, &result_of](const std::string& key) {
    const auto found = by_key.find(key);
    if (found == by_key.end()) return engine::KnownTask{};
    return engine::KnownTask{found->second, result_of ? result_of(key) : nullptr};
  };
  std::map<std::string, KindEstimate> by_kind;
  for (const auto& spec : tasks) {
    if (counted && !counted(spec)) continue;
    KindEstimate& kind = by_kind[spec.kind];
    ++kind.tasks;
    const auto cost = task_cost(spec, lookup);
    if (!cost) continue;
    ++kind.estimated;
    // A cell whose slot has no site (its sites are stored) steps nothing: not in the ranges.
    if (cost->particles > 0.0) {
      if (kind.sized++ == 0) {
        kind.particles_min = kind.particles_max = cost->particles;
        kind.steps_min = cost->steps;
        kind.steps_max = cost->steps_at_caps;
      }
      kind.particles_min = std::min(kind.particles_min, cost->particles);
      kind.particles_max = std::max(kind.particles_max, cost->particles);
      kind.steps_min = std::min(kind.steps_min, cost->steps);
      kind.steps_max = std::max(kind.steps_max, cost->steps_at_caps);
    }
    kind.core_seconds += cost->core_seconds;
    kind.core_seconds_at_caps += cost->core_seconds_at_caps;
    kind.longest_task_s = std::max(kind.longest_task_s, cost->core_seconds_at_caps);
  }
  return by_kind;
}

std::string format_estimate(const std::map<std::string, KindEstimate>& by_kind) {
  std::string text = fmt::format("{:<12} {:>6} {:>20} {:>22} {:>24}\n", "kind", "tasks",
                                 "particles per task", "steps per task", "core-hours");
  double total = 0.0, total_at_caps = 0.0;
  int tasks = 0;
  for (const auto& [kind, estimate] : by_kind) {
    tasks += estimate.tasks;
    if (estimate.estimated == 0) {
      text += fmt::format("{:<12} {:>6} {:>20} {:>22} {:>24}\n", kind, estimate.tasks, "-", "-",
                          "small (not modelled)");
      continue;
    }
    total += estimate.core_seconds;
    total_at_caps += estimate.core_seconds_at_caps;
    text +=
        fmt::format("{:<12} {:>6} {:>20} {:>22} {:>24}\n", kind, estimate.tasks,
                    range(estimate.particles_min, estimate.particles_max),
                    range(estimate.steps_min, estimate.steps_max),
                    hours(estimate.core_seconds) + " - " + hours(estimate.core_seconds_at_caps));
  }
  text += fmt::format("{:<12} {:>6} {:>20} {:>22} {:>24}\n", "total", tasks, "", "",
                      hours(total) + " - " + hours(total_at_caps));
  json per_kind = json::object();
  for (const auto& [kind, estimate] : by_kind) {
    if (estimate.estimated == 0) continue;
    const double minutes = std::max(1.0, std::ceil(2.0 * estimate.longest_task_s / 60.0));
    per_kind[kind] = {{"time_limit", fmt::format("{:.0f}", minutes)}};
  }
  if (!per_kind.empty())
    text += "Slurm time limits, twice the costliest task at the caps on one CPU (minutes): " +
            json{{"per_kind", per_kind}}.dump() + "\n";
  return text;
}

}  // namespace millflow::tasks
