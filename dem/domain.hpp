#pragma once
// The simulation box: bounds, periodic axes and Lees-Edwards (sheared periodic) images.
//
// Lees-Edwards convention: the periodic image of the box one box length above along
// `gradient_axis` is displaced by +offset along `flow_axis` and moves with +velocity along it.
// A particle leaving through the upper face re-enters through the lower face with its flow
// coordinate shifted by -offset and its flow velocity by -velocity (and the reverse).
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "dem/vec.hpp"

namespace millflow::dem {

// std::round (halves away from zero) for every double, inline: without SSE4.1 the compiler calls
// libm for it, in the image code of every pair that straddles a periodic face. Below 2^52 the
// conversion truncates exactly and x - trunc(x) is exact; at and above it every double is whole
// (infinities and NaN pass through, as with std::round).
inline double round_half_away(double x) {
  if (!(std::abs(x) < 0x1p52)) return x;
  const double whole = std::copysign(static_cast<double>(static_cast<std::int64_t>(x)), x);
  return std::abs(x - whole) >= 0.5 ? whole + std::copysign(1.0, x) : whole;
}

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
  // crossings. Returns true if the position changed. Inline: it runs for every particle and step.
  bool wrap(Vec3& position, Vec3& velocity) const;

  // Advances the Lees-Edwards offset by velocity * dt, kept in [0, L_flow).
  void advance_shear(double dt);
};

// Domain::separation and Domain::wrap with the box's constants worked out once, for loops over
// many pairs or particles (construct one per loop, as a local). Domain's own functions call these,
// so both give the same bits.
class PeriodicImages {
 public:
  explicit PeriodicImages(const Domain& domain) {
    const Vec3 len = domain.length();
    for (int axis = 0; axis < 3; ++axis) {
      lo_[axis] = domain.lo[axis];
      hi_[axis] = domain.hi[axis];
      length_[axis] = len[axis];
      // Separations shorter than half a box need no image; an axis without images (open, or the
      // Lees-Edwards gradient axis, which goes first) gets an infinite threshold.
      const bool plain_periodic =
          domain.periodic[axis] &&
          !(domain.lees_edwards.enabled && axis == domain.lees_edwards.gradient_axis);
      half_length_[axis] =
          plain_periodic ? 0.5 * len[axis] : std::numeric_limits<double>::infinity();
      wraps_[axis] = plain_periodic;
    }
    lees_edwards_ = domain.lees_edwards.enabled;
    gradient_ = domain.lees_edwards.gradient_axis;
    flow_ = domain.lees_edwards.flow_axis;
    offset_ = domain.lees_edwards.offset;
    image_velocity_ = domain.lees_edwards.velocity;
  }

  // Domain::separation; `gradient_images` receives how many boxes up the gradient axis the image
  // of b lies (0 without Lees-Edwards).
  Vec3 separation(const Vec3& a, const Vec3& b, double& gradient_images) const {
    Vec3 d = b - a;
    gradient_images = 0.0;
    if (lees_edwards_ && !(std::abs(d[gradient_]) < 0.5 * length_[gradient_])) {
      // The gradient axis first: crossing it moves the image along the flow axis.
      const double n = round_half_away(d[gradient_] / length_[gradient_]);
      if (n != 0.0) {
        d[gradient_] -= n * length_[gradient_];
        d[flow_] -= n * offset_;
        gradient_images = n;
      }
    }
    for (int axis = 0; axis < 3; ++axis) {
      // Most pairs are well inside half a box, where the division and rounding are skipped.
      if (!(std::abs(d[axis]) < half_length_[axis]))
        d[axis] -= round_half_away(d[axis] / length_[axis]) * length_[axis];
    }
    return d;
  }

  // The same, for callers that need no image count.
  Vec3 separation(const Vec3& a, const Vec3& b) const {
    double gradient_images = 0.0;
    return separation(a, b, gradient_images);
  }

  // The velocity to add to b's for its image `gradient_images` boxes up the gradient axis.
  Vec3 image_velocity(double gradient_images) const {
    Vec3 shift = Vec3::Zero();
    if (gradient_images != 0.0) shift[flow_] = -gradient_images * image_velocity_;
    return shift;
  }

  // Whether a position lies in [lo, hi) on every axis, where wrap() changes nothing (periodic
  // axis or not): the common case, in six comparisons.
  bool inside(const Vec3& position) const {
    return position[0] >= lo_[0] && position[0] < hi_[0] && position[1] >= lo_[1] &&
           position[1] < hi_[1] && position[2] >= lo_[2] && position[2] < hi_[2];
  }

  // Domain::wrap.
  bool wrap(Vec3& position, Vec3& velocity) const {
    if (inside(position)) return false;
    bool changed = false;
    if (lees_edwards_ &&
        !(position[gradient_] >= lo_[gradient_] && position[gradient_] < hi_[gradient_])) {
      const int g = gradient_, f = flow_;
      const auto cross_gradient_faces = [&](double n) {
        position[g] -= n * length_[g];
        position[f] -= n * offset_;
        velocity[f] -= n * image_velocity_;
        changed = true;
      };
      const double n = std::floor((position[g] - lo_[g]) / length_[g]);
      if (n != 0.0) cross_gradient_faces(n);
      // Rounding can leave position == hi: that point is on the lower face of the next image, so
      // it crosses once more (flow shift included) rather than being reset to lo in place.
      if (position[g] >= hi_[g]) {
        cross_gradient_faces(1.0);
        position[g] = lo_[g];
      }
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (!wraps_[axis] || (position[axis] >= lo_[axis] && position[axis] < hi_[axis])) continue;
      const double n = std::floor((position[axis] - lo_[axis]) / length_[axis]);
      if (n != 0.0) {
        position[axis] -= n * length_[axis];
        changed = true;
      }
      // Rounding can leave position == hi; keep the half-open interval.
      if (position[axis] >= hi_[axis]) position[axis] = lo_[axis];
    }
    return changed;
  }

 private:
  std::array<double, 3> lo_{}, hi_{}, length_{}, half_length_{};
  std::array<bool, 3> wraps_{};
  bool lees_edwards_ = false;
  int gradient_ = 1, flow_ = 0;
  double offset_ = 0.0, image_velocity_ = 0.0;
};

inline Vec3 Domain::separation(const Vec3& a, const Vec3& b, Vec3* velocity_shift) const {
  const PeriodicImages images(*this);
  double gradient_images = 0.0;
  const Vec3 d = images.separation(a, b, gradient_images);
  if (velocity_shift) *velocity_shift = images.image_velocity(gradient_images);
  return d;
}

inline bool Domain::wrap(Vec3& position, Vec3& velocity) const {
  return PeriodicImages(*this).wrap(position, velocity);
}

}  // namespace millflow::dem
