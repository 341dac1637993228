// The upscale kind: site-weighted sums of hand-made shear cells checked against the formulas of
// tasks/upscale.hpp worked out by hand.
#include <gtest/gtest.h>

#include "tasks/upscale.hpp"
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
  // The macro draw scaled by the cells' power input with / without powder: 3.5 W / 2.8 W.
  EXPECT_DOUBLE_EQ(r.at("power_draw_with_powder_w"), 1000.0 * 3.5 / 2.8);
  EXPECT_EQ(r.at("dominant_region"), "toe");
  EXPECT_EQ(r.at("average_task"), "average-key");
  EXPECT_DOUBLE_EQ(r.at("mill").at("diameter_m"), 1.0);

  ASSERT_EQ(r.at("regions").size(), 2u);  // region_names() order: toe before bulk
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

TEST(Upscale, CouplingComparesTheMediaOnlyCellWithTheMacroShearStress) {
  const json r = upscale(point_inputs(), 1.0);
  const json& sites = r.at("sites");
  ASSERT_EQ(sites.size(), 3u);
  EXPECT_DOUBLE_EQ(sites.at(0).at("coupling_ratio"), 880.0 / 800.0);
  EXPECT_DOUBLE_EQ(sites.at(1).at("coupling_ratio"), 450.0 / 500.0);
  EXPECT_TRUE(sites.at(2).at("coupling_ratio").is_null());
  EXPECT_EQ(sites.at(2).at("skipped"), "no shear cell ran at this site");
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
}

TEST(Upscale, RefusesAPointWithoutItsMacroRun) {
  auto inputs = point_inputs();
  inputs.erase(inputs.begin());
  EXPECT_THROW(upscale(inputs, 1.0), std::invalid_argument);
}

}  // namespace
}  // namespace millflow::tasks
