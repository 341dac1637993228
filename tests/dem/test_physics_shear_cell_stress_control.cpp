// The stress control of both boundaries at realistic stiffness: the rough walls' servo and the
// Lees-Edwards barostat hold the target normal stress within 5% at k_n / (p d) = 1e4 (the walls
// also at 1e2 and 1e5: 984 and 985 Pa against 1000, docs/shear_cells.md).
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>

#include "dem/shear_cell.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

ShearCellMeasurements run_at_stiffness(ShearCellSetup::Boundary boundary, double kappa) {
  spdlog::set_level(std::getenv("MF_DEBUG") ? spdlog::level::debug : spdlog::level::warn);
  ShearCellSetup setup = testing::small_shear_cell(0.1);
  setup.boundary = boundary;
  setup.size_diameters = Vec3(6, 6, 6);
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

TEST(ShearCellStressControl, WallServoHoldsTheNormalStressAtRealisticStiffness) {
  const ShearCellMeasurements m = run_at_stiffness(ShearCellSetup::Boundary::RoughWalls, 1e4);
  EXPECT_NEAR(m.normal_stress, 1000.0, 50.0);
  // Not asserted: stationarity and the bulk rate. With the filtered wall-speed controller
  // (dem/wall_speed_controller.hpp) the measured bulk rate of seeds 1, 2, 3 of this cell was 3%
  // low, 0.4% high and 12% low (normal stress 970, 995, 990 Pa; seeds 2 and 3 stationary at
  // strain 5.5): one window's bulk rate still scatters by 20-30% here, so 10% does not hold for
  // every seed (docs/shear_cells.md, "Not yet done").
  EXPECT_GT(m.wall_slip, 0.0) << "rough walls slip";
  EXPECT_NEAR(m.wall_slip, 0.5 * (m.wall_speed - m.bulk_shear_rate * m.gap), 1e-12);
}

TEST(ShearCellStressControl, BarostatHoldsTheNormalStressAtRealisticStiffness) {
  const ShearCellMeasurements m = run_at_stiffness(ShearCellSetup::Boundary::LeesEdwards, 1e4);
  EXPECT_NEAR(m.normal_stress, 1000.0, 50.0);
  EXPECT_TRUE(m.stationary);
}

}  // namespace
}  // namespace millflow::dem
