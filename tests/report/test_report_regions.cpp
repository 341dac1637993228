// The report's flow-region section: the region map of a sites task over its average's fields,
// the region and sensitivity tables, and the files the report task writes from them.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>

#include "method/fields_file.hpp"
#include "method/sites_result.hpp"
#include "report/report_regions.hpp"
#include "tasks/report.hpp"
#include "tests/common/scratch_dir.hpp"
#include "tests/tasks/upscale_inputs.hpp"

namespace millflow::tasks {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kRadius = 0.5, kOmega = 4.0;
constexpr int kCells = 20;

// A bed below y = -0.1 m turning with the shell under a layer flowing left, in a 20 x 20 grid.
json fields_document() {
  std::vector<double> nu, zero, dissipation, velocity;
  const method::CrossSectionGrid grid{.nx = kCells, .ny = kCells, .half_width = kRadius};
  for (std::size_t c = 0; c < grid.size(); ++c) {
    const double x = grid.x_of(c), y = grid.y_of(c);
    const bool bed = y<-0.1, layer = y> - 0.25;
    nu.push_back(bed ? 0.6 : 0.0);
    zero.push_back(0.0);
    dissipation.push_back(bed ? (layer ? 100.0 : 10.0) : 0.0);
    velocity.insert(velocity.end(), {bed ? (layer ? -1.0 : -kOmega * y) : 0.0,
                                     bed && !layer ? kOmega * x : 0.0, 0.0});
  }
  json arrays = {{"solid_fraction", {{"components", 1}, {"values", nu}}},
                 {"dissipation_w_m3", {{"components", 1}, {"values", dissipation}}},
                 {"velocity_m_s", {{"components", 3}, {"values", velocity}}}};
  for (const char* name : {"shear_rate_per_s", "normal_stress_pa", "shear_stress_pa", "pressure_pa",
                           "granular_temperature_m2_s2", "collision_frequency_per_m3_s"}) {
    arrays[name] = {{"components", 1}, {"values", zero}};
  }
  return {{"grid", {{"nx", kCells}, {"ny", kCells}, {"half_width_m", kRadius}}},
          {"slice_length_m", 0.1},
          {"media_diameter_m", 0.02},
          {"angular_velocity_rad_s", kOmega},
          {"arrays", arrays}};
}

// What a sites task of these fields reports, as far as the report reads it.
json sites_result() {
  method::SitesResult result{.toe_angle_deg = 210.0,
                             .shoulder_angle_deg = -30.0,
                             .fill = 0.3,
                             .speed_fraction = 0.75,
                             .average_task = "average-key",
                             .region_index = method::region_names()};
  method::RuleSet defaults{.name = "default"}, narrow{.name = "narrow"};
  for (const std::string& name : method::region_names()) {
    result.regions.push_back({.name = name,
                              .volume_m3 = 0.01,
                              .solid_volume_m3 = 0.006,
                              .dissipation_share = name == "toe" ? 0.3 : 0.1});
    defaults.regions.push_back({.name = name,
                                .volume_m3 = 0.01,
                                .solid_volume_m3 = 0.006,
                                .dissipation_share = name == "toe" ? 0.3 : 0.1});
    narrow.regions.push_back({.name = name, .dissipation_share = name == "toe" ? 0.2 : 0.16});
  }
  result.rule_sets = {defaults, narrow};
  return result;
}

// The report's inputs from the sites result above and `upscales` (task key, result).
report::ReportInputs region_inputs(const std::vector<std::pair<std::string, json>>& upscales = {}) {
  report::ReportInputs inputs{
      .sites = {report::read_sites("sites-key", sites_result())},
      .flow_maps = {{"average-key", method::flow_map_from_document(fields_document())}}};
  for (const auto& [key, result] : upscales)
    inputs.points.push_back(report::read_upscale(key, result));
  return inputs;
}

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(ReportRegions, MapsTheRegionsWithTheChargeOutlineToeAndShoulder) {
  const report::ReportInputs inputs = region_inputs();
  const std::map<std::string, method::FlowMap>& maps = inputs.flow_maps;
  const report::RegionSection section = report::region_section(inputs);
  ASSERT_EQ(section.files.size(), 1u);
  EXPECT_EQ(section.files[0].first, "regions_0.3_0.75.svg");
  const std::string& svg = section.files[0].second;
  // One rect per charge cell, one swatch per region and the background.
  const method::FlowMap& map = maps.at("average-key");
  std::size_t charge = 0;
  for (std::size_t c = 0; c < map.grid.size(); ++c)
    charge += map.grid.inside_mill(c) && map.solid_fraction[c] >= 0.02 ? 1 : 0;
  EXPECT_EQ(count_of(svg, "<rect"), charge + method::region_names().size() + 1);
  EXPECT_EQ(count_of(svg, "<path"), 1u) << "the charge outline";
  EXPECT_EQ(count_of(svg, "stroke-dasharray"), 1u) << "the toe's disc";
  EXPECT_EQ(count_of(svg, "<circle"), 3u) << "mill, toe disc, shoulder";
  for (const std::string& name : method::region_names())
    EXPECT_NE(svg.find(">" + name + "<"), std::string::npos);
  EXPECT_NE(svg.find(">shoulder<"), std::string::npos);
  EXPECT_NE(svg.find(">toe<"), std::string::npos);
  // The table: each region's volumes and its share under both rule sets.
  EXPECT_NE(section.markdown.find("| toe | 0.01 | 0.006 | 0.3 | 0.2 |"), std::string::npos)
      << section.markdown;
  EXPECT_NE(section.markdown.find("narrow rules"), std::string::npos);
}

TEST(ReportRegions, NoSitesInputsMeansNoSection) {
  const report::RegionSection section = report::region_section({});
  EXPECT_TRUE(section.files.empty());
  EXPECT_TRUE(section.markdown.empty());
}

TEST(ReportRegions, ListsTheCellsLeftOut) {
  auto point = testing::point_inputs(0.3, 0.75);
  for (auto& input : point) {
    if (input.key == "bulk-0@" + std::to_string(1.0)) input.result["steady"] = false;
  }
  const std::string markdown =
      report::region_section(region_inputs({{"upscale-1", testing::upscale(point, 1.0)}})).markdown;
  EXPECT_NE(markdown.find("| 0.3 | 0.75 | 1 | bulk-0 | 1 | not steady | no |"), std::string::npos)
      << markdown;
}

TEST(ReportRegions, TheReportWritesTheMapAndEachRuleSetsDominantRegion) {
  millflow::testing::ScratchDir dir;
  const fs::path fields = dir.path() / "fields.json";
  std::ofstream(fields) << fields_document().dump();
  const std::vector<engine::TaskInput> point = testing::point_inputs(0.3, 0.75);
  std::vector<engine::TaskInput> inputs = {
      {"average-key", "average", json::object(), {{"fields.json", fields}}},
      {"sites-key", "sites", sites_result(), {}}};
  for (double load : {0.0, 1.0})
    inputs.push_back(
        {fmt::format("upscale-{}", load), "upscale", testing::upscale(point, load), {}});
  const json params = {{"campaign", "regions"}};
  engine::TaskContext context{.key = "report",
                              .params = params,
                              .inputs = inputs,
                              .work_dir = dir.path() / "report",
                              .threads = 1,
                              .attempt = 1,
                              .stop = {},
                              .progress = [](double, std::string_view) {},
                              .log = [](std::string_view) {}};
  const auto outcome = run_report(context);
  bool map = false;
  for (const auto& artifact : outcome.artifacts)
    map = map || artifact.name == "regions_0.3_0.75.svg";
  EXPECT_TRUE(map);
  std::ifstream index(dir.path() / "report" / "index.md");
  const std::string page((std::istreambuf_iterator<char>(index)), {});
  EXPECT_NE(page.find("![flow regions](regions_0.3_0.75.svg)"), std::string::npos);
  // The upscale at load 1 (tests/tasks/upscale_inputs.hpp): toe 0.8 of 1.4 W by default, 1.6 of
  // 1.8 W under the wide rules.
  EXPECT_NE(page.find("| default | 1 | toe | 0.5714 |"), std::string::npos) << page;
  EXPECT_NE(page.find("| wide | 1 | toe | 0.8889 |"), std::string::npos);
  // Both methods side by side: the toe's share 0.8 / 1.1 from its cells, 0.8 / 1.4 anchored on
  // the macro dissipation; its media-only cell draws 0.8 of the macro run's 2 W.
  EXPECT_NE(page.find("| toe | 0.7273 | 0.5714 | 0.8 |"), std::string::npos);
  EXPECT_NE(page.find("None: every cell that ran was steady and converged."), std::string::npos);
}

}  // namespace
}  // namespace millflow::tasks
