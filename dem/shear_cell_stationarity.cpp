// The stationarity test of two consecutive warm-up windows (ShearCellProtocol).
#include "dem/shear_cell.hpp"

#include <cmath>

#include "dem/shear_cell_geometry.hpp"

namespace millflow::dem {

using namespace shear_cell_detail;

bool ShearCell::stationary(const WindowSummary& previous, const WindowSummary& last) const {
  const auto near = [](double value, double target, double tolerance) {
    return std::abs(value - target) <= tolerance * std::abs(target);
  };
  const bool rate_ok =
      !walls() || near(last.bulk_shear_rate, setup_.shear_rate, kStationaryStressTolerance);
  return rate_ok && near(last.normal_stress, setup_.normal_stress, kStationaryStressTolerance) &&
         std::abs(last.solid_fraction - previous.solid_fraction) <= kStationarySolidFractionDrift &&
         near(last.shear_stress, 0.5 * (last.shear_stress + previous.shear_stress),
              0.5 * kStationaryShearDrift);
}

}  // namespace millflow::dem
