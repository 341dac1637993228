#include "tasks/report.hpp"

#include <fmt/format.h>

#include "report/report.hpp"
#include "tasks/kinds.hpp"

namespace millflow::tasks {

engine::TaskOutcome run_report(engine::TaskContext& context) {
  const std::string campaign = context.params.at("campaign").get<std::string>();
  const millflow::report::ReportInputs inputs =
      millflow::report::read_report_inputs(context.inputs);
  const millflow::report::RegionSection regions =
      millflow::report::region_section(context.inputs, inputs.flow_maps);
  const millflow::report::ReportFiles files =
      millflow::report::write_report(context.work_dir, campaign, inputs, regions);
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
