#include "dem/packing.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>

namespace millflow::dem {

std::vector<Vec3> mill_lattice_sites(const MillShell& mill, double theta, double radius, double spacing,
                                     const Vec3& down, double jitter, Rng& rng) {
  if (!(spacing >= 2.0 * radius)) {
    throw std::invalid_argument(fmt::format("lattice spacing {} m is smaller than the ball diameter {} m", spacing, 2 * radius));
  }
  const double clearance = 0.5 * (spacing - 2.0 * radius) * std::clamp(jitter, 0.0, 1.0);
  const int n_radial = static_cast<int>(std::floor(mill.radius / spacing));
  // Layers at (k + 1/2) spacing: across a periodic axial boundary they stay a spacing apart.
  const int n_axial = std::max(1, static_cast<int>(std::floor(mill.length / spacing)));
  std::vector<Vec3> sites;
  for (int i = -n_radial; i <= n_radial; ++i) {
    for (int j = -n_radial; j <= n_radial; ++j) {
      for (int k = 0; k < n_axial; ++k) {
        const Vec3 site(i * spacing, j * spacing, (k + 0.5) * spacing);
        if (sphere_clear_of_mill(mill, theta, site, radius + clearance)) sites.push_back(site);
      }
    }
  }
  std::stable_sort(sites.begin(), sites.end(), [&](const Vec3& a, const Vec3& b) { return a.dot(down) > b.dot(down); });
  for (Vec3& site : sites) {
    site += clearance * Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)) / std::sqrt(3.0);
  }
  return sites;
}

std::size_t balls_for_fill(const MillShell& mill, double fill, double diameter, double packing) {
  const double ball_volume = std::numbers::pi * diameter * diameter * diameter / 6.0;
  const double charge_volume = fill * mill_free_cross_section_area(mill) * mill.length;
  return static_cast<std::size_t>(std::llround(charge_volume * packing / ball_volume));
}

}  // namespace millflow::dem
