// The stiffness policy's arithmetic (dem/stiffness_policy.hpp) on the cement campaign's cell:
// 50 mm steel balls (7800 kg/m^3), clinker powder of 0.125 d (3150 kg/m^3), 20 kPa, bounds mean
// 1% and p95 3% of the smaller diameter. The overlaps it buys are measured by
// test_physics_shear_cell_policy.cpp and docs/cell_validation.md, table 5.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "dem/stiffness_policy.hpp"

namespace millflow::dem {
namespace {

constexpr double kMediaDiameter = 0.05, kPowderDiameter = 0.125 * kMediaDiameter;
// m = rho pi d^3 / 6 of one ball and of one grain.
const double kMediaMass = 7800.0 * std::numbers::pi / 6.0 * 1.25e-4;
const double kPowderMass = 3150.0 * std::numbers::pi / 6.0 * 2.44140625e-7;

ShearCellSetup cement_cell(double shear_rate) {
  ShearCellSetup s;
  s.media_diameter = kMediaDiameter;
  s.media = {"steel", 7800.0};
  s.powder = {"clinker", 3150.0};
  s.powder_diameter_ratio = 0.125;
  s.normal_stress = 2e4;
  s.shear_rate = shear_rate;
  s.media_media.normal_stiffness = 1.156e7;  // the campaign's collision time of 5e-4 s
  s.media_powder.normal_stiffness = 1.139e5;
  s.powder_powder.normal_stiffness = 6.272e4;
  return s;
}

TEST(StiffnessPolicy, StaticBoundCarriesABallScaleForceAtTheMeanOverlap) {
  ShearCellSetup s = cement_cell(10.0);
  const auto derived = apply_overlap_bound(s);
  ASSERT_EQ(derived.size(), 3u);
  // 2 x 2e4 Pa x (0.05 m)^2 / (0.01 x d_s)
  EXPECT_NEAR(derived[0].static_bound, 100.0 / (0.01 * kMediaDiameter), 1e-6);
  EXPECT_NEAR(derived[1].static_bound, 100.0 / (0.01 * kPowderDiameter), 1e-6);
  EXPECT_NEAR(derived[2].static_bound, 1.6e6, 1e-6);
  EXPECT_DOUBLE_EQ(derived[1].smaller_diameter, kPowderDiameter);
}

TEST(StiffnessPolicy, ImpactBoundStopsTwoCollidingBallsAtTheTailOverlap) {
  ShearCellSetup s = cement_cell(10.0);
  const auto derived = apply_overlap_bound(s);
  const double speed = kImpactSpeedFactor * 10.0 * kMediaDiameter;  // 2.5 gdot d_m = 1.25 m/s
  const double ball_pair_mass = 0.5 * kMediaMass;
  // A ball-ball contact: v sqrt(m_mm / k) = 0.03 d_m.
  EXPECT_NEAR(derived[0].impact_bound,
              ball_pair_mass * std::pow(speed / (0.03 * kMediaDiameter), 2), 1e-6);
  // A grain between two balls: two contacts in series, each v sqrt(m_mm / (2 k)) = 0.03 d_s;
  // the grain's own mass does not enter.
  EXPECT_NEAR(derived[1].impact_bound,
              0.5 * ball_pair_mass * std::pow(speed / (0.03 * kPowderDiameter), 2), 1e-3);
  EXPECT_NEAR(derived[1].impact_bound, 5.672e6, 1e3);
  // Two grains: their own pair mass.
  EXPECT_NEAR(derived[2].impact_bound,
              0.5 * kPowderMass * std::pow(speed / (0.03 * kPowderDiameter), 2), 1e-6);
}

TEST(StiffnessPolicy, TakesTheLargestCriterionAndSaysWhichGoverns) {
  ShearCellSetup s = cement_cell(10.0);  // I = 0.31: the ball-powder impact governs
  const auto derived = apply_overlap_bound(s);
  EXPECT_EQ(derived[0].governing, "given");
  EXPECT_EQ(derived[1].governing, "impact");
  EXPECT_EQ(derived[2].governing, "static");
  EXPECT_DOUBLE_EQ(s.media_media.normal_stiffness, 1.156e7);
  EXPECT_DOUBLE_EQ(s.media_powder.normal_stiffness, derived[1].impact_bound);
  EXPECT_DOUBLE_EQ(s.powder_powder.normal_stiffness, derived[2].static_bound);
  EXPECT_DOUBLE_EQ(derived[1].kappa, derived[1].chosen / (2e4 * kPowderDiameter));

  // A third of the rate (I = 0.1): the impact bound falls by 9, below the static one.
  ShearCellSetup slow = cement_cell(10.0 / 3.0);
  const auto slower = apply_overlap_bound(slow);
  EXPECT_NEAR(slower[1].impact_bound, derived[1].impact_bound / 9.0, 1e-3);
  EXPECT_EQ(slower[1].governing, "static");
  EXPECT_DOUBLE_EQ(slow.media_powder.normal_stiffness, 1.6e6);
}

TEST(StiffnessPolicy, RigidityBoundRaisesOnlyTheBallsToTheirKappa) {
  ShearCellSetup s = cement_cell(10.0);
  const auto without = apply_overlap_bound(s);
  EXPECT_EQ(without[0].rigidity_bound, 0.0);  // off by default
  EXPECT_EQ(without[0].governing, "given");

  ShearCellSetup rigid = cement_cell(10.0);
  rigid.overlap_bound.media_rigidity = 5e4;
  const auto derived = apply_overlap_bound(rigid);
  // 5e4 x 2e4 Pa x 0.05 m = 5e7 N/m, above the given 1.156e7 and both overlap bounds.
  EXPECT_NEAR(derived[0].rigidity_bound, 5e7, 1e-6);
  EXPECT_EQ(derived[0].governing, "rigidity");
  EXPECT_DOUBLE_EQ(rigid.media_media.normal_stiffness, 5e7);
  EXPECT_DOUBLE_EQ(derived[0].kappa, 5e4);
  // The pairs with powder are what they were.
  for (std::size_t k : {1u, 2u}) {
    EXPECT_EQ(derived[k].rigidity_bound, 0.0);
    EXPECT_EQ(derived[k].chosen, without[k].chosen);
    EXPECT_EQ(derived[k].governing, without[k].governing);
  }
  // A floor only: a stiffer given pair keeps its k_n.
  ShearCellSetup stiff = rigid;
  stiff.media_media.normal_stiffness = 1e8;
  EXPECT_EQ(apply_overlap_bound(stiff)[0].governing, "given");
  EXPECT_DOUBLE_EQ(stiff.media_media.normal_stiffness, 1e8);
}

TEST(StiffnessPolicy, NeverSoftensAPairAndDescribingChangesNothing) {
  ShearCellSetup s = cement_cell(10.0);
  s.powder_powder.normal_stiffness = 1e8;
  const ShearCellSetup before = s;
  const auto described = describe_stiffness(s);
  EXPECT_EQ(s.media_powder.normal_stiffness, before.media_powder.normal_stiffness);
  for (const PairStiffness& p : described) {
    EXPECT_EQ(p.chosen, p.given) << p.pair;
    EXPECT_EQ(p.governing, "given") << p.pair;
  }
  const auto applied = apply_overlap_bound(s);
  EXPECT_EQ(applied[2].governing, "given");
  EXPECT_DOUBLE_EQ(s.powder_powder.normal_stiffness, 1e8);
}

}  // namespace
}  // namespace millflow::dem
