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
//  - once at least kSteadyWindows windows show no drift, f = their mean (standard error se_f)
//    asks for U* = g_target H / f. Within kSettleTolerance of U the controller has settled;
//    within the estimate's own standard error se_f / f it waits for more windows; further off
//    the speed steps to U* (clamped to a factor kMaxStep) and the windows start anew.
#include <vector>

#include "dem/binary_io.hpp"

namespace millflow::dem {

class WallSpeedController {
 public:
  static constexpr int kSteadyWindows = 3;
  static constexpr double kDriftAllowance = 0.05;
  static constexpr double kZ = 2.5;
  static constexpr double kMaxStep = 2.0;
  static constexpr double kSettleTolerance = 0.05;

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
  // estimate (double), settled (uint8).
  void write(BinaryWriter& out) const;
  void read(BinaryReader& in);

 private:
  double target_rate_;
  std::vector<double> fractions_;  // f_i of the windows at the current speed, oldest first
  double bulk_fraction_ = 0.0;
  bool settled_ = false;
};

}  // namespace millflow::dem
