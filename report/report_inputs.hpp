#pragma once
// The inputs of the `report` task (tasks/report.cpp gathers them from its upstream tasks by
// kind into ReportSources): every "upscale" task's result (method/upscale_result.hpp), every
// "sites" task's result (method/sites_result.hpp), the fields.json artifact of every "average" task
// an upscale names, and every "macro" task's charge shape and collision spectra
// (method/macro_result.hpp). Points are sorted by fill, speed fraction, powder load (then task
// key), so the report is the same whatever the input order.
//
// A missing or ill-typed value throws std::invalid_argument naming the task kind and key, the
// JSON pointer of the field and what was expected.
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "method/sites.hpp"
#include "method/sites_result.hpp"
#include "method/upscale_result.hpp"

namespace millflow::report {

// One upstream task's result.
struct TaskResult {
  std::string key{};
  nlohmann::json result{};
};

// What the report reads, by the kind of task it comes from.
struct ReportSources {
  std::vector<TaskResult> upscales{}, sites{}, macros{};
  // By average task key: its fields.json artifact, none when the task has none.
  std::map<std::string, std::optional<std::filesystem::path>> average_fields{};
};

// One upscale task's result, read once (method::read_upscale_result, and at least one spectrum
// bin).
struct UpscalePoint {
  std::string task_key{};
  method::UpscaleResult upscale{};
};
UpscalePoint read_upscale(const std::string& task_key, const nlohmann::json& result);

// One sites task's result, read once (method::read_sites_result).
struct SitesPoint {
  std::string task_key{};
  method::SitesResult sites{};
};
SitesPoint read_sites(const std::string& task_key, const nlohmann::json& result);

// One collision spectrum of a macro run: collisions per second in the slice per energy bin (the
// run's histogram counts over its measuring time).
struct MacroSpectrum {
  std::string label{};  // e.g. "ball_ball impact"
  std::vector<double> rate_per_s{};
};

struct MacroRun {
  std::string task_key{};
  double fill = 0.0, speed_fraction = 0.0;
  std::optional<double> toe_angle_deg, shoulder_angle_deg;  // none when undefined
  std::vector<double> bin_edges_j{};
  std::vector<MacroSpectrum> spectra{};  // per contact type: impact, then dissipated energy
};

// One macro task's result.
MacroRun read_macro(const std::string& task_key, const nlohmann::json& result);

struct ReportInputs {
  std::vector<UpscalePoint> points{};                // sorted (see above)
  std::vector<SitesPoint> sites{};                   // in the order of the sources
  std::map<std::string, method::FlowMap> flow_maps;  // by average task key
  std::vector<MacroRun> macro_runs{};                // by fill, speed fraction (then task key)
};

// Throws std::invalid_argument when there is no upscale input, an upscale names an average task
// that is not an input, or an average input has no readable fields.json.
ReportInputs read_report_inputs(const ReportSources& sources);

}  // namespace millflow::report
