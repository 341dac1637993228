#pragma once
// The report's flow-region section (tasks/report.hpp): per fill and speed, a map of the regions
// the sites task drew (regions_<fill>_<speed>.svg: the regions coloured over the cross-section,
// the charge outlined, the toe's disc and the shoulder marked), a table of each region's volume,
// solid volume and share of the macro dissipation under the default rules and each alternative,
// and, per powder load, each rule set's dominant region and toe share of the powder power (the
// upscales' `sensitivity`, tasks/upscale.hpp), and per powder load above 0 each region's powder
// share by both upscalings with the media-only cells' power over the macro dissipation; then the
// cells the upscales left out. docs/regions.md explains the rules.
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "method/sites.hpp"
#include "report/report_inputs.hpp"

namespace millflow::report {

struct RegionSection {
  std::vector<std::pair<std::string, std::string>> files;  // name, SVG text, by fill and speed
  std::string markdown;                                    // for index.md
};

// From the sites results (with their fill, speed_fraction and average_task), the sensitivity of
// the upscale results that name them (sites_task) and the flow maps by average task key, each
// read once by read_report_inputs; nothing without sites results. Throws std::invalid_argument
// naming a sites task whose average task has no flow map.
RegionSection region_section(const ReportInputs& inputs);

}  // namespace millflow::report
