#include "tasks/upscale.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "method/sites.hpp"
#include "method/sites_result.hpp"
#include "method/upscale.hpp"
#include "method/upscale_result.hpp"
#include "tasks/kinds.hpp"
#include "tasks/macro.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

const engine::TaskInput& only_input(const engine::TaskContext& context, const std::string& kind) {
  const engine::TaskInput* found = nullptr;
  for (const auto& input : context.inputs) {
    if (input.kind != kind) continue;
    if (found)
      throw std::invalid_argument(
          fmt::format("upscale {}: more than one {} input", context.key, kind));
    found = &input;
  }
  if (!found)
    throw std::invalid_argument(fmt::format("upscale {}: no {} input", context.key, kind));
  return *found;
}

// Why a finished cell does not count by default (empty when it does): tasks/upscale.hpp.
std::string left_out_reason(const method::CellResult& cell) {
  if (!cell.steady) return "not steady";
  if (!cell.converged) return "not converged";
  return {};
}

// The finished (not skipped) cells that count, at load U and at load 0, and the stiff cells at
// load U, by site id, and the cells left out or counted against their flags (the stiff ones
// apart, with the stiff cells' factor).
struct UsableCells {
  std::map<std::string, method::CellResult> loaded, baseline, stiff;
  std::vector<method::LeftOutCell> flagged, stiff_flagged;
  std::optional<double> stiffness_factor;
};

// The stiff cells' one factor; a second one throws (they come from one campaign setting).
void note_factor(UsableCells& cells, double factor, const std::string& task_key) {
  if (cells.stiffness_factor && *cells.stiffness_factor != factor)
    throw std::invalid_argument(
        fmt::format("upscale {}: stiff cells with factors {} and {}; re-plan the campaign",
                    task_key, *cells.stiffness_factor, factor));
  cells.stiffness_factor = factor;
}

UsableCells usable_cells(const engine::TaskContext& context, double load, bool include_unsteady) {
  UsableCells cells;
  for (const auto& input : context.inputs) {
    if (input.kind != "shear_cell") continue;
    const auto cell = input.result.get<method::CellResult>();
    if (!cell.skipped.empty()) continue;
    const double cell_load = cell.powder_load.get<double>();
    if (cell_load != load && cell_load != 0.0) continue;
    if (cell.stiffness_factor) note_factor(cells, *cell.stiffness_factor, context.key);
    const std::string id = cell.site.get<method::Site>().site_id;
    if (const std::string reason = left_out_reason(cell); !reason.empty()) {
      (cell.stiffness_factor ? cells.stiff_flagged : cells.flagged)
          .push_back({.site_id = id,
                      .powder_load = cell_load,
                      .reason = reason,
                      .counted = include_unsteady});
      if (!include_unsteady) continue;
    }
    if (cell.stiffness_factor) {
      cells.stiff[id] = cell;
      continue;
    }
    if (cell_load == load) cells.loaded[id] = cell;
    if (cell_load == 0.0) cells.baseline[id] = cell;
  }
  return cells;
}

const method::CellResult* cell_of(const std::map<std::string, method::CellResult>& cells,
                                  const std::string& site_id) {
  const auto found = cells.find(site_id);
  return found == cells.end() ? nullptr : &found->second;
}

std::optional<double> ratio_if(double numerator, double denominator) {
  return denominator > 0.0 ? std::optional(numerator / denominator) : std::nullopt;
}

// The figures of one region (or of all) under one method.
method::UpscaleFigures figures_of(const method::PowerSums& r, const method::Sum& total_powder) {
  const method::Ratio share = method::ratio(r.powder, total_powder);
  const method::Ratio cushioning = method::ratio(r.collisions, r.collisions_no_powder);
  const method::Ratio rate_factor = method::ratio(r.rate, r.rate_no_powder);
  const method::Ratio energy_factor = method::ratio(cushioning, rate_factor);
  // Without a counted site the powers are unknown, not 0 W.
  const auto counted = [&](std::optional<double> watts) {
    return r.sites > 0 ? watts : std::nullopt;
  };
  return {.sites = static_cast<std::size_t>(r.sites),
          .volume_m3 = r.volume,
          .solid_volume_m3 = r.solid_volume,
          .powder_power_w = counted(r.powder.value),
          .powder_power_w_se = counted(r.powder.standard_error()),
          .powder_power_share = share.value,
          .powder_power_share_se = share.standard_error,
          .media_power_w = counted(r.input.value - r.powder.value),
          .media_collision_power_w = counted(r.collisions.value),
          .media_collision_power_no_powder_w = counted(r.collisions_no_powder.value),
          .cushioning = cushioning.value,
          .cushioning_se = cushioning.standard_error,
          .cushioning_rate_factor = rate_factor.value,
          .cushioning_rate_factor_se = rate_factor.standard_error,
          .cushioning_energy_factor = energy_factor.value,
          .cushioning_energy_factor_se = energy_factor.standard_error};
}

// A ratio's relative shift, stiff / default - 1.
method::Ratio shift_of(const method::Ratio& r) {
  return {r.value ? std::optional(*r.value - 1.0) : std::nullopt, r.standard_error};
}

void put(const method::Ratio& r, std::optional<double>& value, std::optional<double>& se) {
  value = r.value;
  se = r.standard_error;
}

// The stiffness sensitivity of one region (or of all). Both cushionings share the default
// baselines, which cancel in their quotient: the shift is C_stiff(U) / C(U) - 1 over the same
// sites, with the loaded cells' errors alone.
method::StiffnessFigures stiffness_figures_of(const method::StiffnessSums& r) {
  method::StiffnessFigures f{.sites = static_cast<std::size_t>(r.normal.sites)};
  put(method::ratio(r.normal.collisions, r.normal.collisions_no_powder), f.cushioning,
      f.cushioning_se);
  put(method::ratio(r.stiff.collisions, r.stiff.collisions_no_powder), f.cushioning_stiff,
      f.cushioning_stiff_se);
  put(shift_of(method::ratio(r.stiff.collisions, r.normal.collisions)), f.cushioning_shift,
      f.cushioning_shift_se);
  const method::Ratio share = method::ratio(r.normal.powder, r.normal.input);
  const method::Ratio share_stiff = method::ratio(r.stiff.powder, r.stiff.input);
  put(share, f.powder_share, f.powder_share_se);
  put(share_stiff, f.powder_share_stiff, f.powder_share_stiff_se);
  put(shift_of(method::ratio(share_stiff, share)), f.powder_share_shift, f.powder_share_shift_se);
  return f;
}

// The stiff cells' comparison with the default ones at the sites that have both and a baseline
// (none without stiff cells).
std::optional<method::StiffnessSensitivity> stiffness_sensitivity(const method::SitesResult& sites,
                                                                  const UsableCells& cells) {
  if (!cells.stiffness_factor) return std::nullopt;
  std::map<std::string, method::StiffnessSums> by_region;
  for (const method::Site& site : sites.sites) {
    const method::CellResult* loaded = cell_of(cells.loaded, site.site_id);
    const method::CellResult* stiff = cell_of(cells.stiff, site.site_id);
    const method::CellResult* baseline = cell_of(cells.baseline, site.site_id);
    if (!loaded || !stiff || !baseline) continue;
    by_region[site.region].add(site, sites.weight_by, method::cell_figures(*loaded),
                               method::cell_figures(*stiff), method::cell_figures(*baseline));
  }
  method::StiffnessSensitivity result{.factor = *cells.stiffness_factor,
                                      .left_out_cells = cells.stiff_flagged};
  method::StiffnessSums all;
  for (const std::string& name : method::region_names()) {
    const auto found = by_region.find(name);
    if (found == by_region.end()) continue;
    result.regions.emplace_back(name, stiffness_figures_of(found->second));
    all.merge(found->second);
  }
  result.totals = stiffness_figures_of(all);
  return result;
}

// The macro run's dissipation per region, from a sites result's regions (or a rule set's).
template <typename Region>
std::map<std::string, double> macro_dissipation(const std::vector<Region>& regions) {
  std::map<std::string, double> by_region;
  for (const Region& r : regions) by_region[r.name] = r.dissipation_w;
  return by_region;
}

// The region with the most powder power, or none when none has any.
std::optional<std::string> dominant_of(const std::map<std::string, double>& powder) {
  std::optional<std::string> dominant;
  double most = 0.0;
  for (const std::string& name : method::region_names()) {
    const auto found = powder.find(name);
    if (found != powder.end() && found->second > most) {
      most = found->second;
      dominant = name;
    }
  }
  return dominant;
}

// The regions of one method in region_names() order, with the totals, from its per-region sums.
// `cells` (the unscaled sums) give each region's cell_to_macro_power_ratio under both methods.
method::UpscaleMethod method_result(const std::string& method,
                                    const std::map<std::string, method::PowerSums>& regions,
                                    const std::map<std::string, double>& macro,
                                    const std::map<std::string, method::PowerSums>& cells) {
  method::PowerSums all;
  for (const auto& [name, sums] : regions) all.merge(sums);
  method::UpscaleMethod result{.method = method, .totals = figures_of(all, all.powder)};
  std::map<std::string, double> powder;
  for (const std::string& name : method::region_names()) {
    const auto found = regions.find(name);
    if (found == regions.end()) continue;
    const double dissipation = macro.count(name) ? macro.at(name) : 0.0;
    const method::PowerSums& own = cells.at(name);
    result.regions.push_back(
        {.region = name,
         .method = method,
         .figures = figures_of(found->second, all.powder),
         .macro_dissipation_w = dissipation,
         .cell_to_macro_power_ratio = own.paired_sites > 0
                                          ? ratio_if(own.input_no_powder.value, dissipation)
                                          : std::nullopt});
    powder[name] = found->second.powder.value;
  }
  result.dominant_region = dominant_of(powder);
  return result;
}

method::UpscaleSpectra spectra_of(const method::SpectrumSum& sum) {
  return {.bin_edges_j = sum.bin_edges_j(),
          .powder_rate_per_s = sum.powder(),
          .media_rate_per_s = sum.media(),
          .media_rate_no_powder_per_s = sum.media_no_powder()};
}

// Powder mass over media mass in a loaded cell.
double powder_mass_ratio(const method::CellResult& cell, const json& params) {
  return params.at("powder_density_kg_m3").get<double>() * cell.powder_solid_fraction /
         (params.at("media_density_kg_m3").get<double>() * cell.media_solid_fraction);
}

// Each rule set's powder power per region with the macro-anchored method (tasks/upscale.hpp).
std::vector<method::UpscaleSensitivity> sensitivity(
    const std::vector<method::RuleSet>& rule_sets,
    const std::map<std::string, method::PowerSums>& cells) {
  std::vector<method::UpscaleSensitivity> result;
  for (const method::RuleSet& set : rule_sets) {
    std::map<std::string, double> powder;
    double total = 0.0;
    method::UpscaleSensitivity& row =
        result.emplace_back(method::UpscaleSensitivity{.rule_set = set.name});
    for (const auto& [name, dissipation] : macro_dissipation(set.regions)) {
      const auto found = cells.find(name);
      if (found == cells.end() || found->second.input.value <= 0.0) continue;
      powder[name] = dissipation * found->second.powder.value / found->second.input.value;
      total += powder[name];
      row.regions.push_back(
          {.region = name, .macro_dissipation_w = dissipation, .powder_power_w = powder[name]});
    }
    row.dominant_region = dominant_of(powder);
    if (powder.count("toe")) row.toe_powder_power_share = ratio_if(powder["toe"], total);
  }
  return result;
}

// A site's row; without a counted cell at load U, why: its cell left out (by its flag), or none.
method::UpscaleSite site_row(const method::Site& site, const method::CellResult* loaded,
                             const method::CellResult* baseline, double load,
                             const std::vector<method::LeftOutCell>& left_out) {
  method::UpscaleSite row{.site_id = site.site_id,
                          .region = site.region,
                          .x_m = site.x,
                          .y_m = site.y,
                          .weight_m3 = site.weight_m3,
                          .shear_rate_per_s = site.shear_rate,
                          .normal_stress_pa = site.normal_stress,
                          .macro_shear_stress_pa = site.shear_stress};
  if (baseline) {
    row.cell_shear_stress_pa = baseline->shear_stress_pa;
    row.coupling_ratio = ratio_if(baseline->shear_stress_pa, site.shear_stress);
  }
  if (loaded) {
    row.power_density_w_m3 = loaded->power_density_w_m3;
    row.powder_dissipation_w_m3 = loaded->powder_dissipation_w_m3;
    row.cell_normal_stress_pa = loaded->normal_stress_pa;
  } else {
    const auto flagged = std::find_if(left_out.begin(), left_out.end(), [&](const auto& cell) {
      return cell.site_id == site.site_id && cell.powder_load == load && !cell.counted;
    });
    row.skipped = flagged == left_out.end()
                      ? "no shear cell ran at this site"
                      : fmt::format(
                            "its cell was left out ({}); /upscale/include_unsteady "
                            "counts such cells",
                            flagged->reason);
  }
  return row;
}

method::UpscaleCoupling coupling_summary(const std::vector<method::UpscaleSite>& sites) {
  std::vector<double> ratios;
  for (const method::UpscaleSite& site : sites) {
    if (site.coupling_ratio) ratios.push_back(*site.coupling_ratio);
  }
  method::UpscaleCoupling coupling{.sites = ratios.size(),
                                   .tolerance = kCouplingTolerance,
                                   .within_tolerance = static_cast<std::size_t>(
                                       std::count_if(ratios.begin(), ratios.end(), [](double r) {
                                         return std::abs(r - 1.0) <= kCouplingTolerance;
                                       }))};
  if (!ratios.empty()) {
    std::sort(ratios.begin(), ratios.end());
    const std::size_t n = ratios.size();
    coupling.median_ratio = n % 2 ? ratios[n / 2] : 0.5 * (ratios[n / 2 - 1] + ratios[n / 2]);
  }
  return coupling;
}

method::UpscaleMill mill_of(const method::MacroResult& macro) {
  return {.diameter_m = 2.0 * macro.mill.radius_m,
          .slice_length_m = macro.mill.length_m,
          .ball_mass_kg = macro.ball_mass_kg,
          .power_draw_w = macro.power.mean_w,
          .specific_power_kw_per_t = macro.power.kw_per_t_balls};
}

// A figure for the log line: its value, or null.
template <typename T>
std::string shown(const std::optional<T>& value) {
  return value ? json(*value).dump() : "null";
}

}  // namespace

engine::TaskOutcome run_upscale(engine::TaskContext& context) {
  const json& params = context.params;
  const double load = params.at("powder_load").get<double>();
  const method::MacroResult macro = macro_result_of(only_input(context, "macro"));
  const engine::TaskInput& sites_input = only_input(context, "sites");
  const method::SitesResult sites_result =
      method::read_sites_result(sites_input.result, fmt::format("sites task {}", sites_input.key));
  const method::WeightBasis basis = sites_result.weight_by;
  UsableCells cells =
      usable_cells(context, load, params.at("upscale").at("include_unsteady").get<bool>());

  std::map<std::string, method::PowerSums> by_region;
  std::map<std::string, method::SpectrumSum> region_spectra;
  double powder_mass = 0.0, solid_volume = 0.0;
  std::vector<method::UpscaleSite> site_rows;
  for (const method::Site& typed : sites_result.sites) {
    const method::CellResult* cell = cell_of(cells.loaded, typed.site_id);
    const method::CellResult* reference = cell_of(cells.baseline, typed.site_id);
    site_rows.push_back(site_row(typed, cell, reference, load, cells.flagged));
    if (!cell) continue;
    const method::CellFigures loaded = method::cell_figures(*cell);
    const std::optional<method::CellFigures> baseline =
        reference ? std::optional(method::cell_figures(*reference)) : std::nullopt;
    by_region[typed.region].add(typed, basis, loaded, baseline ? &*baseline : nullptr);
    method::SpectrumSum& spectra = region_spectra[typed.region];
    spectra.add(method::site_weight(typed, loaded, basis), method::cell_spectra(*cell));
    if (baseline)
      spectra.add_baseline(method::site_weight(typed, *baseline, basis),
                           method::cell_spectra(*reference));
    powder_mass += typed.solid_volume_m3 * powder_mass_ratio(*cell, params);
    solid_volume += typed.solid_volume_m3;
  }

  const auto macro_by_region = macro_dissipation(sites_result.regions);
  std::map<std::string, method::PowerSums> anchored;
  method::SpectrumSum spectra, anchored_spectra;
  double covered = 0.0;
  for (const auto& [name, sums] : by_region) {
    const double dissipation = macro_by_region.count(name) ? macro_by_region.at(name) : 0.0;
    anchored[name] = sums.anchored(dissipation);
    covered += dissipation;
    spectra.add_scaled(region_spectra.at(name), 1.0, 1.0);
    const auto [k, k0] = sums.anchor_factors(dissipation);
    anchored_spectra.add_scaled(region_spectra.at(name), k, k0);
  }
  double regions_dissipation = 0.0;
  for (const auto& [name, dissipation] : macro_by_region) regions_dissipation += dissipation;

  method::PowerSums all;
  for (const auto& [name, sums] : by_region) all.merge(sums);
  const std::optional<double> mass_ratio =
      solid_volume > 0.0 ? std::optional(powder_mass / solid_volume) : std::nullopt;
  const double power_draw = macro.power.mean_w;
  const std::size_t left_out = cells.flagged.size();
  method::UpscaleResult result{
      .cells = method_result("cells", by_region, macro_by_region, by_region),
      .fill = macro.fill,
      .speed_fraction = macro.speed_fraction,
      .powder_load = load,
      .average_task = only_input(context, "average").key,
      .sites_task = sites_input.key,
      .mill = mill_of(macro),
      .powder_to_media_mass_ratio = mass_ratio,
      .power_draw_with_powder_w =
          all.input_no_powder.value > 0.0 && mass_ratio
              ? std::optional(power_draw * (1.0 + *mass_ratio) * all.input_paired.value /
                              all.input_no_powder.value)
              : std::nullopt,
      .macro_anchored = {.figures =
                             method_result("macro_anchored", anchored, macro_by_region, by_region),
                         .macro_dissipation_w = covered,
                         .uncovered_macro_dissipation_w = regions_dissipation - covered,
                         .spectra = spectra_of(anchored_spectra),
                         .media_spectrum_shift = anchored_spectra.media_shift()},
      .sensitivity = sensitivity(sites_result.rule_sets, by_region),
      .spectra = spectra_of(spectra),
      .media_spectrum_shift = spectra.media_shift(),
      .left_out_cells = std::move(cells.flagged),
      .coupling = coupling_summary(site_rows)};
  result.sites = std::move(site_rows);
  result.stiffness_sensitivity = stiffness_sensitivity(sites_result, cells);
  if (const auto& stiff = result.stiffness_sensitivity) {
    context.log(fmt::format(
        "upscale U = {}: powder pairs {:g} x stiffer at {} sites: cushioning shift {} +- {}, "
        "powder share shift {} +- {}",
        load, stiff->factor, stiff->totals.sites, shown(stiff->totals.cushioning_shift),
        shown(stiff->totals.cushioning_shift_se), shown(stiff->totals.powder_share_shift),
        shown(stiff->totals.powder_share_shift_se)));
  }
  const auto watts = [](const std::optional<double>& w) {
    return w ? fmt::format("{:.4g} W", *w) : std::string("unknown (no cell counted)");
  };
  context.log(fmt::format(
      "upscale U = {}: powder {} ({} dominates; macro-anchored {}, {}), cushioning {}, "
      "{} cells left out, {} of {} sites couple within {:.0f}%",
      load, watts(result.cells.totals.powder_power_w), shown(result.cells.dominant_region),
      watts(result.macro_anchored.figures.totals.powder_power_w),
      shown(result.macro_anchored.figures.dominant_region), shown(result.cells.totals.cushioning),
      left_out, result.coupling.within_tolerance, result.coupling.sites, 100 * kCouplingTolerance));
  return engine::TaskOutcome::with_result(result);
}

engine::ViewDefinition upscaled_results_view() {
  return {"upscaled_results", R"sql(
WITH methods(task_key, result, method, totals) AS (
  SELECT r.task_key, r.result, 'cells', r.result FROM results r
  UNION ALL
  SELECT r.task_key, r.result, 'macro_anchored', json_extract(r.result, '$.macro_anchored')
  FROM results r
)
SELECT c.name AS campaign,
       json_extract(m.result, '$.fill') AS fill,
       json_extract(m.result, '$.speed_fraction') AS speed_fraction,
       json_extract(m.result, '$.powder_load') AS powder_load,
       up.key AS task_key,
       m.method AS method,
       json_extract(region.value, '$.region') AS region,
       json_extract(region.value, '$.sites') AS sites,
       json_extract(region.value, '$.volume_m3') AS volume_m3,
       json_extract(region.value, '$.solid_volume_m3') AS solid_volume_m3,
       json_extract(region.value, '$.macro_dissipation_w') AS macro_dissipation_w,
       json_extract(region.value, '$.cell_to_macro_power_ratio') AS cell_to_macro_power_ratio,
       json_extract(region.value, '$.powder_power_w') AS powder_power_w,
       json_extract(region.value, '$.powder_power_w_se') AS powder_power_w_se,
       json_extract(region.value, '$.powder_power_share') AS powder_power_share,
       json_extract(region.value, '$.powder_power_share_se') AS powder_power_share_se,
       json_extract(region.value, '$.media_power_w') AS media_power_w,
       json_extract(region.value, '$.media_collision_power_w') AS media_collision_power_w,
       json_extract(region.value, '$.cushioning') AS cushioning,
       json_extract(region.value, '$.cushioning_se') AS cushioning_se,
       json_extract(region.value, '$.cushioning_rate_factor') AS cushioning_rate_factor,
       json_extract(region.value, '$.cushioning_rate_factor_se') AS cushioning_rate_factor_se,
       json_extract(region.value, '$.cushioning_energy_factor') AS cushioning_energy_factor,
       json_extract(region.value, '$.cushioning_energy_factor_se') AS cushioning_energy_factor_se,
       json_extract(m.result, '$.mill.power_draw_w') AS power_draw_w,
       json_extract(m.result, '$.power_draw_with_powder_w') AS power_draw_with_powder_w,
       json_extract(m.totals, '$.powder_power_w') AS mill_powder_power_w,
       json_extract(m.totals, '$.dominant_region') AS dominant_region,
       json_extract(m.result, '$.coupling.median_ratio') AS coupling_median_ratio,
       json_array_length(m.result, '$.left_out_cells') AS left_out_cells
FROM campaign_tasks ct
JOIN campaigns c ON c.id = ct.campaign_id
JOIN tasks up ON up.key = ct.task_key AND up.kind = 'upscale' AND up.status = 'done'
JOIN methods m ON m.task_key = up.key
LEFT JOIN json_each(m.totals, '$.regions') region
)sql"};
}

void register_upscale(engine::Registry& registry) {
  registry.kinds.add(
      engine::TaskKind{.name = "upscale", .version = kUpscaleVersion, .run = run_upscale});
  registry.views.push_back(upscaled_results_view());
}

}  // namespace millflow::tasks
