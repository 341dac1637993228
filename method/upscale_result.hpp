#pragma once
// One sweep point's mill-scale answers (docs/method.md, step 4): what the `upscale` task kind
// stores (tasks/upscale.cpp fills it from the sums of method/upscale.hpp) and the report reads.
// tasks/upscale.hpp says what each figure means; to_json and read_upscale_result below are the
// one spelling of its keys (the upscaled_results SQL view names them too).
//
// Result JSON (versioned by the kind's kUpscaleVersion, tasks/upscale.hpp), SI units unless the key
// says otherwise, null where a figure is undefined:
//   the "cells" method's figures over all regions (UpscaleFigures keys, but `sites` holds the
//   site rows below instead of the count) with method, regions
//   [{region, method, macro_dissipation_w, cell_to_macro_power_ratio, UpscaleFigures keys}],
//   dominant_region; fill, speed_fraction, powder_load, average_task, sites_task,
//   mill {diameter_m, slice_length_m, ball_mass_kg, power_draw_w, specific_power_kw_per_t},
//   powder_to_media_mass_ratio, power_draw_with_powder_w,
//   macro_anchored {the same as the cells method's, macro_dissipation_w,
//   uncovered_macro_dissipation_w, spectra, media_spectrum_shift},
//   sensitivity [{rule_set, regions [{region, macro_dissipation_w, powder_power_w}],
//   dominant_region, toe_powder_power_share}],
//   spectra {bin_edges_j, powder_rate_per_s, media_rate_per_s, media_rate_no_powder_per_s},
//   media_spectrum_shift {threshold_j, fraction_above, fraction_above_no_powder},
//   left_out_cells [{site_id, powder_load, reason, counted}],
//   sites [{site_id, region, x_m, y_m, weight_m3, shear_rate_per_s, normal_stress_pa,
//   macro_shear_stress_pa, cell_shear_stress_pa, coupling_ratio, power_density_w_m3,
//   powder_dissipation_w_m3, cell_normal_stress_pa, skipped}],
//   coupling {sites, median_ratio, tolerance, within_tolerance},
//   stiffness_sensitivity (only with stiff cells, /shear_cell/stiffness/sensitivity) {factor,
//   regions {<region>: StiffnessFigures keys}, totals {StiffnessFigures keys}, left_out_cells
//   [as above]}; StiffnessFigures keys: sites, and cushioning, cushioning_stiff,
//   cushioning_shift, powder_share, powder_share_stiff, powder_share_shift, each with its _se.
#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "method/upscale.hpp"

namespace millflow::method {

// One method's figures over one region or over all, W in the slice. The powers are none where
// no cell was counted (every site's cell left out or never run): a sum over no site is not 0 W.
struct UpscaleFigures {
  std::size_t sites = 0;
  double volume_m3 = 0.0, solid_volume_m3 = 0.0;
  std::optional<double> powder_power_w{}, powder_power_w_se{}, powder_power_share{},
      powder_power_share_se{};
  std::optional<double> media_power_w{}, media_collision_power_w{},
      media_collision_power_no_powder_w{};
  std::optional<double> cushioning{}, cushioning_se{}, cushioning_rate_factor{},
      cushioning_rate_factor_se{}, cushioning_energy_factor{}, cushioning_energy_factor_se{};
};

struct UpscaleRegion {
  std::string region{}, method{};
  UpscaleFigures figures{};
  double macro_dissipation_w = 0.0;
  std::optional<double> cell_to_macro_power_ratio{};  // none without media-only cells
};

// One method ("cells" or "macro_anchored"): its totals, regions and dominant region.
struct UpscaleMethod {
  std::string method{};
  UpscaleFigures totals{};
  std::vector<UpscaleRegion> regions{};          // in region_names() order
  std::optional<std::string> dominant_region{};  // none without powder power
};

// Collisions per second in the slice per energy bin.
struct UpscaleSpectra {
  std::vector<double> bin_edges_j{}, powder_rate_per_s{}, media_rate_per_s{},
      media_rate_no_powder_per_s{};
};

struct UpscaleAnchored {
  UpscaleMethod figures{};
  double macro_dissipation_w = 0.0, uncovered_macro_dissipation_w = 0.0;
  UpscaleSpectra spectra{};
  std::optional<SpectrumShift> media_spectrum_shift{};
};

struct UpscaleMill {
  double diameter_m = 0.0, slice_length_m = 0.0, ball_mass_kg = 0.0, power_draw_w = 0.0,
         specific_power_kw_per_t = 0.0;
};

struct SensitivityRegion {
  std::string region{};
  double macro_dissipation_w = 0.0, powder_power_w = 0.0;
};

// One rule set's powder power per region with the macro-anchored method.
struct UpscaleSensitivity {
  std::string rule_set{};
  std::vector<SensitivityRegion> regions{};
  std::optional<std::string> dominant_region{};
  std::optional<double> toe_powder_power_share{};
};

// The stiffness sensitivity of one region or of all (tasks/upscale.hpp): over the same sites,
// the cushioning and the powder's share of the cells' power input with the default cells and with
// the stiff ones, and the relative shift stiff / default - 1, each with its standard error.
struct StiffnessFigures {
  std::size_t sites = 0;
  std::optional<double> cushioning{}, cushioning_se{}, cushioning_stiff{}, cushioning_stiff_se{},
      cushioning_shift{}, cushioning_shift_se{}, powder_share{}, powder_share_se{},
      powder_share_stiff{}, powder_share_stiff_se{}, powder_share_shift{}, powder_share_shift_se{};
};

// The one spelling of StiffnessFigures' keys (but `sites`).
inline constexpr std::array<std::pair<const char*, std::optional<double> StiffnessFigures::*>, 12>
    kStiffnessFigureKeys{{{"cushioning", &StiffnessFigures::cushioning},
                          {"cushioning_se", &StiffnessFigures::cushioning_se},
                          {"cushioning_stiff", &StiffnessFigures::cushioning_stiff},
                          {"cushioning_stiff_se", &StiffnessFigures::cushioning_stiff_se},
                          {"cushioning_shift", &StiffnessFigures::cushioning_shift},
                          {"cushioning_shift_se", &StiffnessFigures::cushioning_shift_se},
                          {"powder_share", &StiffnessFigures::powder_share},
                          {"powder_share_se", &StiffnessFigures::powder_share_se},
                          {"powder_share_stiff", &StiffnessFigures::powder_share_stiff},
                          {"powder_share_stiff_se", &StiffnessFigures::powder_share_stiff_se},
                          {"powder_share_shift", &StiffnessFigures::powder_share_shift},
                          {"powder_share_shift_se", &StiffnessFigures::powder_share_shift_se}}};

// A cell left out of the sums (or counted against its flags).
struct LeftOutCell {
  std::string site_id{};
  double powder_load = 0.0;
  std::string reason{};
  bool counted = false;
};

// One site: position, weight, macro state and its cells' results.
struct UpscaleSite {
  std::string site_id{}, region{};
  double x_m = 0.0, y_m = 0.0, weight_m3 = 0.0;
  double shear_rate_per_s = 0.0, normal_stress_pa = 0.0, macro_shear_stress_pa = 0.0;
  std::optional<double> cell_shear_stress_pa{}, coupling_ratio{}, power_density_w_m3{},
      powder_dissipation_w_m3{};
  // The normal stress the cell at this point's load held over its measured window (its p_yy),
  // against normal_stress_pa, the site's it was asked to hold.
  std::optional<double> cell_normal_stress_pa{};
  std::optional<std::string> skipped{};  // why no cell counts here
};

struct UpscaleCoupling {
  std::size_t sites = 0;
  std::optional<double> median_ratio{};
  double tolerance = 0.0;
  std::size_t within_tolerance = 0;
};

// What the stiff cells of one point give (tasks/upscale.hpp, Stiffness sensitivity).
struct StiffnessSensitivity {
  double factor = 1.0;  // the stiff cells' factor on the powder pairs' k_n
  std::vector<std::pair<std::string, StiffnessFigures>> regions{};  // in region_names() order
  StiffnessFigures totals{};
  std::vector<LeftOutCell> left_out_cells{};  // stiff cells left out (or counted against flags)
};

struct UpscaleResult {
  UpscaleMethod cells{};  // the top-level figures, but for cells.totals.sites (not stored)
  double fill = 0.0, speed_fraction = 0.0, powder_load = 0.0;
  std::string average_task{}, sites_task{};
  UpscaleMill mill{};
  std::optional<double> powder_to_media_mass_ratio{};  // none without counted cells
  std::optional<double> power_draw_with_powder_w{};    // none without media-only cells
  UpscaleAnchored macro_anchored{};
  std::vector<UpscaleSensitivity> sensitivity{};
  UpscaleSpectra spectra{};
  std::optional<SpectrumShift> media_spectrum_shift{};
  std::vector<LeftOutCell> left_out_cells{};
  std::vector<UpscaleSite> sites{};
  UpscaleCoupling coupling{};
  std::optional<StiffnessSensitivity> stiffness_sensitivity{};  // none without stiff cells
};

void to_json(nlohmann::json& out, const UpscaleResult& result);

// Reads and checks a result: a missing or ill-typed field, or a spectrum whose rates do not
// match its bin edges, throws std::invalid_argument "<owner>: field <JSON pointer> <problem>;
// <fix>" (util/json_fields.hpp), e.g. owner "upscale task <key>".
UpscaleResult read_upscale_result(const nlohmann::json& in, const std::string& owner,
                                  const std::string& fix =
                                      "re-run that task with a matching "
                                      "version");
void from_json(const nlohmann::json& in, UpscaleResult& result);  // owner "upscale result"

}  // namespace millflow::method
