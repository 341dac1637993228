// The close-packed initial placement of a mill charge: its bulk density is the analytic one of
// close packing, no two sites come closer than the spacing (also across the periodic boundary, for
// even and odd layer counts), and it holds the charge of J = 0.5 in the small test mills.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "dem/mill_setup.hpp"
#include "dem/packing.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

MillShell plain_shell(double radius, double length, bool end_walls) {
  return MillShell{
      .radius = radius, .length = length, .lifter_count = 0, .lifter = {}, .end_walls = end_walls};
}

// The smallest distance between two sites, the z distance taken across the periodic boundary.
double closest_pair(const std::vector<Vec3>& sites, double periodic_length) {
  double closest = std::numeric_limits<double>::infinity();
  for (std::size_t a = 0; a < sites.size(); ++a) {
    for (std::size_t b = a + 1; b < sites.size(); ++b) {
      Vec3 d = sites[a] - sites[b];
      if (periodic_length > 0.0) d.z() -= periodic_length * std::round(d.z() / periodic_length);
      closest = std::min(closest, d.norm());
    }
  }
  return closest;
}

TEST(Packing, BulkDensityIsThatOfClosePacking) {
  // Ten layers exactly sqrt(2/3) spacings apart: the bulk holds sqrt(2) / spacing^3 sites per m^3.
  const double spacing = 0.044, length = 10 * spacing * std::sqrt(2.0 / 3.0);
  Rng rng(3);
  const auto sites = mill_lattice_sites(plain_shell(1.0, length, false), 0.0, 0.02, spacing,
                                        Vec3(0, -1, 0), 0.0, rng);
  const double inner = 0.5;
  std::size_t count = 0;
  for (const Vec3& s : sites) count += std::hypot(s.x(), s.y()) < inner ? 1 : 0;
  const double expected =
      std::sqrt(2.0) / std::pow(spacing, 3) * std::numbers::pi * inner * inner * length;
  EXPECT_NEAR(static_cast<double>(count), expected, 0.01 * expected);
  // Solid fraction 0.74 (d / spacing)^3 = 0.556 at the mills' spacing of 1.1 d, against 0.39 for
  // the cubic lattice it replaces.
  EXPECT_NEAR(expected * 4.0 / 3.0 * std::numbers::pi * std::pow(0.02, 3) /
                  (std::numbers::pi * inner * inner * length),
              std::numbers::pi / std::sqrt(18.0) / std::pow(1.1, 3), 1e-12);
}

TEST(Packing, SitesKeepTheSpacingAcrossThePeriodicBoundary) {
  const double radius = 0.005, spacing = 0.011;
  // 1, 2, 3 (A B C) and 4 layers across a periodic boundary, and a slice between end walls.
  for (const double length : {0.0115, 0.02, 0.03, 0.04}) {
    for (const bool end_walls : {false, true}) {
      const MillShell shell = plain_shell(0.05, length, end_walls);
      Rng rng(5);
      const auto lattice =
          mill_lattice_sites(shell, 0.0, radius, spacing, Vec3(0, -1, 0), 0.0, rng);
      ASSERT_GT(lattice.size(), 20u) << length;
      EXPECT_GE(closest_pair(lattice, end_walls ? 0.0 : length), spacing * (1 - 1e-12))
          << length << " " << end_walls;
      const auto jittered =
          mill_lattice_sites(shell, 0.0, radius, spacing, Vec3(0, -1, 0), 1.0, rng);
      EXPECT_GE(closest_pair(jittered, end_walls ? 0.0 : length), 2 * radius * (1 - 1e-12))
          << length;
      for (const Vec3& s : jittered) EXPECT_TRUE(sphere_clear_of_mill(shell, 0.0, s, radius));
      for (std::size_t k = 1; k < jittered.size(); ++k)
        EXPECT_LE(jittered[k - 1].y(), jittered[k].y() + spacing);
    }
  }
  Rng rng(1);
  EXPECT_THROW(mill_lattice_sites(plain_shell(0.05, 0.01, false), 0.0, radius, spacing,
                                  Vec3(0, -1, 0), 0.0, rng),
               std::invalid_argument);
}

TEST(Packing, SmallMillsHoldHalfFullCharges) {
  // The tests' 0.2 m mill with 10 mm balls and the macro tests' one with 12 mm balls in a slice
  // three balls long: the cubic lattice held J <= 0.4 in the latter.
  MillSetup ten = testing::small_mill(0.5, 0.75);
  MillSetup twelve = ten;
  twelve.ball_diameter = 0.012;
  twelve.shell.length = 0.036;
  for (MillSetup setup : {ten, twelve}) {
    for (const double fill : {0.5, 0.55}) {
      setup.fill = fill;
      const System system = build_mill(setup);
      EXPECT_EQ(system.size(), balls_per_class(setup)[0]);
      EXPECT_NO_THROW(system.check_overlaps(0.0));
    }
  }
}

}  // namespace
}  // namespace millflow::dem
