#pragma once
// The rough-wall cell's wall-speed controller (docs/shear_cells.md, "Stress control"): rough
// walls slip, so the wall speed U that gives the site's bulk shear rate is found between warm-up
// windows. Each window measures the bulk rate g_i at its wall speed U_i and gap H_i; in a 6-ball
// cell one window's rate scatters by 20-30%, so a controller that steps on it alone never
// settles. The bulk fraction f = g H / U (bulk rate over nominal rate) is a property of the bed
// that changes slowly with U, so it is estimated over the windows so far, older ones fading:
//   f = sum_i l^(n-i) g_i / sum_i l^(n-i) U_i / H_i,   l = kForgetting,
// and the speed moves a fraction of the way (in log) to the one that estimate asks for:
//   U <- U (U* / U)^kGain,   U* = g_target H / f,   the step clamped to a factor kMaxStep.
// It has settled when the estimate rests on at least kSettleWindows windows and U is within
// kSettleTolerance of U* (then the filtered estimate puts the bulk rate within that of the
// target).
#include "dem/binary_io.hpp"

namespace millflow::dem {

class WallSpeedController {
 public:
  static constexpr double kForgetting = 0.8;
  static constexpr double kGain = 0.5;
  static constexpr double kMaxStep = 2.0;
  static constexpr double kSettleTolerance = 0.05;
  static constexpr int kSettleWindows = 3;

  explicit WallSpeedController(double target_rate) : target_rate_(target_rate) {}

  // A window's measured bulk rate (1/s) at wall speed `wall_speed` (m/s) and gap `gap` (m):
  // returns the wall speed for the next window.
  double update(double measured_rate, double wall_speed, double gap);
  bool settled() const { return settled_; }
  // The filtered bulk fraction f (0 before the first update).
  double bulk_fraction() const;

  // Checkpoint state: the two weighted sums (doubles), the windows seen (int32), settled (uint8).
  void write(BinaryWriter& out) const;
  void read(BinaryReader& in);

 private:
  double target_rate_;
  double rate_sum_ = 0.0, nominal_sum_ = 0.0;
  int windows_ = 0;
  bool settled_ = false;
};

}  // namespace millflow::dem
