#pragma once
// The rough-wall cell's wall-speed controller (docs/shear_cells.md, "Stress control"): rough
// walls slip, so the wall speed U that gives the site's bulk shear rate is found between warm-up
// windows. Each window measures the bulk rate g_i at its wall speed U and gap H_i, so its bulk
// fraction f_i = g_i H_i / U (bulk over nominal rate).
//
// The bulk follows a change of U only slowly: the change diffuses in from the walls through a
// bed whose shear stress hardly depends on its rate (mu(I)), over several strains at I ~ 0.4
// in a 13 d gap (measured: at a fixed U the bulk fraction rose from 0.33 to 0.53 over 6
// strains after a step, docs/cell_validation.md, table 4). A controller that steps every window
// on a fraction measured before the bulk has followed sees it too low and overshoots (it left
// the bulk rate 12-36% high). So the controller steps only on a steady bulk fraction:
//  - the windows at the current speed are kept; while their f_i drift by more than their scatter
//    allows, |drift| > z s_drift + kDriftAllowance |mean| (the least-squares test of
//    dem/stationarity.hpp), the oldest is dropped (it belongs to the transient) and nothing is
//    done;
//  - once at least kSteadyWindows windows (4: two strains at the usual 0.5 per window, and two
//    degrees of freedom for the drift's scatter; with 3 windows and one the drift test let a
//    bed through that still sped up by 5% a strain) show no drift, f = their mean (standard error
//    se_f) gives the steady bulk rate g = f U / H at this speed. Within kSettleTolerance of the
//    target (the stationarity test's tolerance) the controller has settled; within the estimate's
//    own standard error se_f / f it waits for more windows; further off the speed steps (clamped to
//    a factor kMaxStep, the first step to kMaxFirstStep) and the windows start anew.
// The step learns how the rate answers the speed, since the bulk rate is NOT in proportion to
// it (measured in the 8 x 10 x 8 cell: the walls went from 16.5 to 8.75 m/s and the steady bulk
// rate stayed at 10-13 1/s, so the proportional law stepped far too far): with steady points on
// both sides of the target (the latest of each, the lower speed below), regula falsi between
// them; with two steady points on one side, the secant through them, if the rate grew with the
// speed by more than kZ standard errors (its step at most kMaxExtrapolation times the
// proportional one); otherwise (the first step, or a rate that fell as the speed rose) the
// proportional guess U* = g_target H / f.
#include <vector>

#include "dem/binary_io.hpp"
#include "dem/stationarity.hpp"

namespace millflow::dem {

// The rough-wall cell's protocol (the strains of a ShearCellProtocol; docs/shear_cells.md,
// "Wall speed"): a warm-up in windows of 1 strain (4 at least, to a cap of 16: the bed leaves
// compaction denser than it flows and takes 10-16 strains to reach its flowing density), then 8
// strains measured with the catch-up law below. Shorter ones missed the site's rate by up to
// 17.5% (warm-up in windows of 0.5 strain to 12, 4 measured) and 9.0% (the same, 8 measured) on
// seeds 1-3 of the 8 x 10 x 8 d test cell even with the catch-up law. Campaigns (Lees-Edwards)
// set their own strains.
struct RoughWallStrains {
  double warmup_strain = 4.0;
  int warmup_windows = 4;
  double max_warmup_strain = 16.0;
  double measure_strain = 8.0;
};
inline constexpr RoughWallStrains kRoughWallStrains{};

// The least height (gradient direction, ball diameters) of a rough-wall cell: below it the wall
// layers leave too little bulk between them (about 2 d at 6 d) and bias the friction. Measured
// against Lees-Edwards at the walls' bulk I (docs/cell_validation.md, table 4 a tenth time):
// tau / p_yy at 6 d 11% below it (6 cells 5 and 8 d wide, -4.8% to -15.8%), at 8-12 d 6% below
// (12 cells, -0.4% to -12.0%; 8 d alone 7.6%), as at every larger size.
inline constexpr double kRoughWallLeastHeight = 8.0;

class WallSpeedController {
 public:
  static constexpr int kSteadyWindows = 4;
  static constexpr double kDriftAllowance = 0.05;
  static constexpr double kZ = 2.5;
  static constexpr double kMaxStep = 2.0;
  // The first step comes on a bed still dilating out of compaction: its bulk fraction then is
  // 0.6-0.75 of the flowing bed's (0.37 against 0.63 in a 5 x 12 x 5 d cell, 0.61 against 0.8 in
  // the 8 x 10 x 8 d cell of seed 2), so the proportional step on it overshot by as much (up to
  // 1.75x, where the first guess, f = 0.65, was already right). 1.25 reaches upward every
  // flowing bulk fraction the table-4 cells measured (0.55-0.93: at most 0.65 / 0.55 = 1.18 up);
  // a bed flowing at more than 0.81 takes a second step down. Later steps, on a bed that has
  // flowed, may go kMaxStep (docs/cell_validation.md, table 4 a tenth time).
  static constexpr double kMaxFirstStep = 1.25;
  // The stationarity test's tolerance on the bulk rate: a controller that settled only within a
  // tighter band kept stepping a bed the cell already called stationary, and each step restarts
  // its 2-3 strain lag (the 8 x 10 x 8 test cell ended up to 8% off on such late steps).
  static constexpr double kSettleTolerance = StationarityCriterion{}.tolerance;
  static constexpr double kMaxExtrapolation = 2.0;

  // The measured window (a catch-up law on the window's mean): every kMeasuredControlStrain of
  // the target's strain the speed is set so that the bulk strain the window is short of (or
  // ahead of) the target's is made up over the next kCatchUpStrain: the next stretch's rate
  // g* = g_t + (g_t - G) T g_t / kCatchUpStrain, G the bulk rate of the window so far (the fit
  // the result reports) and T its duration, g* within kMaxCatchUp of g_t; the speed for it
  // U = g* H / f, f = G T H / (the walls' travel over the window) the window's bulk fraction so
  // far, at most a factor kMaxMeasuredStep from the speed before. Why: a bed that has reached
  // its flowing state still wanders by 10-20% in bulk rate within 2-3 strains, so a window of 8
  // strains at a fixed speed missed the site's rate by up to 15% (8 x 10 x 8 d test cell, seeds
  // 1-6: +6.5, +0.4, +15.0, +1.2, -2.5, -2.0%), and with the catch-up by at most 3.2% (+3.2,
  // +0.5, +1.1, -1.3, +0.2, +1.5%). Gentle on purpose: the bulk rate answers a speed change
  // only 2-3 strains later, and a law that made up the deficit over 2 strains, 25% and 25% a
  // step, swung the walls from 1.97 to 1.28 m/s and back and left -4.9% (docs/cell_validation.md,
  // table 4 a seventh time).
  static constexpr double kMeasuredControlStrain = 0.5;
  static constexpr double kCatchUpStrain = 4.0;
  static constexpr double kMaxCatchUp = 0.1;
  static constexpr double kMaxMeasuredStep = 1.05;

  explicit WallSpeedController(double target_rate) : target_rate_(target_rate) {}

  // A window's measured bulk rate (1/s) at wall speed `wall_speed` (m/s, the speed this
  // controller last returned, or the first guess) and gap `gap` (m): returns the wall speed for
  // the next window.
  double update(double measured_rate, double wall_speed, double gap);
  bool settled() const { return settled_; }
  // The bulk fraction of the last steady estimate (0 before the first).
  double bulk_fraction() const { return bulk_fraction_; }
  // Windows at the current speed the next estimate rests on.
  int windows() const { return static_cast<int>(fractions_.size()); }

  // Opens the measured window (its travel and duration start at zero).
  void start_measured_window();
  // A control point of the measured window: the window's bulk rate so far `window_rate` (1/s)
  // over its duration so far `window_time` (s), the walls at `wall_speed` (m/s) since the last
  // point and the gap `gap` (m): returns the wall speed for the next stretch.
  double update_measured(double window_rate, double window_time, double wall_speed, double gap);
  // The walls' mean speed over the measured window of duration `window_time`, the walls at
  // `wall_speed` since the last control point.
  double measured_mean_speed(double window_time, double wall_speed) const;

  // Checkpoint state: the current windows' bulk fractions (a span of doubles), the last steady
  // estimate (double), settled (uint8), then the steady points that stepped (the last, the
  // latest below the target, the latest above it; each: speed, bulk fraction and its standard
  // error, three doubles, speed 0 for none), then the measured window's duration up to its last
  // control point (s) and the walls' travel over it (m) (two doubles).
  void write(BinaryWriter& out) const;
  void read(BinaryReader& in);

 private:
  // A steady estimate that made the speed step: its speed (m/s, 0 for none), bulk fraction and
  // the fraction's standard error.
  struct SteadyPoint {
    double speed = 0.0, fraction = 0.0, fraction_error = 0.0;
    bool known() const { return speed > 0.0; }
  };
  // The speed that the steady point `now` (already filed below or above) asks for, unclamped;
  // `previous` is the steady point before it.
  double next_speed(const SteadyPoint& now, const SteadyPoint& previous, double gap);

  double target_rate_;
  std::vector<double> fractions_;  // f_i of the windows at the current speed, oldest first
  double bulk_fraction_ = 0.0;
  bool settled_ = false;
  SteadyPoint last_, below_, above_;
  double measured_time_ = 0.0, measured_travel_ = 0.0;  // the measured window's, s and m
};

}  // namespace millflow::dem
