#pragma once
// One hand-made sweep point for the upscale and report tests: a macro run, its sites (toe-0,
// bulk-0, and bulk-1 whose cells were skipped) weighted by volume, the macro dissipation of its
// regions under two rule sets, and shear cells at loads 0 and 1 with round values (media solid
// fraction 0.5, powder 0.2 at load 1; without standard errors, as cells before they had them;
// the quantities the upscaling does not read left at zero).
#include <nlohmann/json.hpp>
#include <string>
#include <tuple>
#include <vector>

#include "engine/task.hpp"
#include "method/cell_result.hpp"
#include "method/macro_result.hpp"
#include "method/sites.hpp"
#include "method/sites_result.hpp"
#include "tasks/upscale.hpp"

namespace millflow::tasks::testing {

using nlohmann::json;

inline method::Site site(const std::string& id, const std::string& region, double weight,
                         double macro_shear_stress) {
  return method::Site{.site_id = id,
                      .region = region,
                      .x = 0.1,
                      .y = -0.2,
                      .weight_m3 = weight,
                      .solid_volume_m3 = 0.6 * weight,
                      .shear_rate = 5.0,
                      .normal_stress = 2000.0,
                      .shear_stress = macro_shear_stress};
}

struct CellValues {
  double power_density, powder_dissipation, media_media, wall_media, shear_stress;
  std::vector<double> media_counts, powder_counts;
  double media_collision_rate = 1e6, media_collision_count = 1e4;
};

inline engine::TaskInput cell(const std::string& site_id, double load, const CellValues& v) {
  constexpr auto media_media = static_cast<std::size_t>(dem::ContactType::MediaMedia);
  constexpr auto wall_media = static_cast<std::size_t>(dem::ContactType::WallMedia);
  method::CellResult result{.site = method::Site{.site_id = site_id, .region = "any"},
                            .slot = {{"region", "any"}, {"index", 0}},
                            .powder_load = load,
                            .duration_s = 2.0,
                            .volume_m3 = 1e-4,
                            .shear_stress_pa = v.shear_stress,
                            .normal_stress_pa = 2100.0 + load,  // the site asks 2000 Pa
                            .media_solid_fraction = 0.5,
                            .powder_solid_fraction = load > 0.0 ? 0.2 : 0.0,
                            .power_density_w_m3 = v.power_density,
                            .powder_dissipation_w_m3 = v.powder_dissipation,
                            .media_collisions = {.count = v.media_collision_count,
                                                 .rate_per_m3_s = v.media_collision_rate},
                            .spectrum_bin_edges_j = {1e-6, 1e-5, 1e-4},
                            .media_spectrum = {.counts = v.media_counts},
                            .powder_spectrum = {.counts = v.powder_counts},
                            .steady = true,
                            .converged = true};
  result.dissipation_w_m3[media_media] = v.media_media;
  result.dissipation_w_m3[wall_media] = v.wall_media;
  return {.key = site_id + "@" + std::to_string(load),
          .kind = "shear_cell",
          .result = result,
          .artifacts = {}};
}

// A stiff cell of /shear_cell/stiffness/sensitivity (tasks/shear_cell.hpp) at a site.
inline engine::TaskInput stiff_cell(const std::string& site_id, double load, const CellValues& v,
                                    double factor) {
  engine::TaskInput stiff = cell(site_id, load, v);
  stiff.key = site_id + "-stiff@" + std::to_string(load);
  stiff.result["stiffness_factor"] = factor;
  return stiff;
}

inline engine::TaskInput skipped_cell(const std::string& site_id, double load) {
  return {.key = site_id + "-skipped@" + std::to_string(load),
          .kind = "shear_cell",
          .result = method::CellResult{.slot = {{"region", "any"}, {"index", 0}},
                                       .powder_load = load,
                                       .skipped = "no site"},
          .artifacts = {}};
}

inline std::vector<engine::TaskInput> point_inputs(double fill = 0.3, double speed = 0.75,
                                                   double power_scale = 1.0) {
  method::MacroResult macro;
  macro.fill = fill;
  macro.speed_fraction = speed;
  macro.ball_mass_kg = 100.0;
  macro.mill.radius_m = 0.5;
  macro.mill.length_m = 0.1;
  macro.power.mean_w = 1000.0 * power_scale;
  macro.power.kw_per_t_balls = 10.0 * power_scale;
  std::vector<engine::TaskInput> inputs;
  inputs.push_back({.key = "macro-key", .kind = "macro", .result = macro, .artifacts = {}});
  inputs.push_back(
      {.key = "average-key", .kind = "average", .result = json::object(), .artifacts = {}});
  method::SitesResult sites{
      .weight_by = method::WeightBasis::volume,
      .sites = {site("toe-0", "toe", 0.002, 800.0), site("bulk-0", "bulk", 0.003, 500.0),
                site("bulk-1", "bulk", 0.001, 400.0)},
      .fill = fill,
      .speed_fraction = speed,
      .average_task = "average-key"};
  method::RuleSet defaults{.name = "default"}, wide_toe{.name = "wide"};
  for (const auto& [name, dissipation, wide] :
       {std::tuple{"toe", 2.0, 4.0}, {"bulk", 3.0, 1.0}, {"cascading", 1.0, 1.0}}) {
    sites.regions.push_back({.name = name, .dissipation_w = dissipation});
    defaults.regions.push_back({.name = name, .dissipation_w = dissipation});
    wide_toe.regions.push_back({.name = name, .dissipation_w = wide});
  }
  sites.rule_sets = {defaults, wide_toe};
  inputs.push_back({.key = "sites-key", .kind = "sites", .result = sites, .artifacts = {}});
  inputs.push_back(
      cell("toe-0", 1.0, {1000.0, 400.0, 250.0, 50.0, 950.0, {10, 0}, {5, 5}, 1e6, 1e4}));
  inputs.push_back(
      cell("bulk-0", 1.0, {500.0, 100.0, 200.0, 0.0, 520.0, {2, 2}, {0, 4}, 4e5, 4e3}));
  inputs.push_back(
      cell("toe-0", 0.0, {800.0, 0.0, 500.0, 100.0, 880.0, {20, 1}, {0, 0}, 1.5e6, 1.5e4}));
  inputs.push_back(cell("bulk-0", 0.0, {400.0, 0.0, 350.0, 0.0, 450.0, {4, 0}, {0, 0}, 5e5, 5e3}));
  inputs.push_back(skipped_cell("bulk-1", 1.0));
  inputs.push_back(skipped_cell("bulk-1", 0.0));
  return inputs;
}

inline json upscale(const std::vector<engine::TaskInput>& inputs, double load,
                    bool include_unsteady = false) {
  const json params = {{"powder_load", load},
                       {"upscale", {{"include_unsteady", include_unsteady}}},
                       {"media_density_kg_m3", 8000.0},
                       {"powder_density_kg_m3", 2000.0}};
  engine::TaskContext context{.key = "upscale-key",
                              .params = params,
                              .inputs = inputs,
                              .work_dir = {},
                              .threads = 1,
                              .stop = {},
                              .progress = [](double, std::string_view) {},
                              .log = [](std::string_view) {}};
  return run_upscale(context).result;
}

}  // namespace millflow::tasks::testing
