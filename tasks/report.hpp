#pragma once
// The `report` task kind (one per campaign): the campaign report (report/report.hpp says what it
// writes) over every upscale point of the campaign.
//
// Parameters: {"campaign": name} (the page's title). Inputs, found by kind (never by position):
// every "upscale" task of the campaign, the "average" tasks they name (their fields.json), the
// "sites" tasks of the same points (their regions) and the "macro" tasks (charge shape and
// collision spectra), see report/report_inputs.hpp. The files are the task's artifacts, under the
// same names.
#include <vector>

#include "engine/campaign.hpp"
#include "engine/task.hpp"
#include "report/report_inputs.hpp"

namespace millflow::tasks {

// Bump whenever the report's files or result change.
inline constexpr const char* kReportVersion = "9";

// The upstream results the report reads, by kind, and each average task's fields.json artifact.
report::ReportSources report_sources(const std::vector<engine::TaskInput>& inputs);

engine::TaskOutcome run_report(engine::TaskContext& context);

void register_report(engine::Registry& registry);

}  // namespace millflow::tasks
