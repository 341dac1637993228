#include "dem/wall_speed_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

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
  const double rate = bulk_fraction_ * wall_speed / gap;
  const double off = rate / target_rate_ - 1.0;
  settled_ = std::abs(off) <= kSettleTolerance;
  // A miss within the estimate's own standard error waits for more windows.
  const double error = bulk_fraction_ > 0.0 ? fit.mean_error / bulk_fraction_ : 0.0;
  if (std::abs(off) <= std::max(kSettleTolerance, error)) return wall_speed;
  const SteadyPoint point{
      .speed = wall_speed, .fraction = bulk_fraction_, .fraction_error = fit.mean_error};
  const SteadyPoint previous = last_;
  last_ = point;
  (off < 0.0 ? below_ : above_) = point;
  fractions_.clear();
  const double most = previous.known() ? kMaxStep : kMaxFirstStep;
  return std::clamp(next_speed(point, previous, gap), wall_speed / most, wall_speed * most);
}

double WallSpeedController::next_speed(const SteadyPoint& now, const SteadyPoint& previous,
                                       double gap) {
  const auto rate = [gap](const SteadyPoint& p) { return p.fraction * p.speed / gap; };
  const auto rate_error = [gap](const SteadyPoint& p) { return p.fraction_error * p.speed / gap; };
  // The target bracketed (a speed below it at a lower speed than one above it): regula falsi.
  if (below_.known() && above_.known()) {
    if (below_.speed < above_.speed)
      return below_.speed + (target_rate_ - rate(below_)) * (above_.speed - below_.speed) /
                                (rate(above_) - rate(below_));
    // A rate that fell as the speed rose (scatter, or a bed that slips more): the older end
    // goes, the newer one stays.
    (rate(now) < target_rate_ ? above_ : below_) = SteadyPoint{};
  }
  // The first guess: the bulk rate in proportion to the speed (a bed that does not follow the
  // walls at all, f <= 0, asks for the largest step up).
  const double proportional =
      now.fraction > 0.0 ? target_rate_ * gap / now.fraction : now.speed * kMaxStep;
  // Two steady points on one side: the secant through them, if the rate grew with the speed by
  // more than kZ of their standard errors (a secant through scatter stepped the 6 x 6 x 6 test
  // cell 25% too slow), at most kMaxExtrapolation times the proportional step (a bed that still
  // lags looks less sensitive than it is, and the secant through it overshot by up to 70%).
  if (previous.known() && previous.speed != now.speed) {
    const double change = rate(now) - rate(previous);
    const double slope = change / (now.speed - previous.speed);
    if (slope > 0.0 && std::abs(change) > WallSpeedController::kZ *
                                              std::hypot(rate_error(now), rate_error(previous))) {
      const double step = (target_rate_ - rate(now)) / slope;
      const double limit = kMaxExtrapolation * std::abs(proportional - now.speed);
      return now.speed + std::clamp(step, -limit, limit);
    }
  }
  return proportional;
}

void WallSpeedController::start_measured_window() {
  measured_time_ = 0.0;
  measured_travel_ = 0.0;
}

double WallSpeedController::update_measured(double window_rate, double window_time,
                                            double wall_speed, double gap) {
  measured_travel_ += wall_speed * (window_time - measured_time_);
  measured_time_ = window_time;
  const double fraction =
      measured_travel_ > 0.0 ? window_rate * window_time * gap / measured_travel_ : 0.0;
  if (!(fraction > 0.0) || !(window_time > 0.0)) return wall_speed;
  const double behind = (target_rate_ - window_rate) * window_time;  // bulk strain short
  const double rate =
      std::clamp(target_rate_ + behind * target_rate_ / kCatchUpStrain,
                 (1.0 - kMaxCatchUp) * target_rate_, (1.0 + kMaxCatchUp) * target_rate_);
  return std::clamp(rate * gap / fraction, wall_speed / kMaxMeasuredStep,
                    wall_speed * kMaxMeasuredStep);
}

double WallSpeedController::measured_mean_speed(double window_time, double wall_speed) const {
  if (!(window_time > 0.0)) return wall_speed;
  return (measured_travel_ + wall_speed * (window_time - measured_time_)) / window_time;
}

void WallSpeedController::write(BinaryWriter& out) const {
  out.put_span<double>(fractions_);
  out.put(bulk_fraction_);
  out.put<std::uint8_t>(settled_);
  for (const SteadyPoint& p : {last_, below_, above_})
    for (double v : {p.speed, p.fraction, p.fraction_error}) out.put(v);
  out.put(measured_time_);
  out.put(measured_travel_);
}

void WallSpeedController::read(BinaryReader& in) {
  fractions_ = in.get_vector<double>();
  bulk_fraction_ = in.get<double>();
  settled_ = in.get<std::uint8_t>() != 0;
  for (SteadyPoint* p : {&last_, &below_, &above_})
    for (double* v : {&p->speed, &p->fraction, &p->fraction_error}) *v = in.get<double>();
  measured_time_ = in.get<double>();
  measured_travel_ = in.get<double>();
}

}  // namespace millflow::dem
