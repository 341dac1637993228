#include "tasks/report.hpp"

#include <fmt/format.h>

#include "report/report.hpp"
#include "tasks/kinds.hpp"

namespace millflow::tasks {

report::ReportSources report_sources(const std::vector<engine::TaskInput>& inputs) {
  report::ReportSources sources;
  for (const engine::TaskInput& input : inputs) {
    if (input.kind == "upscale") sources.upscales.push_back({input.key, input.result});
    if (input.kind == "sites") sources.sites.push_back({input.key, input.result});
    if (input.kind == "macro") sources.macros.push_back({input.key, input.result});
    if (input.kind == "average") {
      const auto fields = input.artifacts.find("fields.json");
      sources.average_fields[input.key] =
          fields == input.artifacts.end() ? std::nullopt : std::optional(fields->second);
    }
  }
  return sources;
}

engine::TaskOutcome run_report(engine::TaskContext& context) {
  const std::string campaign = context.params.at("campaign").get<std::string>();
  const report::ReportSources sources = report_sources(context.inputs);
  const report::ReportInputs inputs = report::read_report_inputs(sources);
  const report::RegionSection regions = report::region_section(inputs);
  const report::ReportFiles files =
      report::write_report(context.work_dir, campaign, inputs, regions);
  engine::TaskOutcome outcome = engine::TaskOutcome::with_result(files.result);
  for (const std::string& name : files.names)
    outcome.artifacts.push_back({name, context.work_dir / name});
  context.log(fmt::format("report of {} points ({} fill/speed slices): {} files",
                          inputs.points.size(), files.slices, files.names.size()));
  return outcome;
}

void register_report(engine::Registry& registry) {
  registry.kinds.add(
      engine::TaskKind{.name = "report", .version = kReportVersion, .run = run_report});
}

}  // namespace millflow::tasks
