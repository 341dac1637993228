#include "dem/wall_speed_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace millflow::dem {

double WallSpeedController::update(double measured_rate, double wall_speed, double gap) {
  rate_sum_ = kForgetting * rate_sum_ + measured_rate;
  nominal_sum_ = kForgetting * nominal_sum_ + wall_speed / gap;
  const double fraction = bulk_fraction();
  // A bed that does not follow the walls at all (f <= 0) asks for the largest step up.
  const double wanted = fraction > 0.0 ? target_rate_ * gap / fraction : kMaxStep * wall_speed;
  ++windows_;
  settled_ = windows_ >= kSettleWindows && std::abs(wanted / wall_speed - 1.0) <= kSettleTolerance;
  const double step = std::clamp(std::pow(wanted / wall_speed, kGain), 1.0 / kMaxStep, kMaxStep);
  return wall_speed * step;
}

double WallSpeedController::bulk_fraction() const {
  return nominal_sum_ > 0.0 ? rate_sum_ / nominal_sum_ : 0.0;
}

void WallSpeedController::write(BinaryWriter& out) const {
  out.put(rate_sum_);
  out.put(nominal_sum_);
  out.put<std::int32_t>(windows_);
  out.put<std::uint8_t>(settled_);
}

void WallSpeedController::read(BinaryReader& in) {
  rate_sum_ = in.get<double>();
  nominal_sum_ = in.get<double>();
  windows_ = in.get<std::int32_t>();
  settled_ = in.get<std::uint8_t>() != 0;
}

}  // namespace millflow::dem
