// The upscale kind: site-weighted sums of hand-made shear cells checked against the formulas of
// tasks/upscale.hpp worked out by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <tuple>

#include "engine/sqlite.hpp"
#include "engine/store.hpp"
#include "method/upscale_result.hpp"
#include "tasks/upscale.hpp"
#include "tests/common/scratch_dir.hpp"
#include "tests/tasks/upscale_inputs.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;
using testing::point_inputs;
using testing::upscale;

TEST(Upscale, PowersSharesAndCushioningAreTheSiteWeightedSums) {
  const json r = upscale(point_inputs(), 1.0);
  // Powder: 0.002 x 400 + 0.003 x 100 W; media: the rest of the power put in.
  EXPECT_DOUBLE_EQ(r.at("powder_power_w"), 1.1);
  EXPECT_DOUBLE_EQ(r.at("media_power_w"), 0.002 * 600 + 0.003 * 400);
  // Media collision power (media-media + wall-media), with and without powder.
  EXPECT_DOUBLE_EQ(r.at("media_collision_power_w"), 0.002 * 300 + 0.003 * 200);
  EXPECT_DOUBLE_EQ(r.at("media_collision_power_no_powder_w"), 0.002 * 600 + 0.003 * 350);
  EXPECT_DOUBLE_EQ(r.at("cushioning"), 1.2 / 2.25);
  // The macro draw scaled by the cells' power input with / without powder, 3.5 W / 2.8 W, and by
  // the powder's mass: 2000 x 0.2 / (8000 x 0.5) = 0.1 of the media's at every site.
  EXPECT_DOUBLE_EQ(r.at("powder_to_media_mass_ratio"), 0.1);
  EXPECT_DOUBLE_EQ(r.at("power_draw_with_powder_w"), 1000.0 * 1.1 * 3.5 / 2.8);
  EXPECT_EQ(r.at("dominant_region"), "toe");
  EXPECT_EQ(r.at("average_task"), "average-key");
  EXPECT_DOUBLE_EQ(r.at("mill").at("diameter_m"), 1.0);

  ASSERT_EQ(r.at("regions").size(), 2u);  // method::region_names() order: toe before bulk
  const json& toe = r.at("regions").at(0);
  const json& bulk = r.at("regions").at(1);
  EXPECT_EQ(toe.at("region"), "toe");
  EXPECT_DOUBLE_EQ(toe.at("powder_power_share"), 0.8 / 1.1);
  EXPECT_DOUBLE_EQ(bulk.at("powder_power_share"), 0.3 / 1.1);
  EXPECT_EQ(bulk.at("sites"), 1) << "the skipped bulk-1 counts nowhere";
  EXPECT_DOUBLE_EQ(toe.at("cushioning"), 300.0 / 600.0);
  EXPECT_DOUBLE_EQ(bulk.at("cushioning"), 200.0 / 350.0);
}

TEST(Upscale, SpectraAreCollisionsPerSecondInTheSlice) {
  const json s = upscale(point_inputs(), 1.0).at("spectra");
  // Each cell: weight / (volume x duration) = w / 2e-4 per count.
  const double toe = 0.002 / 2e-4, bulk = 0.003 / 2e-4;
  EXPECT_EQ(s.at("bin_edges_j"), (json{1e-6, 1e-5, 1e-4}));
  EXPECT_DOUBLE_EQ(s.at("media_rate_per_s").at(0), 10 * toe + 2 * bulk);
  EXPECT_DOUBLE_EQ(s.at("media_rate_per_s").at(1), 0 * toe + 2 * bulk);
  EXPECT_DOUBLE_EQ(s.at("powder_rate_per_s").at(1), 5 * toe + 4 * bulk);
}

TEST(Upscale, MacroAnchoredSpectraScaleEachRegionsCellsToItsMacroDissipation) {
  const json r = upscale(point_inputs(), 1.0);
  // Loaded cells scaled by 2 W / 2 W at the toe and 3 W / 1.5 W in the bulk; the media-only cells
  // by 2 W / 1.6 W and 3 W / 1.2 W.
  const json& s = r.at("macro_anchored").at("spectra");
  const double toe = 0.002 / 2e-4, bulk = 0.003 / 2e-4;
  EXPECT_DOUBLE_EQ(s.at("powder_rate_per_s").at(1), 1.0 * 5 * toe + 2.0 * 4 * bulk);
  EXPECT_DOUBLE_EQ(s.at("media_rate_no_powder_per_s").at(0), 1.25 * 20 * toe + 2.5 * 4 * bulk);
  // The cells' own spectra are the same sums unscaled.
  EXPECT_DOUBLE_EQ(r.at("spectra").at("powder_rate_per_s").at(1), 5 * toe + 4 * bulk);
}

TEST(Upscale, CouplingComparesTheMediaOnlyCellWithTheMacroShearStress) {
  const json r = upscale(point_inputs(), 1.0);
  const json& sites = r.at("sites");
  ASSERT_EQ(sites.size(), 3u);
  EXPECT_DOUBLE_EQ(sites.at(0).at("coupling_ratio"), 880.0 / 800.0);
  EXPECT_DOUBLE_EQ(sites.at(1).at("coupling_ratio"), 450.0 / 500.0);
  EXPECT_TRUE(sites.at(2).at("coupling_ratio").is_null());
  EXPECT_EQ(sites.at(2).at("skipped"), "no shear cell ran at this site");
  // The normal stress held is the cell's at this point's load (1), not the media-only one's.
  EXPECT_DOUBLE_EQ(sites.at(0).at("cell_normal_stress_pa"), 2101.0);
  EXPECT_TRUE(sites.at(2).at("cell_normal_stress_pa").is_null());
  EXPECT_EQ(r.at("coupling").at("sites"), 2);
  EXPECT_DOUBLE_EQ(r.at("coupling").at("median_ratio"), 0.5 * (880.0 / 800.0 + 450.0 / 500.0));
  EXPECT_EQ(r.at("coupling").at("within_tolerance"), 2);
}

TEST(Upscale, NoPowderMeansNoPowderPowerAndNoCushioning) {
  const json r = upscale(point_inputs(), 0.0);
  EXPECT_DOUBLE_EQ(r.at("powder_power_w"), 0.0);
  EXPECT_DOUBLE_EQ(r.at("cushioning"), 1.0);
  EXPECT_DOUBLE_EQ(r.at("power_draw_with_powder_w"), 1000.0);
  EXPECT_TRUE(r.at("dominant_region").is_null());
  EXPECT_DOUBLE_EQ(r.at("cushioning_rate_factor"), 1.0);
  EXPECT_DOUBLE_EQ(r.at("cushioning_energy_factor"), 1.0);
}

// Changes the cell `upscale_inputs.hpp` gives a site at a load.
template <class Edit>
void edit_cell(std::vector<engine::TaskInput>& inputs, const std::string& site, double load,
               Edit edit) {
  for (auto& input : inputs) {
    if (input.key != site + "@" + std::to_string(load)) continue;
    auto cell = input.result.get<method::CellResult>();
    edit(cell);
    input.result = cell;
    return;
  }
  throw std::logic_error("no cell " + site);
}

TEST(Upscale, CushioningIsTheRateFactorTimesTheEnergyFactor) {
  const json r = upscale(point_inputs(), 1.0);
  // Toe: 2e6 / 3e6 media collisions per second (0.002 m^3 x 1e6 and x 1.5e6 per m^3 s), at
  // 300 / 600 W: each collision loses 0.75 of its energy without powder.
  const json& toe = r.at("regions").at(0);
  EXPECT_DOUBLE_EQ(toe.at("cushioning_rate_factor"), 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(toe.at("cushioning_energy_factor"), 0.75);
  for (const json& row : {r, r.at("regions").at(0), r.at("regions").at(1), r.at("macro_anchored"),
                          r.at("macro_anchored").at("regions").at(1)}) {
    EXPECT_NEAR(row.at("cushioning_rate_factor").get<double>() *
                    row.at("cushioning_energy_factor").get<double>(),
                row.at("cushioning").get<double>(), 1e-14);
  }
}

TEST(Upscale, MacroAnchoredConservesTheMacroDissipationOfTheRegionsWithCells) {
  const json r = upscale(point_inputs(), 1.0);
  const json& anchored = r.at("macro_anchored");
  // Toe and bulk have cells (2 W + 3 W of the macro run's dissipation); cascading (1 W) has none.
  EXPECT_DOUBLE_EQ(anchored.at("macro_dissipation_w"), 5.0);
  EXPECT_DOUBLE_EQ(anchored.at("uncovered_macro_dissipation_w"), 1.0);
  double total = 0.0;
  for (const json& region : anchored.at("regions")) {
    const double power =
        region.at("powder_power_w").get<double>() + region.at("media_power_w").get<double>();
    EXPECT_NEAR(power, region.at("macro_dissipation_w").get<double>(), 1e-15);
    EXPECT_EQ(region.at("method"), "macro_anchored");
    total += power;
  }
  EXPECT_NEAR(total, 5.0, 1e-15);
  EXPECT_NEAR(
      anchored.at("powder_power_w").get<double>() + anchored.at("media_power_w").get<double>(), 5.0,
      1e-15);
  // The split is the cells': 400 of 1000 W/m^3 at the toe, 100 of 500 in the bulk.
  EXPECT_DOUBLE_EQ(anchored.at("regions").at(0).at("powder_power_w"), 0.4 * 2.0);
  EXPECT_DOUBLE_EQ(anchored.at("regions").at(1).at("powder_power_w"), 0.2 * 3.0);
  EXPECT_EQ(anchored.at("dominant_region"), "toe");
  // Cell power without powder over the macro dissipation: 0.002 x 800 / 2, 0.003 x 400 / 3.
  EXPECT_DOUBLE_EQ(r.at("regions").at(0).at("cell_to_macro_power_ratio"), 0.8);
  EXPECT_DOUBLE_EQ(r.at("regions").at(1).at("cell_to_macro_power_ratio"), 0.4);
  EXPECT_EQ(r.at("regions").at(0).at("method"), "cells");
  EXPECT_DOUBLE_EQ(anchored.at("regions").at(0).at("cell_to_macro_power_ratio"), 0.8);
}

TEST(Upscale, SensitivityGivesEachRuleSetsDominantRegionAndToeShare) {
  const json s = upscale(point_inputs(), 1.0).at("sensitivity");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s.at(0).at("rule_set"), "default");
  EXPECT_DOUBLE_EQ(s.at(0).at("toe_powder_power_share"), 0.8 / (0.8 + 0.6));
  EXPECT_EQ(s.at(1).at("rule_set"), "wide");
  EXPECT_DOUBLE_EQ(s.at(1).at("toe_powder_power_share"), 1.6 / (1.6 + 0.2));
  EXPECT_EQ(s.at(1).at("dominant_region"), "toe");
}

TEST(Upscale, UnsteadyAndUnconvergedCellsAreLeftOutAndListed) {
  auto inputs = point_inputs();
  edit_cell(inputs, "bulk-0", 1.0, [](method::CellResult& cell) { cell.steady = false; });
  edit_cell(inputs, "toe-0", 0.0, [](method::CellResult& cell) { cell.converged = false; });
  const json r = upscale(inputs, 1.0);
  ASSERT_EQ(r.at("left_out_cells").size(), 2u);
  EXPECT_EQ(r.at("left_out_cells").at(0).at("reason"), "not steady");
  EXPECT_EQ(r.at("left_out_cells").at(1).at("reason"), "not converged");
  EXPECT_EQ(r.at("left_out_cells").at(1).at("counted"), false);
  EXPECT_DOUBLE_EQ(r.at("powder_power_w"), 0.002 * 400);  // the toe's loaded cell alone
  EXPECT_TRUE(r.at("cushioning").is_null());              // no baseline left to compare with
  EXPECT_TRUE(r.at("regions").at(0).at("cell_to_macro_power_ratio").is_null());
  const json kept = upscale(inputs, 1.0, true);
  EXPECT_DOUBLE_EQ(kept.at("powder_power_w"), 1.1);
  EXPECT_EQ(kept.at("left_out_cells").at(0).at("counted"), true);
}

TEST(Upscale, APointWhoseCellsAreAllLeftOutHasUnknownPowersNotZero) {
  auto inputs = point_inputs();
  for (const char* site : {"toe-0", "bulk-0"})
    edit_cell(inputs, site, 1.0, [](method::CellResult& cell) { cell.steady = false; });
  const json r = upscale(inputs, 1.0);
  for (const char* figure : {"powder_power_w", "powder_power_w_se", "media_power_w",
                             "media_collision_power_w", "media_collision_power_no_powder_w",
                             "powder_to_media_mass_ratio", "power_draw_with_powder_w"})
    EXPECT_TRUE(r.at(figure).is_null()) << figure;
  EXPECT_TRUE(r.at("macro_anchored").at("powder_power_w").is_null());
  EXPECT_TRUE(r.at("spectra").at("bin_edges_j").empty());
  EXPECT_EQ(r.at("sites").at(0).at("skipped"),
            "its cell was left out (not steady); /upscale/include_unsteady counts such cells");
  // The stored result reads back (the report's reader).
  const method::UpscaleResult read = method::read_upscale_result(r, "upscale", "re-run it");
  EXPECT_FALSE(read.cells.totals.powder_power_w);
  EXPECT_FALSE(read.powder_to_media_mass_ratio);
}

// A row per method and region; a point without a counted cell keeps one row per method.
TEST(UpscaledResultsView, APointWithoutACountedCellKeepsARowWithoutRegion) {
  const millflow::testing::ScratchDir scratch;
  const auto db = scratch.db();
  engine::SystemClock clock;
  engine::Store store(db, {upscaled_results_view()}, clock);
  auto uncounted_inputs = point_inputs();
  for (const char* site : {"toe-0", "bulk-0"})
    edit_cell(uncounted_inputs, site, 1.0, [](method::CellResult& cell) { cell.steady = false; });
  const std::vector<std::pair<engine::TaskSpec, json>> points = {
      {engine::make_task_spec("upscale", kUpscaleVersion, {{"point", 1}}, {}),
       upscale(point_inputs(), 1.0)},
      {engine::make_task_spec("upscale", kUpscaleVersion, {{"point", 2}}, {}),
       upscale(uncounted_inputs, 1.0)}};
  const auto campaign = store.register_campaign("c1", "millflow_campaign", json::object(),
                                                {points[0].first, points[1].first});
  for (const auto& [spec, result] : points) {
    store.mark_running(spec.key);
    store.commit_done(campaign, spec.key, result, {}, {}, 1.0);
  }
  auto read = engine::open_read_only(db);
  auto rows = read.prepare(
      "SELECT method, region IS NULL, mill_powder_power_w IS NULL, left_out_cells "
      "FROM upscaled_results WHERE task_key = ? ORDER BY method, region");
  rows.bind(1, points[1].first.key);
  for (const char* method : {"cells", "macro_anchored"}) {
    ASSERT_TRUE(rows.step()) << method;
    EXPECT_EQ(rows.text(0), method);
    EXPECT_EQ(rows.integer(1), 1);
    EXPECT_EQ(rows.integer(2), 1);
    EXPECT_EQ(rows.integer(3), 2);
  }
  EXPECT_FALSE(rows.step());
  auto counted = read.prepare("SELECT count(*) FROM upscaled_results WHERE task_key = ?");
  counted.bind(1, points[0].first.key);
  ASSERT_TRUE(counted.step());
  EXPECT_EQ(counted.integer(0), 4) << "toe and bulk under each method";
}

TEST(Upscale, StandardErrorsOfTheCellsPropagate) {
  EXPECT_TRUE(upscale(point_inputs(), 1.0).at("powder_power_w_se").is_null())
      << "cells without standard errors give none";
  auto inputs = point_inputs();
  for (const auto& [site, load, powder, collisions] : {std::tuple{"toe-0", 1.0, 10.0, 6.0},
                                                       {"bulk-0", 1.0, 5.0, 4.0},
                                                       {"toe-0", 0.0, 0.0, 9.0},
                                                       {"bulk-0", 0.0, 0.0, 7.0}}) {
    edit_cell(inputs, site, load, [&](method::CellResult& cell) {
      method::CellStandardErrors se{.power_density_w_m3 = 20.0, .powder_dissipation_w_m3 = powder};
      se.dissipation_w_m3[static_cast<std::size_t>(dem::ContactType::MediaMedia)] = collisions;
      se.dissipation_w_m3[static_cast<std::size_t>(dem::ContactType::WallMedia)] = 1.0;
      cell.standard_errors = se;
    });
  }
  const json r = upscale(inputs, 1.0);
  EXPECT_DOUBLE_EQ(r.at("powder_power_w_se"), std::hypot(0.002 * 10.0, 0.003 * 5.0));
  // Cushioning C(U) / C(0): relative errors in quadrature; wall-media adds to media-media.
  const double c = 1.2, c0 = 2.25, c_se = std::hypot(0.002 * 7.0, 0.003 * 5.0),
               c0_se = std::hypot(0.002 * 10.0, 0.003 * 8.0);
  EXPECT_NEAR(r.at("cushioning_se").get<double>(), c / c0 * std::hypot(c_se / c, c0_se / c0),
              1e-15);
  const json& toe = r.at("regions").at(0);
  EXPECT_NEAR(toe.at("powder_power_share_se").get<double>(),
              0.8 / 1.1 * std::hypot(0.02 / 0.8, std::hypot(0.02, 0.015) / 1.1), 1e-15);
  // Collision rates count as Poisson: 1/sqrt(1e4) and 1/sqrt(1.5e4) for the toe.
  EXPECT_NEAR(toe.at("cushioning_rate_factor_se").get<double>(),
              2.0 / 3.0 * std::hypot(0.01, 1.0 / std::sqrt(1.5e4)), 1e-15);
  EXPECT_TRUE(toe.at("cushioning_energy_factor_se").is_number());
}

// A stiff cell (stiffness_factor 4) at toe-0, load 1: its media collision power 1.2 times the
// default cell's (360 against 300 W/m^3), its powder's share of the power put in 0.45 against 0.4.
engine::TaskInput stiff_toe_cell() {
  return testing::stiff_cell("toe-0", 1.0,
                             {1000.0, 450.0, 300.0, 60.0, 940.0, {10, 0}, {5, 5}, 1e6, 1e4}, 4.0);
}

void set_errors(method::CellResult& cell, double powder, double collisions) {
  method::CellStandardErrors se{.power_density_w_m3 = 20.0, .powder_dissipation_w_m3 = powder};
  se.dissipation_w_m3[static_cast<std::size_t>(dem::ContactType::MediaMedia)] = collisions;
  se.dissipation_w_m3[static_cast<std::size_t>(dem::ContactType::WallMedia)] = 1.0;
  cell.standard_errors = se;
}

TEST(Upscale, StiffCellsGiveTheShiftOfCushioningAndPowderShareAtTheSameSites) {
  auto inputs = point_inputs();
  inputs.push_back(stiff_toe_cell());
  edit_cell(inputs, "toe-0", 1.0, [](method::CellResult& cell) { set_errors(cell, 10.0, 6.0); });
  edit_cell(inputs, "toe-0", 0.0, [](method::CellResult& cell) { set_errors(cell, 0.0, 9.0); });
  auto stiff = inputs.back().result.get<method::CellResult>();
  set_errors(stiff, 9.0, 11.0);
  inputs.back().result = stiff;
  json r = upscale(inputs, 1.0);
  ASSERT_TRUE(r.contains("stiffness_sensitivity"));
  const json s = r.at("stiffness_sensitivity");
  EXPECT_DOUBLE_EQ(s.at("factor"), 4.0);
  ASSERT_EQ(s.at("regions").size(), 1u) << "only the toe has a stiff cell";
  const json& toe = s.at("regions").at("toe");
  EXPECT_EQ(toe.at("sites"), 1);
  EXPECT_DOUBLE_EQ(toe.at("cushioning"), 300.0 / 600.0);
  EXPECT_DOUBLE_EQ(toe.at("cushioning_stiff"), 360.0 / 600.0);
  EXPECT_NEAR(toe.at("cushioning_shift").get<double>(), 0.2, 1e-12);
  // The baseline cancels: only the two loaded cells' errors (7 and 12 W/m^3) count.
  EXPECT_NEAR(toe.at("cushioning_shift_se").get<double>(),
              1.2 * std::hypot(7.0 / 300.0, 12.0 / 360.0), 1e-12);
  EXPECT_DOUBLE_EQ(toe.at("powder_share"), 0.4);
  EXPECT_DOUBLE_EQ(toe.at("powder_share_stiff"), 0.45);
  EXPECT_NEAR(toe.at("powder_share_shift").get<double>(), 0.125, 1e-12);
  const double share_rel = std::hypot(10.0 / 400.0, 20.0 / 1000.0);
  const double stiff_rel = std::hypot(9.0 / 450.0, 20.0 / 1000.0);
  EXPECT_NEAR(toe.at("powder_share_se").get<double>(), 0.4 * share_rel, 1e-12);
  EXPECT_NEAR(toe.at("powder_share_shift_se").get<double>(),
              1.125 * std::hypot(share_rel, stiff_rel), 1e-12);
  EXPECT_EQ(s.at("totals"), toe) << "the toe is the only region with a stiff cell";

  // The stiff cell counts in nothing else; the result reads back as written.
  EXPECT_EQ(json(method::read_upscale_result(r, "test")), r);
  r.erase("stiffness_sensitivity");
  auto without = inputs;
  without.pop_back();
  EXPECT_EQ(r, upscale(without, 1.0));
  EXPECT_FALSE(upscale(without, 1.0).contains("stiffness_sensitivity"));
}

TEST(Upscale, UnsteadyStiffCellsAreListedApart) {
  auto inputs = point_inputs();
  inputs.push_back(stiff_toe_cell());
  inputs.back().result["steady"] = false;
  const json r = upscale(inputs, 1.0);
  EXPECT_TRUE(r.at("left_out_cells").empty());
  const json& s = r.at("stiffness_sensitivity");
  ASSERT_EQ(s.at("left_out_cells").size(), 1u);
  EXPECT_EQ(s.at("left_out_cells").at(0).at("reason"), "not steady");
  EXPECT_EQ(s.at("totals").at("sites"), 0);
  EXPECT_TRUE(s.at("totals").at("cushioning_shift").is_null());
  EXPECT_NEAR(upscale(inputs, 1.0, true)
                  .at("stiffness_sensitivity")
                  .at("totals")
                  .at("cushioning_shift")
                  .get<double>(),
              0.2, 1e-12);
}

TEST(Upscale, SolidVolumeWeightsCountPowerPerVolumeOfMedia) {
  auto inputs = point_inputs();
  inputs.at(2).result["weight_by"] = "solid_volume";
  // Each site holds 0.6 of its volume in balls, each cell 0.5: weights 1.2 x the volumes.
  const json r = upscale(inputs, 1.0);
  EXPECT_NEAR(r.at("powder_power_w").get<double>(), 1.2 * 1.1, 1e-15);
  EXPECT_NEAR(r.at("cushioning").get<double>(), 1.2 / 2.25, 1e-15);
}

TEST(Upscale, MediaSpectrumShiftIsMeasuredAboveTheMediaOnlyMedian) {
  auto inputs = point_inputs();
  edit_cell(inputs, "toe-0", 0.0, [](method::CellResult& cell) {
    cell.media_spectrum.counts = {2, 20};
  });
  edit_cell(inputs, "bulk-0", 0.0, [](method::CellResult& cell) {
    cell.media_spectrum.counts = {0, 0};
  });
  const json shift = upscale(inputs, 1.0).at("media_spectrum_shift");
  // Without powder most media collisions lie in the upper bin (20 of 22); with powder 2 of 16
  // (toe 10, 0 and bulk 2, 2 at 10 and 15 per count).
  EXPECT_DOUBLE_EQ(shift.at("threshold_j"), 1e-5);
  EXPECT_DOUBLE_EQ(shift.at("fraction_above_no_powder"), 20.0 / 22.0);
  EXPECT_DOUBLE_EQ(shift.at("fraction_above"), 30.0 / (100.0 + 60.0));
}

TEST(Upscale, RefusesAPointWithoutItsMacroRun) {
  auto inputs = point_inputs();
  inputs.erase(inputs.begin());
  EXPECT_THROW(upscale(inputs, 1.0), std::invalid_argument);
}

}  // namespace
}  // namespace millflow::tasks
