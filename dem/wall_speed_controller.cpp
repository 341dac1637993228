#include "dem/wall_speed_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "dem/stationarity.hpp"

namespace millflow::dem {
namespace {

bool drifts(const SeriesFit& fit) {
  return std::abs(fit.drift) > WallSpeedController::kZ * fit.drift_error +
                                   WallSpeedController::kDriftAllowance * std::abs(fit.mean);
}

}  // namespace

double WallSpeedController::update(double measured_rate, double wall_speed, double gap) {
  fractions_.push_back(measured_rate * gap / wall_speed);
  while (fractions_.size() > kSteadyWindows && drifts(fit_series(fractions_)))
    fractions_.erase(fractions_.begin());
  if (fractions_.size() < kSteadyWindows) return wall_speed;
  const SeriesFit fit = fit_series(fractions_);
  if (drifts(fit)) return wall_speed;
  bulk_fraction_ = fit.mean;
  // A bed that does not follow the walls at all (f <= 0) asks for the largest step up.
  const double change =
      bulk_fraction_ > 0.0 ? target_rate_ * gap / bulk_fraction_ / wall_speed : kMaxStep;
  settled_ = std::abs(change - 1.0) <= kSettleTolerance;
  // A change within the estimate's own standard error waits for more windows.
  const double error = bulk_fraction_ > 0.0 ? fit.mean_error / bulk_fraction_ : 0.0;
  if (std::abs(change - 1.0) <= std::max(kSettleTolerance, error)) return wall_speed;
  fractions_.clear();
  return wall_speed * std::clamp(change, 1.0 / kMaxStep, kMaxStep);
}

void WallSpeedController::write(BinaryWriter& out) const {
  out.put_span<double>(fractions_);
  out.put(bulk_fraction_);
  out.put<std::uint8_t>(settled_);
}

void WallSpeedController::read(BinaryReader& in) {
  fractions_ = in.get_vector<double>();
  bulk_fraction_ = in.get<double>();
  settled_ = in.get<std::uint8_t>() != 0;
}

}  // namespace millflow::dem
