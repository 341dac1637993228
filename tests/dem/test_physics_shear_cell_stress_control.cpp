// The stress control of both boundaries at realistic stiffness: the rough walls' servo and the
// Lees-Edwards barostat hold the target normal stress within 5% at k_n / (p d) = 1e4 (the walls
// also at 1e2 and 1e5, with their bulk rate and slip), and the walls drive the bulk to the site's
// rate within 5% at 1e4 (docs/shear_cells.md).
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
// (the middle half of the gap), with a measured slip. In this 6 x 6 x 6 cell at I = 0.1 the bulk
// rate is not controlled to better than its order: with the measured window's catch-up law
// seeds 1, 2, 3 gave +4.4%, +3.4%, +5.9% (1e4), -4.0%, +26.1%, +14.6% (1e2) and -2.1%, +2.4%,
// -0.6% (1e5); without it -5.8%, +2.7%, +18.6%, -7.4%, +25.6%, +16.2% and -3.4%, -6.7%, +16.1%;
// with the flatter walls before -13.1% to +31.8%. With the servo's integral term (seed 1): normal
// stress 995, 1005, 1020 Pa and bulk rate -17.5%, +1.4%, +3.6% at 1e2, 1e4, 1e5. At I = 0.1 the
// rate answers the friction 14 times over (mu(I) = 0.368 + 0.69 I) and a 6 d gap's friction
// scatters by a few percent, so only the order is asserted here; the rate within a tolerance is
// asserted in the larger cell below (docs/shear_cells.md, "Wall speed"), and so is the sign of
// the slip: in this cell the bulk's rate scatters about the walls' own, and the tangential spring
// that follows the step's displacement (6 December 2026) left seed 1's slip below zero at 1e2
// (-0.005 m/s of a wall speed of 0.25 m/s) and, with another rounding of the contact velocity,
// at 1e4 (its bulk 15% above the target).
void expect_walls_hold_their_targets(double kappa) {
  const ShearCellMeasurements m = run_at_stiffness(ShearCellSetup::Boundary::RoughWalls, kappa);
  EXPECT_NEAR(m.normal_stress, 1000.0, 50.0);
  EXPECT_NEAR(m.bulk_shear_rate / m.target_shear_rate, 1.0, 0.5);
  EXPECT_NEAR(m.wall_slip, 0.5 * (m.wall_speed - m.bulk_shear_rate * m.gap), 1e-12);
}

TEST(ShearCellStressControl, WallServoHoldsTheNormalStressAtRealisticStiffness) {
  expect_walls_hold_their_targets(1e4);
}

TEST(ShearCellStressControl, WallServoHoldsTheNormalStressOfSoftAndStiffBalls) {
  expect_walls_hold_their_targets(1e2);
  expect_walls_hold_their_targets(1e5);
}

// A whole rough-wall cell run with the walls' protocol (dem::kRoughWallStrains).
ShearCellMeasurements run_with_the_rough_walls_protocol(const ShearCellSetup& setup) {
  const RoughWallStrains& strains = kRoughWallStrains;
  ShearCellRun run(setup, {.warmup_strain = strains.warmup_strain,
                           .warmup_windows = strains.warmup_windows,
                           .max_warmup_strain = strains.max_warmup_strain,
                           .measure_strain = strains.measure_strain,
                           .measure = {.samples = 100}});
  run.advance(~std::uint64_t{0});
  return run.measurements();
}

// The walls drive the bulk to the site's rate at k_n / (p d) = 1e4, in a cell of the campaign's
// table-4 size (8 x 10 x 8 d) at I = 0.3, with the rough walls' protocol (dem::kRoughWallStrains:
// warm-up in windows of 1 strain to a cap of 16, 8 strains measured with the catch-up law of
// dem/wall_speed_controller.hpp), and the cell stationary. Measured, seeds 1-6, with the
// controller settling within the stationarity test's 10%: +1.5%, -2.0%, +3.1%, -1.0%, -2.6%,
// -2.0%, every one stationary; settling within 5%: +2.5%, -2.0%, -3.8%, -1.0%, -5.0%, -2.0% (normal
// stress 996-1003 Pa; with T_i = 2 tau -5.2%, -2.1%, +4.8%, -0.6%, -0.4%, -2.7%); before it (the
// proportional servo) +3.2%, +0.5%, +1.1%, -1.3%, +0.2%, +1.5% (normal stress 1006-1014 Pa, energy
// balance within 0.7%); the same protocol without the catch-up law +6.5%, +0.4%, +15.0%, +1.2%,
// -2.5%, -2.0%; the code before (warm-up in windows of 0.5 strain to 12, 4 measured, no catch-up)
// +11.6%, +2.3%, +13.6%. So the 5% of issue 12 (docs/cell_validation.md, table 4 a seventh and a
// ninth time). The energy balance is the dashpots' second-order over-count (ShearCellPhysics):
// 1.3%, 0.34%, 0.11% at 20, 40, 80 steps per collision (0.18% at 20 while the tangential spring's
// first-order error, of the other sign, cancelled part of it, until 6 December 2026). About 7
// CPU s.
TEST(ShearCellStressControl, WallsDriveTheBulkToTheSiteRateAtRealisticStiffness) {
  spdlog::set_level(std::getenv("MF_DEBUG") ? spdlog::level::debug : spdlog::level::warn);
  ShearCellSetup setup = testing::small_shear_cell(0.3);
  setup.size_diameters = Vec3(8, 10, 8);
  setup.media_media.normal_stiffness = 1e4 * setup.normal_stress * setup.media_diameter;
  const ShearCellMeasurements m = run_with_the_rough_walls_protocol(setup);
  std::printf(
      "walls 8 x 10 x 8 at I 0.3, k_n/(p d) 1e4: normal stress %.4g Pa, stationary %d at strain "
      "%.3g, bulk rate %.4g (target %.4g, %+.1f%%), slip %.3g m/s of wall speed %.3g m/s, energy "
      "balance %.2g\n",
      m.normal_stress, m.stationary, m.stationary_strain, m.bulk_shear_rate, m.target_shear_rate,
      100.0 * (m.bulk_shear_rate / m.target_shear_rate - 1.0), m.wall_slip, m.wall_speed,
      m.energy_balance_error);
  EXPECT_NEAR(m.normal_stress, 1000.0, 50.0);
  EXPECT_NEAR(m.bulk_shear_rate / m.target_shear_rate, 1.0, 0.05);
  EXPECT_TRUE(m.stationary);
  EXPECT_GT(m.wall_slip, 0.0) << "rough walls slip";
  EXPECT_LT(m.energy_balance_error, 0.02);
}

// The walls hold the MEAN normal stress within 5% in a tall narrow cell (5 x 10 x 5 d) of the
// campaign's steel (restitution 0.3, friction 0.75) at k_n / (p d) = 1e4, I = 0.3, with the rough
// walls' protocol. With the proportional law alone the mean wall load sat 10-14% above the
// target there (the campaign's cell in table 4: 1.122 and 1.096, seeds 1 and 2; this cell 1.128
// on the code before, 1.121 and 1.140 with the integral term switched off; with restitution 0.5
// and friction 0.5 only 1.037 and 1.046). The integral term (dem::IntegralTerm) settles only
// when the mean load is on target: 0.991 and 1.010 (seeds 1, 2; with T_i = 2 tau, the
// barostat's, 1.011 and 0.994; docs/shear_cells.md, "Stress control"). About 2.5 CPU s. (Its energy
// balance is open by 1.2-2.2% with or without the integral term, not asserted here.)
TEST(ShearCellStressControl, WallServoHoldsTheMeanNormalStressOfATallNarrowCell) {
  spdlog::set_level(std::getenv("MF_DEBUG") ? spdlog::level::debug : spdlog::level::warn);
  ShearCellSetup setup = testing::small_shear_cell(0.3);
  setup.size_diameters = Vec3(5, 10, 5);
  setup.media_media.normal_stiffness = 1e4 * setup.normal_stress * setup.media_diameter;
  setup.media_media.restitution = 0.3;
  setup.media_media.friction = 0.75;
  const ShearCellMeasurements m = run_with_the_rough_walls_protocol(setup);
  std::printf(
      "walls 5 x 10 x 5 at I 0.3, k_n/(p d) 1e4: normal stress %.4g Pa (%.4f of the target), "
      "stationary %d, bulk rate %+.1f%%, energy balance %.2g\n",
      m.normal_stress, m.normal_stress / setup.normal_stress, m.stationary,
      100.0 * (m.bulk_shear_rate / m.target_shear_rate - 1.0), m.energy_balance_error);
  EXPECT_NEAR(m.normal_stress / setup.normal_stress, 1.0, 0.05);
}

// The measured window's catch-up law on a synthetic bed that follows the walls at once with a
// bulk fraction of 0.6, the walls starting at the speed a fraction of 0.72 would want (the rate
// 17% low): over 8 strains in stretches of 0.5 the window's mean rate ends within 2% of the
// target (-0.6%; at the starting speed it would stay 17% low), and the walls' mean speed is what
// they travelled.
TEST(ShearCellStressControl, TheMeasuredWindowsCatchUpBringsItsMeanRateToTheTarget) {
  const double target = 10.0, gap = 0.5, fraction = 0.6;
  WallSpeedController controller(target);
  controller.start_measured_window();
  const double stretch = WallSpeedController::kMeasuredControlStrain / target;  // s
  double speed = target * gap / 0.72, time = 0.0, bulk_strain = 0.0, travel = 0.0;
  for (int k = 0; k < 16; ++k) {
    bulk_strain += fraction * speed / gap * stretch;
    travel += speed * stretch;
    time += stretch;
    if (k < 15) speed = controller.update_measured(bulk_strain / time, time, speed, gap);
  }
  EXPECT_NEAR(bulk_strain / time / target, 1.0, 0.02);
  EXPECT_NEAR(controller.measured_mean_speed(time, speed), travel / time, 1e-12);
}

TEST(ShearCellStressControl, BarostatHoldsTheNormalStressAtRealisticStiffness) {
  const ShearCellMeasurements m = run_at_stiffness(ShearCellSetup::Boundary::LeesEdwards, 1e4);
  EXPECT_NEAR(m.normal_stress, 1000.0, 50.0);
  EXPECT_TRUE(m.stationary);
}

}  // namespace
}  // namespace millflow::dem
