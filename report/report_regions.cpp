#include "report/report_regions.hpp"

#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "method/sites_result.hpp"
#include "method/upscale_result.hpp"
#include "report/svg_plot.hpp"

namespace millflow::report {
namespace {

std::string number(double value) {
  return fmt::format("{:.4g}", value);
}

std::string number(const std::optional<double>& value) {
  return value ? fmt::format("{:.4g}", *value) : "n/a";
}

svg::Figure region_map(const std::string& title, const method::FlowMap& map,
                       const method::SitesResult& sites) {
  const method::ChargeAngles angles = sites.angles();
  const method::Classification regions = method::classify_regions(map, sites.rules, angles);
  svg::CategoryMap figure{.title = title,
                          .grid = map.grid,
                          .category = regions.region_of_cell,
                          .names = method::region_names()};
  if (regions.toe) {
    figure.discs.push_back({.x = regions.toe->x,
                            .y = regions.toe->y,
                            .radius = regions.toe->radius_m,
                            .label = "toe"});
  }
  if (angles.shoulder_deg) {  // on the shell, where the macro run's balls leave it
    const double a = *angles.shoulder_deg * std::numbers::pi / 180.0,
                 r = 0.97 * map.grid.half_width;
    figure.markers.push_back({.x = r * std::cos(a), .y = r * std::sin(a), .label = "shoulder"});
  }
  return svg::category_map(figure);
}

// Region | volume | solid volume | share of the macro dissipation under each rule set.
std::string regions_table(const method::SitesResult& sites) {
  std::string out = "| region | volume (m^3) | solid volume (m^3) |";
  std::string rule = "|---|---|---|";
  for (const method::RuleSet& set : sites.rule_sets) {
    out += fmt::format(" share of the macro dissipation, {} rules |", set.name);
    rule += "---|";
  }
  out += "\n" + rule + "\n";
  for (std::size_t r = 0; r < sites.regions.size(); ++r) {
    const method::RegionSummary& region = sites.regions[r];
    out += fmt::format("| {} | {} | {} |", region.name, number(region.volume_m3),
                       number(region.solid_volume_m3));
    for (const method::RuleSet& set : sites.rule_sets)
      out += fmt::format(" {} |", number(set.regions.at(r).dissipation_share));
    out += "\n";
  }
  return out;
}

// Rule set | powder load | dominant region | toe share of the powder power (both macro-anchored),
// loads above 0.
std::string sensitivity_table(const std::map<double, const method::UpscaleResult*>& by_load) {
  std::string out =
      "| rule set | powder load U | dominant region, macro-anchored | toe share of the powder "
      "power, macro-anchored |\n"
      "|---|---|---|---|\n";
  for (const auto& [load, upscale] : by_load) {
    if (load == 0.0) continue;
    for (const method::UpscaleSensitivity& set : upscale->sensitivity) {
      out += fmt::format("| {} | {:g} | {} | {} |\n", set.rule_set, load,
                         set.dominant_region.value_or("none"), number(set.toe_powder_power_share));
    }
  }
  return out;
}

// Per region with cells: the powder power share by both methods and the media-only cells' power
// over the macro dissipation (tasks/upscale.hpp).
std::string methods_table(const method::UpscaleResult& upscale) {
  std::string out =
      "| region | powder power share, cells | powder power share, macro-anchored | cell power / "
      "macro dissipation |\n|---|---|---|---|\n";
  const std::vector<method::UpscaleRegion>& anchored = upscale.macro_anchored.figures.regions;
  for (std::size_t r = 0; r < upscale.cells.regions.size(); ++r) {
    const method::UpscaleRegion& cells = upscale.cells.regions[r];
    out += fmt::format(
        "| {} | {} | {} | {} |\n", cells.region, number(cells.figures.powder_power_share),
        number(anchored.at(r).figures.powder_power_share), number(cells.cell_to_macro_power_ratio));
  }
  return out;
}

// The cells an upscale left out (or counted against their flags), one row each.
std::string left_out_rows(const method::UpscaleResult& upscale) {
  std::string out;
  for (const method::LeftOutCell& cell : upscale.left_out_cells) {
    out += fmt::format("| {:g} | {:g} | {:g} | {} | {:g} | {} | {} |\n", upscale.fill,
                       upscale.speed_fraction, upscale.powder_load, cell.site_id, cell.powder_load,
                       cell.reason, cell.counted ? "yes" : "no");
  }
  return out;
}

}  // namespace

RegionSection region_section(const ReportInputs& inputs) {
  // Sites tasks by fill and speed, and the sensitivity of each of their upscales by load.
  std::map<std::pair<double, double>, const SitesPoint*> sites_tasks;
  // By sites task, then load.
  std::map<std::string, std::map<double, const method::UpscaleResult*>> upscales;
  for (const UpscalePoint& point : inputs.points)
    upscales[point.upscale.sites_task][point.upscale.powder_load] = &point.upscale;
  for (const SitesPoint& input : inputs.sites)
    sites_tasks[{input.sites.fill, input.sites.speed_fraction}] = &input;
  RegionSection section;
  if (sites_tasks.empty()) return section;
  section.markdown =
      "## Flow regions\n\n"
      "The regions the sites were chosen in (docs/regions.md gives the rules): the charge "
      "outlined in black, the toe's disc dashed around the macro run's toe, the shoulder where "
      "the macro run's balls leave the shell. The tables give each region's volume, solid "
      "volume and share of the macro run's dissipation under the default rules and the "
      "alternatives, and for each powder load which region takes the most powder power and the "
      "toe's share of it under each rule set (macro-anchored: each region's macro dissipation "
      "split as its cells split theirs).\n\n";
  for (const auto& [point, input] : sites_tasks) {
    const auto& [fill, speed] = point;
    const method::SitesResult& sites = input->sites;
    const std::string& average = sites.average_task;
    const auto map = inputs.flow_maps.find(average);
    if (map == inputs.flow_maps.end()) {
      throw std::invalid_argument(fmt::format(
          "sites task {} names average task {}, which is not an input of the report: re-plan "
          "the campaign",
          input->task_key, average));
    }
    const std::string file = fmt::format("regions_{:g}_{:g}.svg", fill, speed);
    const std::string title = fmt::format("Flow regions, J = {:g}, phi = {:g}", fill, speed);
    section.files.emplace_back(file, region_map(title, map->second, sites).svg);
    section.markdown +=
        fmt::format("### J = {:g}, phi = {:g}\n\n![flow regions]({})\n\n", fill, speed, file) +
        regions_table(sites) + "\n";
    if (const auto found = upscales.find(input->task_key); found != upscales.end())
      section.markdown += sensitivity_table(found->second) + "\n";
    if (const auto found = upscales.find(input->task_key); found != upscales.end()) {
      for (const auto& [load, upscale] : found->second) {
        if (load == 0.0) continue;
        section.markdown +=
            fmt::format("Both upscalings at U = {:g}:\n\n", load) + methods_table(*upscale) + "\n";
      }
    }
  }
  std::string left_out;
  for (const auto& [sites, by_load] : upscales) {
    for (const auto& [load, upscale] : by_load) left_out += left_out_rows(*upscale);
  }
  section.markdown +=
      "## Cells left out of the upscaling\n\n"
      "Cells that did not reach a steady state or did not converge count in no upscale unless "
      "/upscale/include_unsteady is set (then `counted` is yes).\n\n" +
      (left_out.empty() ? std::string("None: every cell that ran was steady and converged.\n")
                        : "| J | phi | upscale U | site | cell U | reason | counted |\n"
                          "|---|---|---|---|---|---|---|\n" +
                              left_out);
  return section;
}

}  // namespace millflow::report
