#pragma once
// The simulation box: bounds, periodic axes and Lees-Edwards (sheared periodic) images.
//
// Lees-Edwards convention: the periodic image of the box one box length above along
// `gradient_axis` is displaced by +offset along `flow_axis` and moves with +velocity along it.
// A particle leaving through the upper face re-enters through the lower face with its flow
// coordinate shifted by -offset and its flow velocity by -velocity (and the reverse).
#include <array>
#include <cmath>
#include <string>

#include "dem/vec.hpp"

namespace millflow::dem {

struct LeesEdwards {
  bool enabled = false;
  int flow_axis = 0;
  int gradient_axis = 1;
  double offset = 0.0;    // current displacement of the upper image along flow_axis, in [0, L_flow)
  double velocity = 0.0;  // relative velocity of the upper image: shear rate * L_gradient
};

struct Domain {
  Vec3 lo = Vec3::Zero();
  Vec3 hi = Vec3::Ones();
  std::array<bool, 3> periodic{false, false, false};
  LeesEdwards lees_edwards;

  Vec3 length() const { return hi - lo; }

  // Throws std::invalid_argument naming the bad value (hi <= lo, Lees-Edwards axes not periodic
  // or equal, ...).
  void validate() const;

  // Minimum-image vector from a to b. With Lees-Edwards, the image of b across the gradient
  // boundary is shifted along the flow axis; `velocity_shift` (if given) receives the velocity to
  // add to b's velocity for that image. Inline: it is the inner loop of the neighbour search.
  Vec3 separation(const Vec3& a, const Vec3& b, Vec3* velocity_shift = nullptr) const;

  // Maps a position back into [lo, hi) on periodic axes; adjusts the velocity for Lees-Edwards
  // crossings. Returns true if the position changed.
  bool wrap(Vec3& position, Vec3& velocity) const;

  // Advances the Lees-Edwards offset by velocity * dt, kept in [0, L_flow).
  void advance_shear(double dt);
};

// Number of box lengths to take off a separation along one periodic axis. Most pairs are well
// inside half a box, where the division and rounding are skipped.
inline double image_count(double d, double length) {
  return std::abs(d) < 0.5 * length ? 0.0 : std::round(d / length);
}

inline Vec3 Domain::separation(const Vec3& a, const Vec3& b, Vec3* velocity_shift) const {
  Vec3 d = b - a;
  const Vec3 len = length();
  if (velocity_shift) velocity_shift->setZero();
  if (lees_edwards.enabled) {
    // The gradient axis first: crossing it moves the image along the flow axis.
    const int g = lees_edwards.gradient_axis, f = lees_edwards.flow_axis;
    const double n = image_count(d[g], len[g]);
    if (n != 0.0) {
      d[g] -= n * len[g];
      d[f] -= n * lees_edwards.offset;
      if (velocity_shift) (*velocity_shift)[f] = -n * lees_edwards.velocity;
    }
  }
  for (int axis = 0; axis < 3; ++axis) {
    if (!periodic[axis]) continue;
    if (lees_edwards.enabled && axis == lees_edwards.gradient_axis) continue;
    d[axis] -= image_count(d[axis], len[axis]) * len[axis];
  }
  return d;
}

}  // namespace millflow::dem
