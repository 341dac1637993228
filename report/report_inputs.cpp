#include "report/report_inputs.hpp"
#include "method/fields_file.hpp"
#include "method/macro_result.hpp"
#include "util/json_fields.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <stdexcept>
#include <tuple>

namespace millflow::report {
namespace {

using nlohmann::json;

using FieldReader = util::JsonFields;

// Typed reads from an upscale result, with errors that name the task and field.
FieldReader upscale_fields(const std::string& task_key, const json& result) {
  return FieldReader(fmt::format("upscale task {}", task_key), result,
                     "the report reads the upscale result contract, so re-run that task with a "
                     "matching version");
}

RegionResult read_region(const FieldReader& in, const std::string& at) {
  return {.region = in.text(at + "/region"),
          .sites = in.count(at + "/sites"),
          .volume_m3 = in.number(at + "/volume_m3"),
          .powder_power_w = in.number(at + "/powder_power_w"),
          .powder_power_share = in.number_or_null(at + "/powder_power_share"),
          .media_power_w = in.number(at + "/media_power_w"),
          .media_collision_power_w = in.number(at + "/media_collision_power_w"),
          .media_collision_power_no_powder_w = in.number(at + "/media_collision_power_no_powder_w"),
          .cushioning = in.number_or_null(at + "/cushioning"),
          .powder_power_share_se = in.number_or_null(at + "/powder_power_share_se"),
          .cushioning_se = in.number_or_null(at + "/cushioning_se")};
}

SiteResult read_site(const FieldReader& in, const std::string& at) {
  return {.site_id = in.text(at + "/site_id"),
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
          .skipped = in.text_or_null(at + "/skipped")};
}

void read_spectra(const FieldReader& in, UpscalePoint& point) {
  point.bin_edges_j = in.numbers("/spectra/bin_edges_j");
  point.powder_rate_per_s = in.numbers("/spectra/powder_rate_per_s");
  point.media_rate_per_s = in.numbers("/spectra/media_rate_per_s");
  if (point.bin_edges_j.size() < 2) in.refuse("/spectra/bin_edges_j", "holds fewer than 2 edges");
  const std::size_t bins = point.bin_edges_j.size() - 1;
  if (point.powder_rate_per_s.size() != bins)
    in.refuse("/spectra/powder_rate_per_s", fmt::format("does not hold {} bins", bins));
  if (point.media_rate_per_s.size() != bins)
    in.refuse("/spectra/media_rate_per_s", fmt::format("does not hold {} bins", bins));
}

method::FlowMap read_flow_map(const std::string& average_key,
                              const std::optional<std::filesystem::path>& fields) {
  const std::string owner = fmt::format("average task {}", average_key);
  if (!fields) {
    throw std::invalid_argument(owner + ": has no fields.json artifact; re-run the average task");
  }
  std::ifstream file(*fields);
  if (!file)
    throw std::invalid_argument(fmt::format("{}: cannot read {}", owner, fields->string()));
  try {
    return method::flow_map_from_document(json::parse(file));
  } catch (const std::exception& error) {
    throw std::invalid_argument(fmt::format("{}: fields.json: {}", owner, error.what()));
  }
}

}  // namespace

UpscalePoint read_upscale(const std::string& task_key, const json& result) {
  const FieldReader in = upscale_fields(task_key, result);
  UpscalePoint point{.task_key = task_key,
                     .average_task = in.text("/average_task"),
                     .fill = in.number("/fill"),
                     .speed_fraction = in.number("/speed_fraction"),
                     .powder_load = in.number("/powder_load"),
                     .power_draw_w = in.number("/mill/power_draw_w"),
                     .specific_power_kw_per_t = in.number("/mill/specific_power_kw_per_t"),
                     .power_draw_with_powder_w = in.number_or_null("/power_draw_with_powder_w"),
                     .powder_power_w = in.number("/powder_power_w"),
                     .media_power_w = in.number("/media_power_w"),
                     .dominant_region = in.text_or_null("/dominant_region"),
                     .coupling = {.sites = in.count("/coupling/sites"),
                                  .median_ratio = in.number_or_null("/coupling/median_ratio"),
                                  .tolerance = in.number("/coupling/tolerance"),
                                  .within_tolerance = in.count("/coupling/within_tolerance")}};
  for (std::size_t r = 0; r < in.array_size("/regions"); ++r)
    point.regions.push_back(read_region(in, fmt::format("/regions/{}", r)));
  for (std::size_t s = 0; s < in.array_size("/sites"); ++s)
    point.sites.push_back(read_site(in, fmt::format("/sites/{}", s)));
  read_spectra(in, point);
  return point;
}

MacroRun read_macro(const std::string& task_key, const json& result) {
  const std::string owner = fmt::format("macro task {}", task_key);
  const method::MacroResult macro = method::read_macro_result(result, owner);
  MacroRun run{.task_key = task_key,
               .fill = macro.fill,
               .speed_fraction = macro.speed_fraction,
               .toe_angle_deg = macro.charge.toe_angle_deg,
               .shoulder_angle_deg = macro.charge.shoulder_angle_deg,
               .bin_edges_j = macro.spectrum_bin_edges_j};
  if (macro.collisions.empty()) FieldReader(owner, result).refuse("/collisions", "is empty");
  const double duration = macro.measure_end_s - macro.measure_start_s;
  if (!(duration > 0.0))
    FieldReader(owner, result).refuse("/measure_end_s", "is not after /measure_start_s");
  for (const auto& [contact, collisions] : macro.collisions) {
    for (const auto& [energy, histogram] :
         {std::pair{"impact", &collisions.impact_energy},
          std::pair{"dissipated", &collisions.dissipated_energy}}) {
      MacroSpectrum spectrum{.label = fmt::format("{} {}", contact, energy),
                             .rate_per_s = histogram->counts};
      for (double& count : spectrum.rate_per_s) count /= duration;
      run.spectra.push_back(std::move(spectrum));
    }
  }
  return run;
}

ReportInputs read_report_inputs(const ReportSources& sources) {
  ReportInputs report;
  for (const TaskResult& upscale : sources.upscales)
    report.points.push_back(read_upscale(upscale.key, upscale.result));
  for (const TaskResult& macro : sources.macros)
    report.macro_runs.push_back(read_macro(macro.key, macro.result));
  if (report.points.empty()) {
    throw std::invalid_argument(
        "the report has no upscale input: plan it below the campaign's upscale tasks");
  }
  for (const UpscalePoint& point : report.points) {
    if (report.flow_maps.count(point.average_task) > 0) continue;
    const auto average = sources.average_fields.find(point.average_task);
    if (average == sources.average_fields.end()) {
      throw std::invalid_argument(
          fmt::format("upscale task {}: field /average_task names {}, which is not an average "
                      "input of the report; plan the report below that average task",
                      point.task_key, point.average_task));
    }
    report.flow_maps.emplace(point.average_task, read_flow_map(average->first, average->second));
  }
  std::sort(report.points.begin(), report.points.end(),
            [](const UpscalePoint& a, const UpscalePoint& b) {
              return std::tie(a.fill, a.speed_fraction, a.powder_load, a.task_key) <
                     std::tie(b.fill, b.speed_fraction, b.powder_load, b.task_key);
            });
  std::sort(report.macro_runs.begin(), report.macro_runs.end(),
            [](const MacroRun& a, const MacroRun& b) {
              return std::tie(a.fill, a.speed_fraction, a.task_key) <
                     std::tie(b.fill, b.speed_fraction, b.task_key);
            });
  return report;
}

}  // namespace millflow::report
