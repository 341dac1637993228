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

void Domain::advance_shear(double dt) {
  if (!lees_edwards.enabled) return;
  const double len = length()[lees_edwards.flow_axis];
  lees_edwards.offset = std::fmod(lees_edwards.offset + lees_edwards.velocity * dt, len);
  if (lees_edwards.offset < 0.0) lees_edwards.offset += len;
  // A tiny negative remainder plus len rounds to len itself, which is the same image as 0.
  if (lees_edwards.offset >= len) lees_edwards.offset = 0.0;
}

}  // namespace millflow::dem
