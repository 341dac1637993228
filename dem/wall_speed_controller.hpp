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
//    target the controller has settled; within the estimate's own standard error se_f / f it waits
//    for more windows; further off the speed steps (clamped to a factor kMaxStep) and the windows
//    start anew.
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

namespace millflow::dem {

class WallSpeedController {
 public:
  static constexpr int kSteadyWindows = 4;
  static constexpr double kDriftAllowance = 0.05;
  static constexpr double kZ = 2.5;
  static constexpr double kMaxStep = 2.0;
  static constexpr double kSettleTolerance = 0.05;
  static constexpr double kMaxExtrapolation = 2.0;

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

  // Checkpoint state: the current windows' bulk fractions (a span of doubles), the last steady
  // estimate (double), settled (uint8), then the steady points that stepped (the last, the
  // latest below the target, the latest above it; each: speed, bulk fraction and its standard
  // error, three doubles, speed 0 for none).
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
};

}  // namespace millflow::dem
