// The Lees-Edwards barostat holds the MEAN normal stress at its target, in a collisional cell
// (I = 0.5, where single collisions of stiff balls carry an intermittent stress) as in a dense
// one (I = 0.01), at realistic stiffness (docs/shear_cells.md, "Stress control"). A 5 d cell's
// p_yy over 10 strains scatters by ~10% (its batch-means standard error), so the collisional
// test averages 8 seeds (~4%). A clamped proportional law alone held that mean at 1.11 of the
// target: it answers something nearer the median than the mean of an intermittent stress.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>

#include "dem/shear_cell.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

ShearCellMeasurements lees_edwards_cell(double inertial_number, double kappa, std::uint64_t seed,
                                        double warmup, double max_warmup, double measure) {
  spdlog::set_level(std::getenv("MF_DEBUG") ? spdlog::level::debug : spdlog::level::warn);
  ShearCellSetup setup = testing::small_shear_cell(inertial_number);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.size_diameters = Vec3(5, 5, 5);
  setup.seed = seed;
  setup.media_media.normal_stiffness = kappa * setup.normal_stress * setup.media_diameter;
  ShearCellRun run(setup, {.warmup_strain = warmup,
                           .warmup_windows = 4,
                           .max_warmup_strain = max_warmup,
                           .measure_strain = measure,
                           .measure = {.samples = 50}});
  run.advance(~std::uint64_t{0});
  const ShearCellMeasurements& m = run.measurements();
  std::printf("I = %g, k_n/(p d) = %g, seed %llu: p_yy %.4g +- %.3g Pa (target %.4g)\n",
              inertial_number, kappa, static_cast<unsigned long long>(seed), m.normal_stress,
              m.normal_stress_error.standard_error, setup.normal_stress);
  return m;
}

TEST(BarostatMeanStress, CollisionalCellHoldsTheMeanNormalStress) {
  // At least 8 strains of warm-up: the stationarity test passes most of these cells from the
  // fourth of 1-strain windows on, and measured from there the mean of the 8 seeds was 1054 Pa
  // (the barostat's integral term still settling); from 8 strains on it is 998 Pa. 16 seeds: one
  // seed's p_yy scatters by about 110 Pa, so 8 seeds' mean by 39 Pa, and the 5% bound was 1.3 of
  // its standard errors (with the sliding spring reset of 5 December 2026 seeds 1-8 gave 1060 Pa,
  // seeds 9-16 945 Pa); the mean of 16, 1002 Pa, has one of about 27 Pa.
  constexpr int kSeeds = 16;
  double sum = 0.0;
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed)
    sum += lees_edwards_cell(0.5, 1e5, seed, 8.0, 12.0, 10.0).normal_stress;
  EXPECT_NEAR(sum / kSeeds, 1000.0, 50.0);
}

TEST(BarostatMeanStress, DenseCellHoldsTheMeanNormalStress) {
  // (Its window means scatter too much for the stationarity test within a short warm-up.) One
  // seed's 2-strain mean has a standard error of 4-7%, so one seed alone would pass or fail by its
  // trajectory's last bits: seed 1 gave 977 and 1058 Pa from two contact laws that differ in the
  // last place of the spring's rescale. The mean of 4 seeds has a standard error of about 2.5%:
  // 1008 Pa (997 before that change).
  constexpr int kSeeds = 4;
  double sum = 0.0;
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed)
    sum += lees_edwards_cell(0.01, 1e4, seed, 1.0, 1.0, 2.0).normal_stress;
  EXPECT_NEAR(sum / kSeeds, 1000.0, 50.0);
}

}  // namespace
}  // namespace millflow::dem
