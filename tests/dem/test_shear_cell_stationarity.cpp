// The shear cell's stationarity test (dem/stationarity.hpp) and wall-speed controller
// (dem/wall_speed_controller.hpp) on synthetic series: a stationary noisy cell passes, a drifting
// or compacting one fails, the controller settles on the wall speed a noisy or lagging bed asks
// for, and compaction ends on a state, not on one loaded interval.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "dem/rng.hpp"
#include "dem/stationarity.hpp"
#include "dem/stress_control.hpp"
#include "dem/wall_speed_controller.hpp"

namespace millflow::dem {
namespace {

constexpr double kTargetStress = 1000.0, kTargetRate = 5.0;

// A roughly normal deviate of unit variance (sum of 12 uniforms).
double noise(Rng& rng) {
  double sum = -6.0;
  for (int k = 0; k < 12; ++k) sum += rng.uniform();
  return sum;
}

// n windows of a cell with window means scattering by `scatter` (relative) around shear stress
// 500 Pa, the target normal stress, solid fraction 0.58 (+-0.005) and the target rate; each
// window k adds `drift` x k (relative) to the shear stress and `compaction` x k to the solid
// fraction.
std::vector<WindowMeans> windows(Rng& rng, int n, double scatter, double drift = 0.0,
                                 double compaction = 0.0) {
  std::vector<WindowMeans> out;
  for (int k = 0; k < n; ++k) {
    out.push_back({.shear_stress = 500.0 * (1.0 + drift * k + scatter * noise(rng)),
                   .normal_stress = kTargetStress * (1.0 + scatter * noise(rng)),
                   .solid_fraction = 0.58 + compaction * k + 0.005 * noise(rng),
                   .bulk_shear_rate = kTargetRate * (1.0 + scatter * noise(rng))});
  }
  return out;
}

double pass_fraction(double scatter, double drift, double compaction) {
  Rng rng(7);
  int passed = 0;
  constexpr int kCells = 400;
  for (int c = 0; c < kCells; ++c) {
    passed +=
        test_stationarity(windows(rng, 4, scatter, drift, compaction), kTargetStress, kTargetRate)
            .stationary();
  }
  return static_cast<double>(passed) / kCells;
}

TEST(ShearCellStationarity, AStationaryCellWhoseWindowsScatterByTenPercentPasses) {
  // The fixed 10% drift bound passed about a third of such cells; the test now passes most, and
  // the rest pass at a later window (each window is tested again).
  EXPECT_GT(pass_fraction(0.1, 0.0, 0.0), 0.7);
  EXPECT_GT(pass_fraction(0.02, 0.0, 0.0), 0.9);
}

TEST(ShearCellStationarity, ADriftingOrCompactingCellFails) {
  // Shear stress drifting by 15% a window, well above a 2% scatter.
  EXPECT_LT(pass_fraction(0.02, 0.15, 0.0), 0.05);
  // Solid fraction rising by 0.02 a window.
  EXPECT_LT(pass_fraction(0.02, 0.0, 0.02), 0.05);
}

TEST(ShearCellStationarity, TheNormalStressMustBeOnTargetAndCarriedInEveryWindow) {
  Rng rng(3);
  std::vector<WindowMeans> w = windows(rng, 4, 0.01);
  EXPECT_TRUE(test_stationarity(w, kTargetStress, kTargetRate).stationary());
  for (WindowMeans& m : w) m.normal_stress *= 1.3;
  StationarityVerdict verdict = test_stationarity(w, kTargetStress, kTargetRate);
  EXPECT_FALSE(verdict.normal_stress);
  EXPECT_TRUE(verdict.shear_stress && verdict.solid_fraction && verdict.bulk_shear_rate);
  // A first window while the bed still closes: its scatter would otherwise hide it.
  w = windows(rng, 4, 0.01);
  w[0].normal_stress = 0.3 * kTargetStress;
  w[1].normal_stress = 1.6 * kTargetStress;
  EXPECT_FALSE(test_stationarity(w, kTargetStress, kTargetRate).normal_stress);
  // Fewer than three windows are never stationary.
  EXPECT_FALSE(test_stationarity(std::span(w).first(2), kTargetStress, kTargetRate).stationary());
}

TEST(ShearCellStationarity, TheBulkRateCountsOnlyWithATarget) {
  Rng rng(5);
  std::vector<WindowMeans> w = windows(rng, 4, 0.01);
  for (WindowMeans& m : w) m.bulk_shear_rate *= 1.5;
  EXPECT_FALSE(test_stationarity(w, kTargetStress, kTargetRate).bulk_shear_rate);
  EXPECT_TRUE(test_stationarity(w, kTargetStress, 0.0).bulk_shear_rate);
}

TEST(CompactionEnd, ALoneSpikeDoesNotEndCompaction) {
  // One ball hitting the wall: one interval carries ten times the target, the next nothing.
  CompactionEnd end(kTargetStress);
  end.answer(0.0);
  end.answer(10.0 * kTargetStress);
  EXPECT_FALSE(end.compacted());
  EXPECT_FALSE(end.closing());  // the control answers a loaded interval by its own law
  end.answer(0.0);
  EXPECT_FALSE(end.compacted());
  EXPECT_TRUE(end.closing());  // and closes at the speed limit again once it is empty
  // Spikes every other interval never compact it.
  for (int interval = 0; interval < 20; ++interval) {
    end.answer(interval % 2 == 0 ? 10.0 * kTargetStress : 0.1 * kTargetStress);
    EXPECT_FALSE(end.compacted()) << "interval " << interval;
  }
}

TEST(CompactionEnd, ABedCarryingHalfItsTargetIntervalAfterIntervalHasCompacted) {
  CompactionEnd end(kTargetStress);
  for (int interval = 1; interval <= kCompactedIntervals; ++interval) {
    EXPECT_FALSE(end.compacted()) << "interval " << interval;
    end.answer((kClosingStressFraction + 0.01 * interval) * kTargetStress);
  }
  EXPECT_TRUE(end.compacted());
}

TEST(WallSpeedController, SettlesOnTheSpeedANoisyBedAsksFor) {
  // A bed whose bulk rate is 0.4 of the nominal one, each window's rate scattering by 25%:
  // the speed that gives the target is target x gap / 0.4.
  constexpr double kFraction = 0.4, kGap = 0.06;
  const double wanted = kTargetRate * kGap / kFraction;
  int within = 0, tries = 0, settled = 0;
  for (std::uint64_t seed = 1; seed <= 50; ++seed) {
    Rng rng(seed);
    WallSpeedController controller(kTargetRate);
    double speed = kTargetRate * kGap / 0.5;  // the cell's first guess
    for (int window = 0; window < 16; ++window) {
      const double rate = kFraction * speed / kGap * (1.0 + 0.25 * noise(rng));
      speed = controller.update(rate, speed, kGap);
      if (window >= 8) {
        ++tries;
        within += std::abs(speed / wanted - 1.0) <= 0.1;
        settled += controller.settled();
      }
    }
  }
  // Measured: 70% (the estimate rests on 3 windows, 14% apart at this scatter).
  EXPECT_GT(static_cast<double>(within) / tries, 0.6);
  EXPECT_GT(settled, 0);
}

TEST(WallSpeedController, SettlesOnABedThatLags) {
  // The bulk follows the wall speed with a lag of 3 windows (first order), as the rough-wall
  // cell's bulk does at I ~ 0.4 in a 13 d gap, its rate scattering by 5%; starting 40% below
  // the speed it asks for: after 40 windows the speed is within 10% of that speed, plus one
  // standard error of a 4-window estimate at this scatter (2.5%; with the first step limited to
  // kMaxFirstStep seeds 12 and 20 settle 10.2% and 11.4% off, every other within 10%), and the
  // controller has settled (in 18 of these 20 seeds).
  constexpr double kFraction = 0.4, kGap = 0.06, kLagWindows = 3.0;
  int settled = 0;
  const double wanted = kTargetRate * kGap / kFraction;
  const double decay = std::exp(-1.0 / kLagWindows);
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Rng rng(seed);
    WallSpeedController controller(kTargetRate);
    double speed = 0.6 * wanted, followed = speed, highest = speed;
    for (int window = 0; window < 40; ++window) {
      followed = speed + (followed - speed) * decay;
      const double rate = kFraction * followed / kGap * (1.0 + 0.05 * noise(rng));
      speed = controller.update(rate, speed, kGap);
      highest = std::max(highest, speed);
    }
    // The highest speed up to 71% above the wanted one: the secant through two steady points of
    // a bed that still lags sees it less sensitive than it is and extrapolates too far (the price
    // of learning the sensitivity; regula falsi brings it back). Not 2x: the step limits hold.
    EXPECT_NEAR(speed / wanted, 1.0, 0.1 + 0.025) << "seed " << seed;
    EXPECT_LE(highest, 1.8 * wanted) << "seed " << seed;
    settled += controller.settled();
  }
  EXPECT_GE(settled, 15);
}

// A bed whose steady bulk rate at wall speed U is target x `shape`(U / U0), each window's rate
// scattering by 5%, from the speed `start` x U0: over 54 windows (40 when an estimate rested on 3
// windows, now on kSteadyWindows = 4), how many of 20 seeds end
// settled with the true rate at their last speed within `tolerance` of the target.
template <typename Shape>
int seeds_settled_on_target(Shape shape, double start, double tolerance) {
  constexpr double kGap = 0.06, kWanted = 0.3;  // U0, m/s
  int good = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Rng rng(seed);
    WallSpeedController controller(kTargetRate);
    double speed = start * kWanted;
    for (int window = 0; window < 54; ++window) {
      const double rate = kTargetRate * shape(speed / kWanted) * (1.0 + 0.05 * noise(rng));
      speed = controller.update(rate, speed, kGap);
    }
    const double off = std::abs(shape(speed / kWanted) - 1.0);
    good += controller.settled() && off <= tolerance;
    // Every seed within the tolerance plus one standard error of a 4-window estimate at this
    // scatter (2.5%): a controller settles on its estimate, which can be that far from the truth
    // (seed 5 of the first shape settles 5.15% off).
    EXPECT_LE(off, tolerance + 0.025) << "seed " << seed << ": speed " << speed / kWanted << " U0";
  }
  return good;
}

TEST(WallSpeedController, SettlesOnABedWhoseRateHardlyAnswersTheSpeed) {
  // As the 8 x 10 x 8 cell measured: 0.9 + 0.1 U / U0, so from 1.9 U0 the bulk runs 9% fast and
  // the proportional law needs a dozen steps (1.9, 1.74, 1.62, ... U0); the secant through two
  // steady points finds U0.
  const int settled = seeds_settled_on_target([](double u) { return 0.9 + 0.1 * u; }, 1.9,
                                              WallSpeedController::kSettleTolerance);
  EXPECT_GE(settled, 18);
}

TEST(WallSpeedController, SettlesOnABedWhoseRateGrowsFasterThanTheSpeed) {
  // Rate ~ U^2: the proportional law jumps between U0 / u and u U0 for ever (from 0.6 U0: 1.2,
  // 0.83, 1.2, ...); regula falsi between the two sides settles.
  const int settled = seeds_settled_on_target([](double u) { return u * u; }, 0.6,
                                              WallSpeedController::kSettleTolerance);
  EXPECT_GE(settled, 18);
}

TEST(WallSpeedController, WaitsWhileTheBulkFractionDrifts) {
  // A bed still developing: its bulk fraction grows by 10% a window. No step on it.
  WallSpeedController controller(kTargetRate);
  constexpr double kGap = 0.06, kSpeed = 0.1;
  for (int window = 0; window < 10; ++window) {
    const double rate = 0.2 * std::pow(1.1, window) * kSpeed / kGap;
    EXPECT_DOUBLE_EQ(controller.update(rate, kSpeed, kGap), kSpeed) << "window " << window;
  }
  EXPECT_FALSE(controller.settled());
}

TEST(WallSpeedController, StepsUpWhenTheBedDoesNotFollowAndKeepsItsState) {
  WallSpeedController controller(kTargetRate);
  // Steady windows in which the bulk does not follow at all: the largest first step up, once the
  // estimate rests on enough windows.
  for (int window = 1; window < WallSpeedController::kSteadyWindows; ++window)
    EXPECT_DOUBLE_EQ(controller.update(0.0, 0.1, 0.06), 0.1);
  EXPECT_DOUBLE_EQ(controller.update(0.0, 0.1, 0.06), 0.1 * WallSpeedController::kMaxFirstStep);
  EXPECT_FALSE(controller.settled());
  // Later steps go as far as kMaxStep.
  for (int window = 1; window < WallSpeedController::kSteadyWindows; ++window)
    EXPECT_DOUBLE_EQ(controller.update(0.0, 0.125, 0.06), 0.125);
  EXPECT_DOUBLE_EQ(controller.update(0.0, 0.125, 0.06), 0.125 * WallSpeedController::kMaxStep);
  controller.update(1.0, 0.25, 0.06);
  BinaryWriter out;
  controller.write(out);
  WallSpeedController copy(kTargetRate);
  BinaryReader in(out.bytes());
  copy.read(in);
  for (int window = 0; window < WallSpeedController::kSteadyWindows; ++window)
    EXPECT_DOUBLE_EQ(copy.update(1.1, 0.25, 0.06), controller.update(1.1, 0.25, 0.06));
  EXPECT_EQ(copy.settled(), controller.settled());
  EXPECT_DOUBLE_EQ(copy.bulk_fraction(), controller.bulk_fraction());
}

}  // namespace
}  // namespace millflow::dem
