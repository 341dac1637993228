// The `report` task on synthetic inputs: 2 fills x 2 speeds x 2 powder loads of upscale results
// that follow the upscale contract, and a small fields.json and a macro result per fill/speed. The
// tables must hold exactly the input values (parsed back and compared with the inputs), the page
// must link every figure, the bytes must not depend on the run or the input order, and bad inputs
// must name the task and the field.
#include "tasks/report.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>

#include <algorithm>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "method/macro_result.hpp"
#include "method/upscale_result.hpp"
#include "report/report_inputs.hpp"
#include "tests/common/scratch_dir.hpp"
#include "tests/tasks/upscale_inputs.hpp"

namespace millflow::tasks {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::vector<double> kFills = {0.2, 0.3}, kSpeeds = {0.6, 0.75}, kLoads = {0.0, 0.5};

std::string average_key(double fill, double speed) {
  return fmt::format("average-{}-{}", fill, speed);
}
std::string upscale_key(double fill, double speed, double load) {
  return fmt::format("upscale-{}-{}-{}", fill, speed, load);
}
std::string macro_key(double fill, double speed) {
  return fmt::format("macro-{}-{}", fill, speed);
}

// The macro contract's charge and spectra (tasks/macro.hpp): 3 bins over a 2 s measurement; the
// fastest run of the fuller charge has no shoulder (undefined).
json macro_result(double fill, double speed) {
  const bool shoulder = !(fill == 0.3 && speed == 0.75);
  auto collisions = [&](const char* category, double scale) {
    method::MacroCollisions c;
    c.category = category;
    c.impact_energy.counts = {400.0 * scale, 200.0 * scale, 20.0 * scale};
    c.dissipated_energy.counts = {300.0 * scale, 60.0 * scale, 2.0 * scale};
    return c;
  };
  method::MacroResult r;
  r.fill = fill;
  r.speed_fraction = speed;
  r.measure_start_s = 1.5;
  r.measure_end_s = 3.5;
  r.charge.toe_angle_deg = 200.0 + 40.0 * speed;
  if (shoulder) r.charge.shoulder_angle_deg = 20.0 + 50.0 * fill;
  r.spectrum_bin_edges_j = {1e-6, 1e-4, 1e-2, 1.0};
  r.collisions = {{"ball_ball", collisions("steel-steel", fill)},
                  {"ball_liner", collisions("steel-wall:shell", speed)}};
  return r;
}

// A toe and a bulk region; the bulk's cushioning is unknown (none) without powder, and the bulk
// site's cell was skipped, so its cell values are none.
json upscale_result(double fill, double speed, double load) {
  using Optional = std::optional<double>;
  const double draw = 2000.0 * fill + 1000.0 * speed, powder = 100.0 * load;
  auto region = [&](const char* name, double share, Optional cushioning, Optional cushioning_se) {
    return method::UpscaleRegion{
        .region = name,
        .method = "cells",
        .figures = {.sites = 1,
                    .volume_m3 = 0.001 * share,
                    .powder_power_w = share * powder,
                    .powder_power_share = load > 0 ? Optional(share) : std::nullopt,
                    .powder_power_share_se = load > 0 ? Optional(0.1 * share) : std::nullopt,
                    .media_power_w = 300.0 * share,
                    .media_collision_power_w = 60.0 * share * (1.0 - 0.2 * load),
                    .media_collision_power_no_powder_w = 60.0 * share,
                    .cushioning = cushioning,
                    .cushioning_se = cushioning_se}};
  };
  const method::UpscaleSite toe_site{
      .site_id = "toe-0",
      .region = "toe",
      .x_m = 0.1,
      .y_m = -0.3,
      .weight_m3 = 0.0006,
      .shear_rate_per_s = 12.0 * speed,
      .normal_stress_pa = 4000.0 * fill,
      .macro_shear_stress_pa = 1500.0 * fill,
      .cell_shear_stress_pa = 1400.0 * fill,
      .coupling_ratio = 1400.0 / 1500.0,
      .power_density_w_m3 = 9000.0,
      .powder_dissipation_w_m3 = 800.0 * load,
      // The cell with powder held 30% high, the other 5% low.
      .cell_normal_stress_pa = 4000.0 * fill * (load > 0 ? 1.3 : 0.95)};
  const method::UpscaleSite bulk_site{.site_id = "bulk-0",
                                      .region = "bulk",
                                      .x_m = -0.1,
                                      .y_m = -0.1,
                                      .weight_m3 = 0.0004,
                                      .shear_rate_per_s = 2.0,
                                      .normal_stress_pa = 3000.0,
                                      .macro_shear_stress_pa = 900.0,
                                      .skipped = "no steady state"};
  method::UpscaleResult r;
  r.cells = {
      .method = "cells",
      .totals = {.sites = 2, .powder_power_w = powder, .media_power_w = 300.0},
      .regions = {region("toe", 0.6, 1.0 - 0.2 * load, load > 0 ? Optional(0.05) : std::nullopt),
                  region("bulk", 0.4, load > 0 ? Optional(0.9) : std::nullopt, std::nullopt)},
      .dominant_region =  // none without powder
      load > 0 ? std::optional<std::string>("toe") : std::nullopt};
  r.fill = fill;
  r.speed_fraction = speed;
  r.powder_load = load;
  r.average_task = average_key(fill, speed);
  r.sites_task = "sites-key";
  r.mill = {.diameter_m = 1.0,
            .slice_length_m = 0.15,
            .ball_mass_kg = 123.0,
            .power_draw_w = draw,
            .specific_power_kw_per_t = draw / 123.0};
  r.power_draw_with_powder_w = draw * (1.0 + 0.1 * load);
  r.spectra = {.bin_edges_j = {1e-9, 1e-8, 1e-7, 1e-6},
               .powder_rate_per_s = {10.0 * load, 20.0 * load, 5.0 * load},
               .media_rate_per_s = {100.0, 50.0 * speed, 10.0 * fill},
               .media_rate_no_powder_per_s = {100.0, 50.0, 10.0}};
  r.sites = {toe_site, bulk_site};
  r.coupling = {
      .sites = 1, .median_ratio = 1400.0 / 1500.0, .tolerance = 0.5, .within_tolerance = 1};
  return r;
}

// A 4 x 4 grid over a mill of radius 0.5 m with made-up fields.
json fields_document(double fill) {
  json arrays = json::object();
  for (const char* name :
       {"solid_fraction", "shear_rate_per_s", "normal_stress_pa", "shear_stress_pa", "pressure_pa",
        "granular_temperature_m2_s2", "collision_frequency_per_m3_s", "dissipation_w_m3"}) {
    std::vector<double> values;
    for (int c = 0; c < 16; ++c) values.push_back(fill * (c + 1));
    arrays[name] = {{"components", 1}, {"values", values}};
  }
  arrays["velocity_m_s"] = {{"components", 3}, {"values", std::vector<double>(3 * 16, 0.1)}};
  return {{"grid", {{"nx", 4}, {"ny", 4}, {"half_width_m", 0.5}}},
          {"slice_length_m", 0.15},
          {"media_diameter_m", 0.04},
          {"angular_velocity_rad_s", 4.0},
          {"arrays", arrays}};
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<std::map<std::string, std::string>> read_csv(const fs::path& file) {
  std::istringstream in(read_text(file));
  auto split = [](const std::string& line) {
    std::vector<std::string> cells;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();
    return cells;
  };
  std::string line;
  std::getline(in, line);
  const auto header = split(line);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    const auto cells = split(line);
    EXPECT_EQ(cells.size(), header.size()) << line;
    std::map<std::string, std::string> row;
    for (std::size_t i = 0; i < std::min(cells.size(), header.size()); ++i)
      row[header[i]] = cells[i];
    rows.push_back(row);
  }
  return rows;
}

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

class Report : public ::testing::Test {
 protected:
  void SetUp() override {
    for (double fill : kFills) {
      for (double speed : kSpeeds) {
        const fs::path fields = dir_.path() / (average_key(fill, speed) + ".json");
        std::ofstream(fields) << fields_document(fill).dump();
        inputs_.push_back(
            {average_key(fill, speed), "average", json::object(), {{"fields.json", fields}}});
        inputs_.push_back({macro_key(fill, speed), "macro", macro_result(fill, speed), {}});
        for (double load : kLoads) {
          inputs_.push_back(
              {upscale_key(fill, speed, load), "upscale", upscale_result(fill, speed, load), {}});
        }
      }
    }
  }

  engine::TaskOutcome run(const std::vector<engine::TaskInput>& inputs, const std::string& work) {
    const json params = {{"campaign", "synthetic"}};
    engine::TaskContext context{.key = "report",
                                .params = params,
                                .inputs = inputs,
                                .work_dir = dir_.path() / work,
                                .threads = 1,
                                .attempt = 1,
                                .stop = {},
                                .progress = [](double, std::string_view) {},
                                .log = [](std::string_view) {}};
    return run_report(context);
  }

  // The upscale kind's own results of one hand-made point (tests/tasks/upscale_inputs.hpp) at
  // loads 0 and 1, with their average task.
  std::vector<engine::TaskInput> own_inputs(const std::vector<engine::TaskInput>& point) {
    const fs::path fields = dir_.path() / "point-fields.json";
    std::ofstream(fields) << fields_document(0.3).dump();
    std::vector<engine::TaskInput> inputs = {
        {"average-key", "average", json::object(), {{"fields.json", fields}}}};
    for (double load : {0.0, 1.0}) {
      inputs.push_back(
          {fmt::format("upscale-{}", load), "upscale", testing::upscale(point, load), {}});
    }
    return inputs;
  }

  // The error of a run whose input `key` has been changed by `edit`.
  std::string error_after(const std::string& key, const std::function<void(json&)>& edit) {
    auto inputs = inputs_;
    for (auto& input : inputs) {
      if (input.key == key) edit(input.result);
    }
    try {
      run(inputs, "bad");
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    ADD_FAILURE() << "expected std::invalid_argument";
    return {};
  }

  millflow::testing::ScratchDir dir_;
  std::vector<engine::TaskInput> inputs_;
};

const std::vector<std::string> kExpectedFiles = {"power_draw.svg",   "powder_power_shares.svg",
                                                 "cushioning.svg",   "powder_spectra.svg",
                                                 "charge_shape.svg", "macro_spectra.svg",
                                                 "maps_0.2_0.6.svg", "maps_0.2_0.75.svg",
                                                 "maps_0.3_0.6.svg", "maps_0.3_0.75.svg",
                                                 "coupling.svg",     "upscaled.csv",
                                                 "sites.csv",        "spectra.csv",
                                                 "index.md"};

TEST_F(Report, WritesEveryFileAsAnArtifact) {
  const auto outcome = run(inputs_, "work");
  std::vector<std::string> names;
  for (const auto& artifact : outcome.artifacts) {
    names.push_back(artifact.name);
    EXPECT_TRUE(fs::is_regular_file(artifact.file)) << artifact.file;
    EXPECT_EQ(artifact.file.filename(), artifact.name);
  }
  EXPECT_EQ(names, kExpectedFiles);
  EXPECT_EQ(outcome.result.at("files"), json(kExpectedFiles));
  EXPECT_EQ(outcome.result.at("points"), 8);
  EXPECT_EQ(outcome.result.at("slices"), 4);
  EXPECT_EQ(outcome.result.at("coupling"), json({{"sites", 4}, {"within_tolerance", 4}}));
}

// The upscale kind's own results (not the hand-written contract above), with and without
// powder, must read: this is the contract between the two kinds.
TEST_F(Report, ReadsTheUpscaleKindsResultsWithAndWithoutPowder) {
  const std::vector<engine::TaskInput> point = testing::point_inputs(0.3, 0.75);
  std::vector<engine::TaskInput> inputs = own_inputs(point);
  const auto outcome = run(inputs, "own");
  EXPECT_EQ(outcome.result.at("points"), 2);
  const json& dominant = outcome.result.at("dominant_regions");
  ASSERT_EQ(dominant.size(), 2u);
  EXPECT_TRUE(dominant.at(0).at("region").is_null()) << "no powder, no dominant region";
  EXPECT_EQ(dominant.at(1).at("region"), "toe");
  for (const auto& row : read_csv(dir_.path() / "own" / "upscaled.csv")) {
    EXPECT_EQ(row.at("powder_power_share").empty(), row.at("powder_load") == "0")
        << row.at("region");
  }
}

// Stiff cells (/shear_cell/stiffness/sensitivity) give their point a sentence and table rows;
// without them the page has no such section.
TEST_F(Report, StiffCellsGiveTheirPointASentence) {
  std::vector<engine::TaskInput> point = testing::point_inputs(0.3, 0.75);
  // At toe-0: media collision power 360 against 300 W/m^3, powder share 0.45 against 0.4.
  point.push_back(testing::stiff_cell(
      "toe-0", 1.0, {1000.0, 450.0, 300.0, 60.0, 940.0, {10, 0}, {5, 5}, 1e6, 1e4}, 4.0));
  std::vector<engine::TaskInput> inputs = own_inputs(point);
  run(inputs, "stiff");
  const std::string index = read_text(dir_.path() / "stiff" / "index.md");
  EXPECT_NE(index.find("- J = 0.3, phi = 0.75, U = 1: with the powder pairs 4 x stiffer, "
                       "cushioning moves by +20.0% (no standard error) and the powder share by "
                       "+12.5% (no standard error) (over 1 site); the cushioning's shift is "
                       "without a standard error to judge it by, the share's without a standard "
                       "error to judge it by.\n"),
            std::string::npos)
      << index;
  {
    // With the cells' standard errors: the media collisions' small, the powder's large, so the
    // cushioning's shift stands out of its error and the share's does not.
    std::vector<engine::TaskInput> with_errors = point;
    for (engine::TaskInput& input : with_errors) {
      if (input.kind != "shear_cell") continue;
      method::CellResult cell = input.result.get<method::CellResult>();
      method::CellStandardErrors se;
      se.power_density_w_m3 = 0.01 * cell.power_density_w_m3;
      se.powder_dissipation_w_m3 = 0.3 * cell.powder_dissipation_w_m3;
      for (std::size_t t = 0; t < se.dissipation_w_m3.size(); ++t)
        se.dissipation_w_m3[t] = 0.01 * cell.dissipation_w_m3[t];
      cell.standard_errors = se;
      input.result = cell;
    }
    run(own_inputs(with_errors), "stiff-errors");
    const std::string page = read_text(dir_.path() / "stiff-errors" / "index.md");
    EXPECT_NE(page.find("the cushioning's shift is beyond twice its standard error: a systematic "
                        "error the error bars do not carry, the share's within twice its standard "
                        "error: not resolved at this precision.\n"),
              std::string::npos)
        << page;
  }
  EXPECT_NE(index.find("| 0.3 | 0.75 | 1 | toe | 1 | 0.5 | 0.6 | +20.0% (no standard error) | "
                       "0.4 | 0.45 | +12.5% (no standard error) |\n"),
            std::string::npos);
  EXPECT_EQ(index.find("U = 0:"), std::string::npos) << "no stiff cells without powder";

  // A stiff cell left out (unsteady) leaves its point without a shift, and says why.
  point.back().result["steady"] = false;
  inputs.back().result = testing::upscale(point, 1.0);
  run(inputs, "unsteady");
  EXPECT_NE(read_text(dir_.path() / "unsteady" / "index.md")
                .find("- J = 0.3, phi = 0.75, U = 1: no site has both a default and a 4 x stiffer "
                      "cell that count (1 stiff cells left out as unsteady or unconverged).\n"),
            std::string::npos);
  run(inputs_, "plain");
  EXPECT_EQ(read_text(dir_.path() / "plain" / "index.md").find("Stiffness sensitivity"),
            std::string::npos);
}

// A point whose media-only cells were all left out of the upscaling (unsteady) has no power draw
// with powder: the report leaves it out of the plot and the tables instead of failing
// (quick.json's J = 0.35, 65% point did, with every media-only cell unsteady).
TEST_F(Report, PointWithoutPowerDrawWithPowderIsReportedWithoutIt) {
  auto inputs = inputs_;
  const std::string key = upscale_key(0.3, 0.6, 0.5);
  for (auto& input : inputs) {
    if (input.key == key) input.result["power_draw_with_powder_w"] = nullptr;
  }
  run(inputs, "no-reference");
  const auto rows = read_csv(dir_.path() / "no-reference" / "upscaled.csv");
  std::size_t blank = 0;
  for (const auto& row : rows) {
    const bool this_point = row.at("upscale_task") == key;
    EXPECT_EQ(row.at("power_draw_with_powder_w").empty(), this_point) << row.at("upscale_task");
    if (this_point) ++blank;
  }
  EXPECT_GT(blank, 0u);
}

// Every cell of a point left out as unsteady: its powers are null and its spectra hold no bin.
TEST_F(Report, APointWithoutACountedCellIsReportedAsUnknown) {
  auto inputs = inputs_;
  const std::string key = upscale_key(0.3, 0.6, 0.5);
  for (auto& input : inputs) {
    if (input.key != key) continue;
    json& r = input.result;
    for (const char* figure :
         {"powder_power_w", "powder_power_w_se", "media_power_w", "media_collision_power_w",
          "media_collision_power_no_powder_w", "powder_to_media_mass_ratio",
          "power_draw_with_powder_w", "dominant_region", "powder_power_share", "cushioning"})
      r[figure] = nullptr;
    r["regions"] = json::array();
    for (auto& [name, bins] : r["spectra"].items()) bins = json::array();
  }
  run(inputs, "uncounted");
  const std::string index = read_text(dir_.path() / "uncounted" / "index.md");
  EXPECT_NE(index.find("| 0.3 | 0.6 | 0.5 | 1200 | - | - | - | - |"), std::string::npos) << index;
  EXPECT_NE(index.find("No cell was counted at J = 0.3, phi = 0.6, U = 0.5 (0 cells left out)"),
            std::string::npos)
      << index;
  EXPECT_TRUE(fs::exists(dir_.path() / "uncounted" / "powder_spectra.svg"));
  for (const auto& row : read_csv(dir_.path() / "uncounted" / "spectra.csv"))
    EXPECT_NE(row.at("upscale_task"), key) << "a point without bins has no spectrum rows";
}

TEST_F(Report, UpscaledTableHoldsTheInputsInPointOrder) {
  run(inputs_, "work");
  const auto rows = read_csv(dir_.path() / "work" / "upscaled.csv");
  ASSERT_EQ(rows.size(), 8u * 2u);
  std::vector<std::tuple<double, double, double>> order;
  for (const auto& row : rows) {
    const double fill = std::stod(row.at("fill")), speed = std::stod(row.at("speed_fraction"));
    const double load = std::stod(row.at("powder_load"));
    order.emplace_back(fill, speed, load);
    EXPECT_EQ(row.at("upscale_task"), upscale_key(fill, speed, load));
    const json expected = upscale_result(fill, speed, load);
    const json& region = expected.at("regions").at(row.at("region") == "toe" ? 0 : 1);
    EXPECT_EQ(std::stod(row.at("powder_power_w")), region.at("powder_power_w").get<double>());
    EXPECT_EQ(std::stod(row.at("media_collision_power_w")),
              region.at("media_collision_power_w").get<double>());
    EXPECT_EQ(std::stod(row.at("power_draw_with_powder_w")),
              expected.at("power_draw_with_powder_w").get<double>());
    for (const char* column : {"cushioning", "cushioning_se", "powder_power_share_se"}) {
      if (region.at(column).is_null())
        EXPECT_EQ(row.at(column), "") << column;
      else
        EXPECT_EQ(std::stod(row.at(column)), region.at(column).get<double>()) << column;
    }
  }
  EXPECT_TRUE(std::is_sorted(order.begin(), order.end()));
}

TEST_F(Report, SitesAndSpectraTablesHoldTheInputs) {
  run(inputs_, "work");
  const auto sites = read_csv(dir_.path() / "work" / "sites.csv");
  ASSERT_EQ(sites.size(), 8u * 2u);
  for (const auto& row : sites) {
    const json expected =
        upscale_result(std::stod(row.at("fill")), std::stod(row.at("speed_fraction")),
                       std::stod(row.at("powder_load")));
    const json& site = expected.at("sites").at(row.at("site_id") == "toe-0" ? 0 : 1);
    EXPECT_EQ(std::stod(row.at("macro_shear_stress_pa")),
              site.at("macro_shear_stress_pa").get<double>());
    if (site.at("cell_shear_stress_pa").is_null()) {
      EXPECT_EQ(row.at("cell_shear_stress_pa"), "");
      EXPECT_EQ(row.at("skipped"), "no steady state");
    } else {
      EXPECT_EQ(std::stod(row.at("cell_shear_stress_pa")),
                site.at("cell_shear_stress_pa").get<double>());
      EXPECT_EQ(std::stod(row.at("cell_normal_stress_pa")),
                site.at("cell_normal_stress_pa").get<double>());
    }
  }
  // Of the eight toe cells, the four with powder held 30% above their site's normal stress.
  const std::string index = read_text(dir_.path() / "work" / "index.md");
  EXPECT_NE(index.find("Normal stress held: 4 of 8 cells held their site's normal stress within "
                       "10% over the measured window (sites.csv, cell_normal_stress_pa against "
                       "normal_stress_pa); the others measured a state of another stress, their "
                       "friction and powder figures with it: toe-0 at J = 0.2, phi = 0.6, U = 0.5 "
                       "(+30%);"),
            std::string::npos)
      << index;
  const auto spectra = read_csv(dir_.path() / "work" / "spectra.csv");
  ASSERT_EQ(spectra.size(), 8u * 3u);
  for (const auto& row : spectra) {
    const json expected =
        upscale_result(std::stod(row.at("fill")), std::stod(row.at("speed_fraction")),
                       std::stod(row.at("powder_load")));
    const std::size_t bin = std::stoul(row.at("bin"));
    EXPECT_EQ(std::stod(row.at("energy_low_j")),
              expected.at("spectra").at("bin_edges_j").at(bin).get<double>());
    EXPECT_EQ(std::stod(row.at("media_rate_per_s")),
              expected.at("spectra").at("media_rate_per_s").at(bin).get<double>());
  }
}

TEST_F(Report, IndexLinksEveryFigureAndTable) {
  run(inputs_, "work");
  const std::string index = read_text(dir_.path() / "work" / "index.md");
  for (const std::string& file : kExpectedFiles) {
    if (file == "index.md") continue;
    EXPECT_NE(index.find("](" + file + ")"), std::string::npos) << file;
  }
  EXPECT_EQ(count_of(index, "| toe |"), 4u);  // the dominant region of every point with powder
  EXPECT_EQ(count_of(index, "| - |"), 4u);    // and none without
}

TEST_F(Report, FiguresDrawOneMarkerPerComparedSite) {
  run(inputs_, "work");
  // Four slices, each with one site that has a cell result; the 1:1 line has no markers.
  EXPECT_EQ(count_of(read_text(dir_.path() / "work" / "coupling.svg"), "<circle"), 4u);
  // Three panels, each with the mill outline and the two sites.
  EXPECT_EQ(count_of(read_text(dir_.path() / "work" / "maps_0.3_0.75.svg"), "<circle"), 3u * 3u);
}

TEST_F(Report, ErrorBarsWhereTheUpscaleGivesAStandardError) {
  run(inputs_, "work");
  // Shares: both regions' at load 0.5 in each of the 4 panels; cushioning: the toe's at load 0.5.
  // Each bar is three <line>s (svg_plot.hpp).
  const std::string bar = "class=\"error-bar\"";
  EXPECT_EQ(count_of(read_text(dir_.path() / "work" / "powder_power_shares.svg"), bar),
            4u * 2u * 3u);
  EXPECT_EQ(count_of(read_text(dir_.path() / "work" / "cushioning.svg"), bar), 4u * 1u * 3u);
}

TEST_F(Report, ChargeShapeHasAMarkerPerDefinedAngle) {
  run(inputs_, "work");
  const std::string svg = read_text(dir_.path() / "work" / "charge_shape.svg");
  // 4 runs x (toe, shoulder), less the one undefined shoulder; a toe and a shoulder line per fill.
  EXPECT_EQ(count_of(svg, "<circle"), 4u * 2u - 1u);
  EXPECT_EQ(count_of(svg, "<path"), 2u * 2u);
  EXPECT_NE(svg.find(">J = 0.3 shoulder<"), std::string::npos);
}

TEST_F(Report, MacroSpectraAreCollisionsPerSecondPerRun) {
  const report::MacroRun run = report::read_macro("m", macro_result(0.2, 0.6));
  ASSERT_EQ(run.spectra.size(), 4u);
  EXPECT_EQ(run.spectra[0].label, "ball_ball impact");
  EXPECT_EQ(run.spectra[3].label, "ball_liner dissipated");
  // Counts over the 2 s measurement (ball_ball scaled by the fill, ball_liner by the speed).
  EXPECT_EQ(run.spectra[0].rate_per_s,
            (std::vector<double>{400.0 * 0.2 / 2, 200.0 * 0.2 / 2, 20.0 * 0.2 / 2}));
  EXPECT_EQ(run.spectra[3].rate_per_s,
            (std::vector<double>{300.0 * 0.6 / 2, 60.0 * 0.6 / 2, 2.0 * 0.6 / 2}));
  ASSERT_TRUE(run.toe_angle_deg.has_value());
  EXPECT_DOUBLE_EQ(*run.toe_angle_deg, 224.0);

  this->run(inputs_, "work");
  // A panel per run, a step line per contact type and energy.
  EXPECT_EQ(count_of(read_text(dir_.path() / "work" / "macro_spectra.svg"), "<path"), 4u * 4u);
}

TEST_F(Report, MacroFieldErrorsNameTheMacroTask) {
  const std::string key = macro_key(0.2, 0.75);
  const std::string short_spectrum = error_after(
      key, [](json& r) { r["spectra"]["ball_liner"]["dissipated_energy"]["counts"] = {1.0}; });
  EXPECT_NE(short_spectrum.find("macro task " + key +
                                ": field /spectra/ball_liner/dissipated_energy/counts does not "
                                "hold 3 bins"),
            std::string::npos)
      << short_spectrum;
  const std::string no_charge = error_after(key, [](json& r) { r.erase("charge"); });
  EXPECT_NE(no_charge.find("/charge/toe_angle_deg is missing"), std::string::npos) << no_charge;
}

// Every figure renders (rsvg-convert) and no label leaves the canvas or covers another one,
// from the SVG's own text boxes (tests/report/check_svg_text.py).
TEST_F(Report, FiguresRenderWithEveryLabelInsideTheCanvasAndApart) {
  run(inputs_, "work");
  const std::string command = std::string("/usr/bin/python3 ") + MILLFLOW_SOURCE_DIR +
                              "/tests/report/check_svg_text.py " + (dir_.path() / "work").string();
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status)) << command;
  if (WEXITSTATUS(status) == 77) GTEST_SKIP() << "rsvg-convert is not installed (librsvg2-bin)";
  EXPECT_EQ(WEXITSTATUS(status), 0) << command;
}

TEST_F(Report, SameInputsInAnyOrderGiveTheSameBytes) {
  run(inputs_, "first");
  auto reversed = inputs_;
  std::reverse(reversed.begin(), reversed.end());
  run(reversed, "second");
  for (const std::string& file : kExpectedFiles) {
    EXPECT_EQ(read_text(dir_.path() / "first" / file), read_text(dir_.path() / "second" / file))
        << file;
  }
}

TEST_F(Report, MissingOrIllTypedFieldNamesTheTaskAndTheField) {
  const std::string key = upscale_key(0.3, 0.6, 0.5);
  const std::string missing =
      error_after(key, [](json& r) { r["regions"][1].erase("powder_power_w"); });
  EXPECT_NE(missing.find("upscale task " + key), std::string::npos) << missing;
  EXPECT_NE(missing.find("/regions/1/powder_power_w is missing"), std::string::npos) << missing;

  const std::string ill_typed = error_after(key, [](json& r) { r["fill"] = "high"; });
  EXPECT_NE(ill_typed.find("/fill is \"high\", not a number"), std::string::npos) << ill_typed;

  const std::string short_spectrum =
      error_after(key, [](json& r) { r["spectra"]["media_rate_per_s"] = {1.0}; });
  EXPECT_NE(short_spectrum.find("/spectra/media_rate_per_s does not hold 3 bins"),
            std::string::npos)
      << short_spectrum;
}

TEST_F(Report, UnknownAverageTaskIsNamed) {
  const std::string key = upscale_key(0.2, 0.6, 0.0);
  const std::string error = error_after(key, [](json& r) { r["average_task"] = "nowhere"; });
  EXPECT_NE(error.find("upscale task " + key + ": field /average_task names nowhere"),
            std::string::npos)
      << error;
}

TEST_F(Report, UnreadableFieldsNameTheAverageTask) {
  auto inputs = inputs_;
  const std::string key = average_key(0.2, 0.75);
  for (auto& input : inputs) {
    if (input.key == key) {
      const fs::path broken = dir_.path() / "broken.json";
      std::ofstream(broken) << json{{"grid", {{"nx", 4}, {"ny", 4}, {"half_width_m", 0.5}}}}.dump();
      input.artifacts["fields.json"] = broken;
    }
  }
  try {
    run(inputs, "bad");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("average task " + key + ": fields.json"),
              std::string::npos)
        << error.what();
  }
}

TEST_F(Report, NoUpscaleInputIsRefused) {
  std::vector<engine::TaskInput> averages;
  for (const auto& input : inputs_) {
    if (input.kind == "average") averages.push_back(input);
  }
  EXPECT_THROW(run(averages, "empty"), std::invalid_argument);
}

}  // namespace
}  // namespace millflow::tasks
