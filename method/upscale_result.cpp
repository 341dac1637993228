#include "method/upscale_result.hpp"

#include <fmt/format.h>

#include "util/json_fields.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

template <typename T>
json optional_json(const std::optional<T>& value) {
  return value ? json(*value) : json();
}

json figures_json(const UpscaleFigures& f) {
  return {{"sites", f.sites},
          {"volume_m3", f.volume_m3},
          {"solid_volume_m3", f.solid_volume_m3},
          {"powder_power_w", optional_json(f.powder_power_w)},
          {"powder_power_w_se", optional_json(f.powder_power_w_se)},
          {"powder_power_share", optional_json(f.powder_power_share)},
          {"powder_power_share_se", optional_json(f.powder_power_share_se)},
          {"media_power_w", optional_json(f.media_power_w)},
          {"media_collision_power_w", optional_json(f.media_collision_power_w)},
          {"media_collision_power_no_powder_w", optional_json(f.media_collision_power_no_powder_w)},
          {"cushioning", optional_json(f.cushioning)},
          {"cushioning_se", optional_json(f.cushioning_se)},
          {"cushioning_rate_factor", optional_json(f.cushioning_rate_factor)},
          {"cushioning_rate_factor_se", optional_json(f.cushioning_rate_factor_se)},
          {"cushioning_energy_factor", optional_json(f.cushioning_energy_factor)},
          {"cushioning_energy_factor_se", optional_json(f.cushioning_energy_factor_se)}};
}

json method_json(const UpscaleMethod& m) {
  json regions = json::array();
  for (const UpscaleRegion& r : m.regions) {
    json row = figures_json(r.figures);
    row["region"] = r.region;
    row["method"] = r.method;
    row["macro_dissipation_w"] = r.macro_dissipation_w;
    row["cell_to_macro_power_ratio"] = optional_json(r.cell_to_macro_power_ratio);
    regions.push_back(std::move(row));
  }
  json out = figures_json(m.totals);
  out["method"] = m.method;
  out["regions"] = std::move(regions);
  out["dominant_region"] = optional_json(m.dominant_region);
  return out;
}

json spectra_json(const UpscaleSpectra& s) {
  return {{"bin_edges_j", s.bin_edges_j},
          {"powder_rate_per_s", s.powder_rate_per_s},
          {"media_rate_per_s", s.media_rate_per_s},
          {"media_rate_no_powder_per_s", s.media_rate_no_powder_per_s}};
}

json shift_json(const std::optional<SpectrumShift>& shift) {
  if (!shift) return nullptr;
  return {{"threshold_j", shift->threshold_j},
          {"fraction_above", optional_json(shift->fraction_above)},
          {"fraction_above_no_powder", shift->fraction_above_no_powder}};
}

json sensitivity_json(const UpscaleSensitivity& s) {
  json regions = json::array();
  for (const SensitivityRegion& r : s.regions) {
    regions.push_back({{"region", r.region},
                       {"macro_dissipation_w", r.macro_dissipation_w},
                       {"powder_power_w", r.powder_power_w}});
  }
  return {{"rule_set", s.rule_set},
          {"regions", regions},
          {"dominant_region", optional_json(s.dominant_region)},
          {"toe_powder_power_share", optional_json(s.toe_powder_power_share)}};
}

json left_out_json(const std::vector<LeftOutCell>& cells) {
  json out = json::array();
  for (const LeftOutCell& c : cells) {
    out.push_back({{"site_id", c.site_id},
                   {"powder_load", c.powder_load},
                   {"reason", c.reason},
                   {"counted", c.counted}});
  }
  return out;
}

json stiffness_figures_json(const StiffnessFigures& f) {
  json out = {{"sites", f.sites}};
  for (const auto& [key, member] : kStiffnessFigureKeys) out[key] = optional_json(f.*member);
  return out;
}

json stiffness_json(const StiffnessSensitivity& s) {
  json regions = json::object();
  for (const auto& [region, figures] : s.regions) regions[region] = stiffness_figures_json(figures);
  return {{"factor", s.factor},
          {"regions", regions},
          {"totals", stiffness_figures_json(s.totals)},
          {"left_out_cells", left_out_json(s.left_out_cells)}};
}

json site_json(const UpscaleSite& s) {
  return {{"site_id", s.site_id},
          {"region", s.region},
          {"x_m", s.x_m},
          {"y_m", s.y_m},
          {"weight_m3", s.weight_m3},
          {"shear_rate_per_s", s.shear_rate_per_s},
          {"normal_stress_pa", s.normal_stress_pa},
          {"macro_shear_stress_pa", s.macro_shear_stress_pa},
          {"cell_shear_stress_pa", optional_json(s.cell_shear_stress_pa)},
          {"coupling_ratio", optional_json(s.coupling_ratio)},
          {"power_density_w_m3", optional_json(s.power_density_w_m3)},
          {"powder_dissipation_w_m3", optional_json(s.powder_dissipation_w_m3)},
          {"cell_normal_stress_pa", optional_json(s.cell_normal_stress_pa)},
          {"skipped", optional_json(s.skipped)}};
}

// The top level's `sites` are the site rows, so there (`at` "") the count is not read.
UpscaleFigures read_figures(const util::JsonFields& in, const std::string& at) {
  return {.sites = at.empty() ? 0 : in.count(at + "/sites"),
          .volume_m3 = in.number(at + "/volume_m3"),
          .solid_volume_m3 = in.number(at + "/solid_volume_m3"),
          .powder_power_w = in.number_or_null(at + "/powder_power_w"),
          .powder_power_w_se = in.number_or_null(at + "/powder_power_w_se"),
          .powder_power_share = in.number_or_null(at + "/powder_power_share"),
          .powder_power_share_se = in.number_or_null(at + "/powder_power_share_se"),
          .media_power_w = in.number_or_null(at + "/media_power_w"),
          .media_collision_power_w = in.number_or_null(at + "/media_collision_power_w"),
          .media_collision_power_no_powder_w =
              in.number_or_null(at + "/media_collision_power_no_powder_w"),
          .cushioning = in.number_or_null(at + "/cushioning"),
          .cushioning_se = in.number_or_null(at + "/cushioning_se"),
          .cushioning_rate_factor = in.number_or_null(at + "/cushioning_rate_factor"),
          .cushioning_rate_factor_se = in.number_or_null(at + "/cushioning_rate_factor_se"),
          .cushioning_energy_factor = in.number_or_null(at + "/cushioning_energy_factor"),
          .cushioning_energy_factor_se = in.number_or_null(at + "/cushioning_energy_factor_se")};
}

// `at` is "" for the top-level (cells) method.
UpscaleMethod read_method(const util::JsonFields& in, const std::string& at) {
  UpscaleMethod m{.method = in.text(at + "/method"),
                  .totals = read_figures(in, at),
                  .dominant_region = in.text_or_null(at + "/dominant_region")};
  for (std::size_t r = 0; r < in.array_size(at + "/regions"); ++r) {
    const std::string row = fmt::format("{}/regions/{}", at, r);
    m.regions.push_back(
        {.region = in.text(row + "/region"),
         .method = in.text(row + "/method"),
         .figures = read_figures(in, row),
         .macro_dissipation_w = in.number(row + "/macro_dissipation_w"),
         .cell_to_macro_power_ratio = in.number_or_null(row + "/cell_to_macro_power_ratio")});
  }
  return m;
}

UpscaleSpectra read_spectra(const util::JsonFields& in, const std::string& at) {
  UpscaleSpectra s{.bin_edges_j = in.numbers(at + "/bin_edges_j"),
                   .powder_rate_per_s = in.numbers(at + "/powder_rate_per_s"),
                   .media_rate_per_s = in.numbers(at + "/media_rate_per_s"),
                   .media_rate_no_powder_per_s = in.numbers(at + "/media_rate_no_powder_per_s")};
  const std::size_t bins = s.bin_edges_j.empty() ? 0 : s.bin_edges_j.size() - 1;
  for (const auto& [key, rates] :
       {std::pair{"/powder_rate_per_s", &s.powder_rate_per_s},
        std::pair{"/media_rate_per_s", &s.media_rate_per_s},
        std::pair{"/media_rate_no_powder_per_s", &s.media_rate_no_powder_per_s}}) {
    if (rates->size() != bins) in.refuse(at + key, fmt::format("does not hold {} bins", bins));
  }
  return s;
}

std::optional<SpectrumShift> read_shift(const util::JsonFields& in, const std::string& at) {
  if (in.at(at).is_null()) return std::nullopt;
  return SpectrumShift{.threshold_j = in.number(at + "/threshold_j"),
                       .fraction_above = in.number_or_null(at + "/fraction_above"),
                       .fraction_above_no_powder = in.number(at + "/fraction_above_no_powder")};
}

bool read_flag(const util::JsonFields& in, const std::string& at) {
  const json& value = in.at(at);
  if (!value.is_boolean()) in.refuse(at, "is " + value.dump() + ", not true or false");
  return value.get<bool>();
}

std::vector<LeftOutCell> read_left_out(const util::JsonFields& in, const std::string& at) {
  std::vector<LeftOutCell> cells;
  for (std::size_t i = 0; i < in.array_size(at); ++i) {
    const std::string row = fmt::format("{}/{}", at, i);
    cells.push_back({.site_id = in.text(row + "/site_id"),
                     .powder_load = in.number(row + "/powder_load"),
                     .reason = in.text(row + "/reason"),
                     .counted = read_flag(in, row + "/counted")});
  }
  return cells;
}

StiffnessFigures read_stiffness_figures(const util::JsonFields& in, const std::string& at) {
  StiffnessFigures f{.sites = in.count(at + "/sites")};
  for (const auto& [key, member] : kStiffnessFigureKeys)
    f.*member = in.number_or_null(at + "/" + key);
  return f;
}

std::optional<StiffnessSensitivity> read_stiffness(const util::JsonFields& in,
                                                   const json& document) {
  const std::string at = "/stiffness_sensitivity";
  if (!document.contains("stiffness_sensitivity")) return std::nullopt;
  StiffnessSensitivity s{.factor = in.number(at + "/factor"),
                         .totals = read_stiffness_figures(in, at + "/totals"),
                         .left_out_cells = read_left_out(in, at + "/left_out_cells")};
  const json& regions = in.at(at + "/regions");
  if (!regions.is_object()) in.refuse(at + "/regions", "is not an object of regions");
  for (const std::string& region : region_names()) {
    if (regions.contains(region))
      s.regions.emplace_back(region, read_stiffness_figures(in, at + "/regions/" + region));
  }
  return s;
}

}  // namespace

void to_json(json& out, const UpscaleResult& r) {
  json anchored = method_json(r.macro_anchored.figures);
  anchored["macro_dissipation_w"] = r.macro_anchored.macro_dissipation_w;
  anchored["uncovered_macro_dissipation_w"] = r.macro_anchored.uncovered_macro_dissipation_w;
  anchored["spectra"] = spectra_json(r.macro_anchored.spectra);
  anchored["media_spectrum_shift"] = shift_json(r.macro_anchored.media_spectrum_shift);
  json sensitivity = json::array(), sites = json::array();
  for (const UpscaleSensitivity& s : r.sensitivity) sensitivity.push_back(sensitivity_json(s));
  for (const UpscaleSite& s : r.sites) sites.push_back(site_json(s));
  out = method_json(r.cells);
  out.update(json{
      {"fill", r.fill},
      {"speed_fraction", r.speed_fraction},
      {"powder_load", r.powder_load},
      {"average_task", r.average_task},
      {"sites_task", r.sites_task},
      {"mill",
       {{"diameter_m", r.mill.diameter_m},
        {"slice_length_m", r.mill.slice_length_m},
        {"ball_mass_kg", r.mill.ball_mass_kg},
        {"power_draw_w", r.mill.power_draw_w},
        {"specific_power_kw_per_t", r.mill.specific_power_kw_per_t}}},
      {"powder_to_media_mass_ratio", optional_json(r.powder_to_media_mass_ratio)},
      {"power_draw_with_powder_w", optional_json(r.power_draw_with_powder_w)},
      {"macro_anchored", anchored},
      {"sensitivity", sensitivity},
      {"spectra", spectra_json(r.spectra)},
      {"media_spectrum_shift", shift_json(r.media_spectrum_shift)},
      {"left_out_cells", left_out_json(r.left_out_cells)},
      {"sites", sites},
      {"coupling",
       {{"sites", r.coupling.sites},
        {"median_ratio", optional_json(r.coupling.median_ratio)},
        {"tolerance", r.coupling.tolerance},
        {"within_tolerance", r.coupling.within_tolerance}}},
  });
  if (r.stiffness_sensitivity)
    out["stiffness_sensitivity"] = stiffness_json(*r.stiffness_sensitivity);
}

UpscaleResult read_upscale_result(const json& document, const std::string& owner,
                                  const std::string& fix) {
  const util::JsonFields in(owner, document, fix);
  UpscaleResult r{
      .cells = read_method(in, ""),
      .fill = in.number("/fill"),
      .speed_fraction = in.number("/speed_fraction"),
      .powder_load = in.number("/powder_load"),
      .average_task = in.text("/average_task"),
      .sites_task = in.text("/sites_task"),
      .mill = {.diameter_m = in.number("/mill/diameter_m"),
               .slice_length_m = in.number("/mill/slice_length_m"),
               .ball_mass_kg = in.number("/mill/ball_mass_kg"),
               .power_draw_w = in.number("/mill/power_draw_w"),
               .specific_power_kw_per_t = in.number("/mill/specific_power_kw_per_t")},
      .powder_to_media_mass_ratio = in.number_or_null("/powder_to_media_mass_ratio"),
      .power_draw_with_powder_w = in.number_or_null("/power_draw_with_powder_w"),
      .macro_anchored = {.figures = read_method(in, "/macro_anchored"),
                         .macro_dissipation_w = in.number("/macro_anchored/macro_dissipation_w"),
                         .uncovered_macro_dissipation_w =
                             in.number("/macro_anchored/uncovered_macro_dissipation_w"),
                         .spectra = read_spectra(in, "/macro_anchored/spectra"),
                         .media_spectrum_shift =
                             read_shift(in, "/macro_anchored/media_spectrum_shift")},
      .spectra = read_spectra(in, "/spectra"),
      .media_spectrum_shift = read_shift(in, "/media_spectrum_shift"),
      .coupling = {.sites = in.count("/coupling/sites"),
                   .median_ratio = in.number_or_null("/coupling/median_ratio"),
                   .tolerance = in.number("/coupling/tolerance"),
                   .within_tolerance = in.count("/coupling/within_tolerance")}};
  for (std::size_t i = 0; i < in.array_size("/sensitivity"); ++i) {
    const std::string at = fmt::format("/sensitivity/{}", i);
    UpscaleSensitivity& s = r.sensitivity.emplace_back(UpscaleSensitivity{
        .rule_set = in.text(at + "/rule_set"),
        .dominant_region = in.text_or_null(at + "/dominant_region"),
        .toe_powder_power_share = in.number_or_null(at + "/toe_powder_power_share")});
    for (std::size_t j = 0; j < in.array_size(at + "/regions"); ++j) {
      const std::string row = fmt::format("{}/regions/{}", at, j);
      s.regions.push_back({.region = in.text(row + "/region"),
                           .macro_dissipation_w = in.number(row + "/macro_dissipation_w"),
                           .powder_power_w = in.number(row + "/powder_power_w")});
    }
  }
  r.left_out_cells = read_left_out(in, "/left_out_cells");
  r.stiffness_sensitivity = read_stiffness(in, document);
  for (std::size_t i = 0; i < in.array_size("/sites"); ++i) {
    const std::string at = fmt::format("/sites/{}", i);
    r.sites.push_back(
        {.site_id = in.text(at + "/site_id"),
         .region = in.text(at + "/region"),
         .x_m = in.number(at + "/x_m"),
         .y_m = in.number(at + "/y_m"),
         .weight_m3 = in.number(at + "/weight_m3"),
         .shear_rate_per_s = in.number(at + "/shear_rate_per_s"),
         .normal_stress_pa = in.number(at + "/normal_stress_pa"),
         .macro_shear_stress_pa = in.number(at + "/macro_shear_stress_pa"),
         .cell_shear_stress_pa = in.number_or_null(at + "/cell_shear_stress_pa"),
         .coupling_ratio = in.number_or_null(at + "/coupling_ratio"),
         .power_density_w_m3 = in.number_or_null(at + "/power_density_w_m3"),
         .powder_dissipation_w_m3 = in.number_or_null(at + "/powder_dissipation_w_m3"),
         .cell_normal_stress_pa = in.number_or_null(at + "/cell_normal_stress_pa"),
         .skipped = in.text_or_null(at + "/skipped")});
  }
  return r;
}

void from_json(const json& in, UpscaleResult& result) {
  result = read_upscale_result(in, "upscale result");
}

}  // namespace millflow::method
