#pragma once
// Small shear cells shared by the shear-cell tests: 10 mm steel media under 1 kPa, soft contacts
// (k_n = 100 x normal stress x d, overlaps ~1% of d) so a cell shears a few strains in seconds.
#include <cmath>

#include "dem/shear_cell.hpp"

namespace millflow::dem::testing {

inline ShearCellSetup small_shear_cell(double inertial_number, double powder_load = 0.0,
                                       double powder_ratio = 0.3) {
  ShearCellSetup s;
  s.media_diameter = 0.01;
  s.media = {"steel", 7800.0};
  s.powder = {"clinker", 3000.0};
  s.normal_stress = 1000.0;
  s.size_diameters = Vec3(4, 6, 4);
  const double k = 100.0 * s.normal_stress * s.media_diameter;
  const double dp = powder_ratio * s.media_diameter;
  s.media_media = {.restitution = 0.5, .friction = 0.5, .normal_stiffness = k};
  s.media_powder = {
      .restitution = 0.5,
      .friction = 0.5,
      .normal_stiffness = size_scaled_stiffness(k, s.media_diameter, s.media_diameter, dp)};
  s.powder_powder = {.restitution = 0.5,
                     .friction = 0.5,
                     .normal_stiffness = size_scaled_stiffness(k, s.media_diameter, dp, dp)};
  s.powder_diameter_ratio = powder_ratio;
  s.powder_load = powder_load;
  // I = gdot d / sqrt(p / rho)
  s.shear_rate = inertial_number * std::sqrt(s.normal_stress / s.media.density) / s.media_diameter;
  return s;
}

}  // namespace millflow::dem::testing
