#include "dem/domain.hpp"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace millflow::dem {

void Domain::validate() const {
  for (int a = 0; a < 3; ++a) {
    if (!(hi[a] > lo[a])) {
      throw std::invalid_argument(
          fmt::format("domain: hi[{}] = {} must be greater than lo[{}] = {}", a, hi[a], a, lo[a]));
    }
  }
  if (lees_edwards.enabled) {
    const int f = lees_edwards.flow_axis, g = lees_edwards.gradient_axis;
    if (f < 0 || f > 2 || g < 0 || g > 2 || f == g) {
      throw std::invalid_argument(fmt::format(
          "domain: Lees-Edwards flow_axis = {} and gradient_axis = {} must be distinct axes 0..2",
          f, g));
    }
    if (!periodic[f] || !periodic[g]) {
      throw std::invalid_argument(
          "domain: Lees-Edwards needs both its flow and gradient axes periodic");
    }
    if (!std::isfinite(lees_edwards.velocity)) {
      throw std::invalid_argument("domain: Lees-Edwards velocity is not finite");
    }
  }
}

bool Domain::wrap(Vec3& position, Vec3& velocity) const {
  bool changed = false;
  const Vec3 len = length();
  if (lees_edwards.enabled) {
    const int g = lees_edwards.gradient_axis, f = lees_edwards.flow_axis;
    const auto cross_gradient_faces = [&](double n) {
      position[g] -= n * len[g];
      position[f] -= n * lees_edwards.offset;
      velocity[f] -= n * lees_edwards.velocity;
      changed = true;
    };
    const double n = std::floor((position[g] - lo[g]) / len[g]);
    if (n != 0.0) cross_gradient_faces(n);
    // Rounding can leave position == hi: that point is on the lower face of the next image, so
    // it crosses once more (flow shift included) rather than being reset to lo in place.
    if (position[g] >= hi[g]) {
      cross_gradient_faces(1.0);
      position[g] = lo[g];
    }
  }
  for (int axis = 0; axis < 3; ++axis) {
    if (!periodic[axis]) continue;
    if (lees_edwards.enabled && axis == lees_edwards.gradient_axis) continue;
    if (position[axis] >= lo[axis] && position[axis] < hi[axis]) continue;  // the common case
    const double n = std::floor((position[axis] - lo[axis]) / len[axis]);
    if (n != 0.0) {
      position[axis] -= n * len[axis];
      changed = true;
    }
    // Rounding can leave position == hi; keep the half-open interval.
    if (position[axis] >= hi[axis]) position[axis] = lo[axis];
  }
  return changed;
}

void Domain::advance_shear(double dt) {
  if (!lees_edwards.enabled) return;
  const double len = length()[lees_edwards.flow_axis];
  lees_edwards.offset = std::fmod(lees_edwards.offset + lees_edwards.velocity * dt, len);
  if (lees_edwards.offset < 0.0) lees_edwards.offset += len;
  // A tiny negative remainder plus len rounds to len itself, which is the same image as 0.
  if (lees_edwards.offset >= len) lees_edwards.offset = 0.0;
}

}  // namespace millflow::dem
