#include "report/report_inputs.hpp"
#include "method/fields_file.hpp"
#include "method/macro_result.hpp"
#include "method/upscale_result.hpp"
#include "util/json_fields.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <stdexcept>
#include <tuple>
#include <utility>

namespace millflow::report {
namespace {

using nlohmann::json;

using FieldReader = util::JsonFields;

constexpr const char* kSitesFix =
    "the report reads the sites result contract, so re-run that task with a matching version";
constexpr const char* kUpscaleFix =
    "the report reads the upscale result contract, so re-run that task with a matching version";

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
  const std::string owner = fmt::format("upscale task {}", task_key);
  return {.task_key = task_key, .upscale = method::read_upscale_result(result, owner, kUpscaleFix)};
}

SitesPoint read_sites(const std::string& task_key, const json& result) {
  return {.task_key = task_key,
          .sites =
              method::read_sites_result(result, fmt::format("sites task {}", task_key), kSitesFix)};
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
  for (const TaskResult& sites : sources.sites)
    report.sites.push_back(read_sites(sites.key, sites.result));
  for (const TaskResult& macro : sources.macros)
    report.macro_runs.push_back(read_macro(macro.key, macro.result));
  if (report.points.empty()) {
    throw std::invalid_argument(
        "the report has no upscale input: plan it below the campaign's upscale tasks");
  }
  for (const UpscalePoint& point : report.points) {
    const std::string& average_task = point.upscale.average_task;
    if (report.flow_maps.count(average_task) > 0) continue;
    const auto average = sources.average_fields.find(average_task);
    if (average == sources.average_fields.end()) {
      throw std::invalid_argument(
          fmt::format("upscale task {}: field /average_task names {}, which is not an average "
                      "input of the report; plan the report below that average task",
                      point.task_key, average_task));
    }
    report.flow_maps.emplace(average_task, read_flow_map(average->first, average->second));
  }
  std::sort(report.points.begin(), report.points.end(),
            [](const UpscalePoint& a, const UpscalePoint& b) {
              return std::tie(a.upscale.fill, a.upscale.speed_fraction, a.upscale.powder_load,
                              a.task_key) < std::tie(b.upscale.fill, b.upscale.speed_fraction,
                                                     b.upscale.powder_load, b.task_key);
            });
  std::sort(report.macro_runs.begin(), report.macro_runs.end(),
            [](const MacroRun& a, const MacroRun& b) {
              return std::tie(a.fill, a.speed_fraction, a.task_key) <
                     std::tie(b.fill, b.speed_fraction, b.task_key);
            });
  return report;
}

}  // namespace millflow::report
