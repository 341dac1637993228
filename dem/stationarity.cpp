#include "dem/stationarity.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace millflow::dem {
namespace {

bool on_target(const SeriesFit& f, double target, double tolerance, double z) {
  return std::abs(f.mean - target) <= std::max(tolerance * std::abs(target), z * f.mean_error);
}

}  // namespace

SeriesFit fit_series(std::span<const double> x) {
  const auto n = static_cast<double>(x.size());
  SeriesFit out;
  for (double v : x) out.mean += v / n;
  const double k_mean = 0.5 * (n - 1.0);
  double skk = 0.0, skx = 0.0, sxx = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double dk = static_cast<double>(k) - k_mean;
    skk += dk * dk;
    skx += dk * (x[k] - out.mean);
    sxx += (x[k] - out.mean) * (x[k] - out.mean);
  }
  out.mean_error = std::sqrt(sxx / (n - 1.0) / n);
  const double slope = skx / skk;
  const double residual = std::max(0.0, sxx - slope * skx);  // sum of squared residuals
  out.drift = slope * (n - 1.0);
  out.drift_error = std::sqrt(residual / (n - 2.0) / skk) * (n - 1.0);
  return out;
}

StationarityVerdict test_stationarity(std::span<const WindowMeans> windows,
                                      double target_normal_stress, double target_shear_rate,
                                      const StationarityCriterion& c) {
  StationarityVerdict verdict;
  if (windows.size() < 3) return verdict;
  const auto series = [&](double WindowMeans::*field) {
    std::vector<double> x;
    for (const WindowMeans& w : windows) x.push_back(w.*field);
    return fit_series(x);
  };
  const SeriesFit shear = series(&WindowMeans::shear_stress);
  const SeriesFit solid = series(&WindowMeans::solid_fraction);
  verdict.shear_stress =
      std::abs(shear.drift) <= c.z * shear.drift_error + c.shear_floor * std::abs(shear.mean);
  verdict.solid_fraction =
      std::abs(solid.drift) <= std::max(c.solid_fraction_drift, c.z * solid.drift_error);
  const bool contact = std::ranges::all_of(windows, [&](const WindowMeans& w) {
    return w.normal_stress >= c.contact_fraction * target_normal_stress;
  });
  verdict.normal_stress = contact && on_target(series(&WindowMeans::normal_stress),
                                               target_normal_stress, c.tolerance, c.z);
  const SeriesFit rate = series(&WindowMeans::bulk_shear_rate);
  verdict.bulk_shear_rate =
      target_shear_rate <= 0.0 ||
      (on_target(rate, target_shear_rate, c.tolerance, c.z) &&
       std::abs(rate.drift) <= c.z * rate.drift_error + c.rate_floor * std::abs(rate.mean));
  return verdict;
}

}  // namespace millflow::dem
