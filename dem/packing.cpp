#include "dem/packing.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "util/sphere.hpp"

namespace millflow::dem {
namespace {

// The z of each layer and its stacking (0, 1, 2 for A, B, C): neighbouring layers, also across a
// periodic boundary, never share a stacking.
struct Layer {
  double z = 0.0;
  int stacking = 0;
};

std::vector<Layer> axial_layers(const MillShell& mill, double radius, double clearance,
                                double spacing) {
  const double min_gap = spacing * std::sqrt(2.0 / 3.0);
  std::vector<Layer> layers;
  if (mill.end_walls) {
    const double first = radius + clearance, span = mill.length - 2.0 * first;
    if (span < 0.0) return layers;
    const int gaps = static_cast<int>(std::floor(span / min_gap));
    for (int k = 0; k <= gaps; ++k) {
      layers.push_back(
          {.z = gaps > 0 ? first + k * span / gaps : 0.5 * mill.length, .stacking = k % 2});
    }
    return layers;
  }
  if (mill.length < spacing) {
    throw std::invalid_argument(
        fmt::format("a periodic mill slice of length {} m is shorter than the lattice spacing {} m",
                    mill.length, spacing));
  }
  const int count = std::max(1, static_cast<int>(std::floor(mill.length / min_gap)));
  const double gap = mill.length / count;
  for (int k = 0; k < count; ++k) {
    // An odd count closes the ring with C, between the B before it and the A after it.
    const bool closing = count % 2 == 1 && count > 1 && k == count - 1;
    layers.push_back({.z = (k + 0.5) * gap, .stacking = closing ? 2 : k % 2});
  }
  return layers;
}

}  // namespace

std::vector<Vec3> mill_lattice_sites(const MillShell& mill, double theta, double radius,
                                     double spacing, const Vec3& down, double jitter, Rng& rng) {
  if (!(spacing >= 2.0 * radius)) {
    throw std::invalid_argument(fmt::format(
        "lattice spacing {} m is smaller than the ball diameter {} m", spacing, 2 * radius));
  }
  const double clearance = 0.5 * (spacing - 2.0 * radius) * std::clamp(jitter, 0.0, 1.0);
  const double row_gap = spacing * std::sqrt(3.0) / 2.0;
  const int n_columns = static_cast<int>(std::ceil(mill.radius / spacing)) + 1;
  const int n_rows = static_cast<int>(std::ceil(mill.radius / row_gap)) + 1;
  std::vector<Vec3> sites;
  for (const Layer& layer : axial_layers(mill, radius, clearance, spacing)) {
    // Stacking s shifts the layer by s x (spacing / 2, spacing / (2 sqrt 3)): onto the hollows.
    const double shift_x = 0.5 * spacing * layer.stacking,
                 shift_y = spacing / (2.0 * std::sqrt(3.0)) * layer.stacking;
    for (int j = -n_rows; j <= n_rows; ++j) {
      const double row_shift = (j % 2 == 0) ? 0.0 : 0.5 * spacing;
      for (int i = -n_columns; i <= n_columns; ++i) {
        const Vec3 site(i * spacing + row_shift + shift_x, j * row_gap + shift_y, layer.z);
        if (sphere_clear_of_mill(mill, theta, site, radius + clearance)) sites.push_back(site);
      }
    }
  }
  std::stable_sort(sites.begin(), sites.end(),
                   [&](const Vec3& a, const Vec3& b) { return a.dot(down) > b.dot(down); });
  for (Vec3& site : sites) {
    site += clearance * Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)) /
            std::sqrt(3.0);
  }
  return sites;
}

std::size_t balls_for_fill(const MillShell& mill, double fill, double diameter, double packing) {
  const double ball_volume = util::sphere_volume_of_diameter(diameter);
  const double charge_volume = fill * mill_free_cross_section_area(mill) * mill.length;
  return static_cast<std::size_t>(std::llround(charge_volume * packing / ball_volume));
}

}  // namespace millflow::dem
