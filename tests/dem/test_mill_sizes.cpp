// Ball charges of several sizes: counts per class from the mass fractions, and a mixed bed
// without overlaps.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>

#include "dem/mill_setup.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

MillSetup two_size_mill() {
  MillSetup setup = testing::small_mill(0.3, 0.75);
  setup.size_distribution = {{.diameter = 0.012, .mass_fraction = 2.0},
                             {.diameter = 0.008, .mass_fraction = 1.0}};
  return setup;
}

TEST(MillSizes, MassFractionsAreNormalisedAndGiveTheMeanDiameter) {
  const auto classes = ball_size_classes(two_size_mill());
  ASSERT_EQ(classes.size(), 2u);
  EXPECT_DOUBLE_EQ(classes[0].mass_fraction, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(classes[1].mass_fraction, 1.0 / 3.0);
  EXPECT_NEAR(mean_ball_diameter(two_size_mill()), 2.0 / 3.0 * 0.012 + 1.0 / 3.0 * 0.008, 1e-15);
  EXPECT_EQ(mean_ball_diameter(testing::small_mill(0.3, 0.75)), 0.01);  // one size: ball_diameter
}

TEST(MillSizes, EachClassTakesItsMassFractionOfTheCharge) {
  const MillSetup setup = two_size_mill();
  System system = build_mill(setup);
  std::map<double, double> mass_by_radius;
  double total = 0.0;
  for (std::size_t p = 0; p < system.size(); ++p) {
    mass_by_radius[system.radii()[p]] += system.masses()[p];
    total += system.masses()[p];
  }
  ASSERT_EQ(mass_by_radius.size(), 2u);
  EXPECT_NEAR(mass_by_radius[0.006] / total, 2.0 / 3.0, 0.02);
  EXPECT_NEAR(mass_by_radius[0.004] / total, 1.0 / 3.0, 0.02);
  // The bed's solid volume: J x free volume x packing.
  const double solid = total / setup.media.density;
  const double expected =
      setup.fill * mill_free_cross_section_area(setup.shell) * setup.shell.length * setup.packing;
  EXPECT_NEAR(solid, expected, 0.02 * expected);
  EXPECT_NO_THROW(system.check_overlaps(0.0));
  // Mixed: the small balls are spread over the bed's height, not all on top.
  double small_y = 0.0, large_y = 0.0;
  int small = 0, large = 0;
  for (std::size_t p = 0; p < system.size(); ++p) {
    (system.radii()[p] < 0.005 ? small_y : large_y) += system.positions()[p].y();
    ++(system.radii()[p] < 0.005 ? small : large);
  }
  EXPECT_NEAR(small_y / small, large_y / large, 0.01);
}

TEST(MillSizes, BadClassesAreRefusedByName) {
  MillSetup setup = two_size_mill();
  setup.size_distribution[1].mass_fraction = 0.0;
  EXPECT_THROW(validate(setup), std::invalid_argument);
  setup = two_size_mill();
  setup.size_distribution[0].diameter = 0.06;  // more than a quarter of D = 0.2 m
  try {
    validate(setup);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ball size class 0"), std::string::npos) << e.what();
  }
}

TEST(MillSizes, SameMaterialForMediaAndLinerGetsALinerName) {
  MillSetup setup = two_size_mill();
  setup.liner = setup.media;
  const System system = build_mill(setup);
  EXPECT_EQ(system.materials().material(system.wall(0).material).name, "steel_liner");
}

}  // namespace
}  // namespace millflow::dem
