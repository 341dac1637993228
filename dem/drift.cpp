#include "dem/drift.hpp"

#include "dem/system.hpp"

#include <algorithm>
#include <cmath>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

namespace millflow::dem {
namespace {

// One particle: the reference the four lanes follow, and where they cannot (a particle leaving
// the box, a displacement that may need a periodic image, a kinematic group). It holds copies of
// the arrays' addresses and the parameters: the stores through them could alias what a reference
// points to, and the compiler would load them again after each.
class ParticleDrift {
 public:
  ParticleDrift(const DriftArrays& arrays, const DriftParameters& parameters, const Domain& domain)
      : a_(arrays), p_(parameters), images_(domain) {}

  void operator()(std::size_t p, DriftMaxima& maxima) const {
    Vec3 v = a_.velocity[p];
    Vec3 w = a_.angular_velocity[p];
    v += a_.force[p] * (a_.inv_mass[p] * p_.half_dt);
    w += a_.torque[p] * (a_.inv_inertia[p] * p_.half_dt);
    if (a_.group != nullptr && a_.group[p] != kFreeParticle)
      v = a_.groups[a_.group[p] - 1].velocity;
    const double height = a_.position[p][p_.gradient_axis] - p_.flow_centre;
    maxima.peculiar_speed_sq =
        std::max(maxima.peculiar_speed_sq, (v - height * p_.flow_per_height).squaredNorm());
    Vec3 x = a_.position[p] + v * p_.dt;
    if (!images_.inside(x)) {
      // Through copies: the compiler keeps x and v in registers unless wrap() runs.
      Vec3 x_wrapped = x, v_wrapped = v;
      images_.wrap(x_wrapped, v_wrapped);
      x = x_wrapped;
      v = v_wrapped;
    }
    // Dashpots act on the velocity at the end of the step, predicted from the last forces.
    a_.predicted_velocity[p] = v + a_.force[p] * (a_.inv_mass[p] * p_.half_dt);
    a_.predicted_angular_velocity[p] = w + a_.torque[p] * (a_.inv_inertia[p] * p_.half_dt);
    a_.position[p] = x;
    a_.velocity[p] = v;
    a_.angular_velocity[p] = w;
    if (a_.reference_position != nullptr) {
      const std::array<double, 3>& limit = p_.no_image_limit;
      Vec3 moved = x - a_.reference_position[p];
      double moved_sq = moved.squaredNorm();
      if (!(moved_sq < p_.image_test_sq) &&  // below it, no axis can reach its limit
          !(std::abs(moved[0]) < limit[0] && std::abs(moved[1]) < limit[1] &&
            std::abs(moved[2]) < limit[2])) {
        double gradient_images;
        moved = images_.separation(a_.reference_position[p], x, gradient_images);
        moved_sq = moved.squaredNorm();
      }
      maxima.moved_sq = std::max(maxima.moved_sq, moved_sq);
    }
  }

 private:
  const DriftArrays a_;
  const DriftParameters p_;
  const PeriodicImages images_;
};

#if defined(__AVX2__)

// Four particles' 3-vectors as they lie in memory, twelve doubles in three registers:
// [x0 y0 z0 x1] [y1 z1 x2 y2] [z2 x3 y3 z3]. Arithmetic done element by element on them is the
// arithmetic of each particle's vector.
struct Flat {
  __m256d r[3];
};

Flat load(const Vec3* v) {
  const double* d = v->data();
  return {{_mm256_loadu_pd(d), _mm256_loadu_pd(d + 4), _mm256_loadu_pd(d + 8)}};
}

void store(Vec3* v, const Flat& f) {
  double* d = v->data();
  _mm256_storeu_pd(d, f.r[0]);
  _mm256_storeu_pd(d + 4, f.r[1]);
  _mm256_storeu_pd(d + 8, f.r[2]);
}

// a + b * c, element by element: a multiplication then an addition, each rounded (as the scalar
// code, built without contraction to FMA).
Flat add_product(const Flat& a, const Flat& b, const Flat& c) {
  Flat out;
  for (int k = 0; k < 3; ++k) out.r[k] = _mm256_add_pd(a.r[k], _mm256_mul_pd(b.r[k], c.r[k]));
  return out;
}

// A value per particle [s0 s1 s2 s3], repeated for each of its three components.
Flat per_component(__m256d s) {
  return {{_mm256_permute4x64_pd(s, _MM_SHUFFLE(1, 0, 0, 0)),
           _mm256_permute4x64_pd(s, _MM_SHUFFLE(2, 2, 1, 1)),
           _mm256_permute4x64_pd(s, _MM_SHUFFLE(3, 3, 3, 2))}};
}

// A 3-vector the same for every particle, laid out as Flat.
Flat repeated(const Vec3& v) {
  return {{_mm256_setr_pd(v[0], v[1], v[2], v[0]), _mm256_setr_pd(v[1], v[2], v[0], v[1]),
           _mm256_setr_pd(v[2], v[0], v[1], v[2])}};
}

// Component `axis` of the four vectors, one per lane.
__m256d component(const Flat& f, int axis) {
  const __m256d a0 = f.r[0], a1 = f.r[1], a2 = f.r[2];
  switch (axis) {
    case 0:  // [x0 y0 x2 x1] -> [x0 x3 x2 x1] -> [x0 x1 x2 x3]
      return _mm256_permute4x64_pd(_mm256_blend_pd(_mm256_blend_pd(a0, a1, 0b0100), a2, 0b0010),
                                   _MM_SHUFFLE(1, 2, 3, 0));
    case 1:  // [y1 y0 z0 y2] -> [y1 y0 y3 y2] -> [y0 y1 y2 y3]
      return _mm256_permute4x64_pd(_mm256_blend_pd(_mm256_blend_pd(a0, a1, 0b1001), a2, 0b0100),
                                   _MM_SHUFFLE(2, 3, 0, 1));
    default:  // [x0 z1 z0 x1] -> [z2 z1 z0 z3] -> [z0 z1 z2 z3]
      return _mm256_permute4x64_pd(_mm256_blend_pd(_mm256_blend_pd(a0, a1, 0b0010), a2, 0b1001),
                                   _MM_SHUFFLE(3, 0, 1, 2));
  }
}

// Each vector's squared norm, summed as Eigen sums a 3-vector's: (x x + y y) + z z.
__m256d squared_norms(const Flat& f) {
  Flat squares;
  for (int k = 0; k < 3; ++k) squares.r[k] = _mm256_mul_pd(f.r[k], f.r[k]);
  return _mm256_add_pd(_mm256_add_pd(component(squares, 0), component(squares, 1)),
                       component(squares, 2));
}

// Whether all twelve components of `x` lie in [lo, hi): PeriodicImages::inside for each.
bool all_inside(const Flat& x, const Flat& lo, const Flat& hi) {
  __m256d ok = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
  for (int k = 0; k < 3; ++k) {
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(x.r[k], lo.r[k], _CMP_GE_OQ));
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(x.r[k], hi.r[k], _CMP_LT_OQ));
  }
  return _mm256_movemask_pd(ok) == 0b1111;
}

// Whether particles p .. p + 3 are all marked kWeightOnly (force_state given: no force, no
// torque), so that their kicks, by zero, can be passed by.
bool four_unforced(const std::uint8_t* force_state, std::size_t p) {
  return force_state != nullptr && all_weight_only<4>(force_state + p);
}

// Four free particles at a time. A block with a particle that leaves the box, or a displacement
// that may need a periodic image, goes one particle at a time instead (nothing of it is stored
// before that is known), as does a NaN anywhere (it fails the tests, which are ordered compares).
DriftMaxima drift_on_lanes(const DriftArrays& arrays, const DriftParameters& prm,
                           const Domain& domain, std::size_t begin, std::size_t end,
                           DriftMaxima running) {
  const ParticleDrift one(arrays, prm, domain);
  const DriftArrays a = arrays;  // a copy, for the reason ParticleDrift holds one
  const Flat lo = repeated(domain.lo), hi = repeated(domain.hi);
  const Flat flow_per_height = repeated(prm.flow_per_height);
  const Flat step = per_component(_mm256_set1_pd(prm.dt));
  const __m256d half_dt = _mm256_set1_pd(prm.half_dt), centre = _mm256_set1_pd(prm.flow_centre);
  const __m256d image_test_sq = _mm256_set1_pd(prm.image_test_sq);
  const bool track = a.reference_position != nullptr;
  __m256d fastest = _mm256_set1_pd(running.peculiar_speed_sq);
  __m256d farthest = _mm256_set1_pd(running.moved_sq);
  std::size_t p = begin;
  // A block of four; kUnforced: none has a force or torque, so none is kicked, and their forces,
  // torques and inverse masses, a third of what the pass reads, stay unread (a path of its own,
  // so that the blocks with forces, all of a dense cell's, test nothing more).
  const auto block = [&]<bool kUnforced>(std::size_t p) __attribute__((always_inline)) {
    Flat v = load(a.velocity + p), w = load(a.angular_velocity + p);
    Flat force{}, torque{}, kick{}, turn{};
    if constexpr (!kUnforced) {
      force = load(a.force + p);
      torque = load(a.torque + p);
      kick = per_component(_mm256_mul_pd(_mm256_loadu_pd(a.inv_mass + p), half_dt));
      turn = per_component(_mm256_mul_pd(_mm256_loadu_pd(a.inv_inertia + p), half_dt));
      v = add_product(v, force, kick);
      w = add_product(w, torque, turn);
    }
    const Flat position = load(a.position + p);
    const Flat height =
        per_component(_mm256_sub_pd(component(position, prm.gradient_axis), centre));
    Flat peculiar;
    for (int k = 0; k < 3; ++k)
      peculiar.r[k] = _mm256_sub_pd(v.r[k], _mm256_mul_pd(height.r[k], flow_per_height.r[k]));
    const Flat x = add_product(position, v, step);
    if (!all_inside(x, lo, hi)) {
      for (std::size_t q = p; q != p + 4; ++q) one(q, running);
      return;
    }
    __m256d moved_sq = _mm256_setzero_pd();
    if (track) {
      const Flat reference = load(a.reference_position + p);
      Flat moved;
      for (int k = 0; k < 3; ++k) moved.r[k] = _mm256_sub_pd(x.r[k], reference.r[k]);
      moved_sq = squared_norms(moved);
      if (_mm256_movemask_pd(_mm256_cmp_pd(moved_sq, image_test_sq, _CMP_LT_OQ)) != 0b1111) {
        for (std::size_t q = p; q != p + 4; ++q) one(q, running);
        return;
      }
    }
    fastest = _mm256_max_pd(squared_norms(peculiar), fastest);
    farthest = _mm256_max_pd(moved_sq, farthest);
    store(a.position + p, x);
    if constexpr (kUnforced) {  // unkicked, v and w are what was read: their lines stay clean
      store(a.predicted_velocity + p, v);
      store(a.predicted_angular_velocity + p, w);
    } else {
      store(a.predicted_velocity + p, add_product(v, force, kick));
      store(a.predicted_angular_velocity + p, add_product(w, torque, turn));
      store(a.velocity + p, v);
      store(a.angular_velocity + p, w);
    }
  };
  for (; p + 4 <= end; p += 4) {
    if (four_unforced(a.force_state, p)) {
      block.template operator()<true>(p);
    } else {
      block.template operator()<false>(p);
    }
  }
  for (; p != end; ++p) one(p, running);
  alignas(32) double lanes[4];
  _mm256_store_pd(lanes, fastest);
  for (double lane : lanes) running.peculiar_speed_sq = std::max(running.peculiar_speed_sq, lane);
  if (track) {
    _mm256_store_pd(lanes, farthest);
    for (double lane : lanes) running.moved_sq = std::max(running.moved_sq, lane);
  }
  return running;
}

void kick_on_lanes(const DriftArrays& arrays, double half_dt, std::size_t begin, std::size_t end) {
  const DriftArrays a = arrays;  // a copy, for the reason ParticleDrift holds one
  const __m256d step = _mm256_set1_pd(half_dt);
  std::size_t p = begin;
  for (; p + 4 <= end; p += 4) {
    if (four_unforced(a.force_state, p)) continue;
    const Flat kick = per_component(_mm256_mul_pd(_mm256_loadu_pd(a.inv_mass + p), step));
    const Flat turn = per_component(_mm256_mul_pd(_mm256_loadu_pd(a.inv_inertia + p), step));
    store(a.velocity + p, add_product(load(a.velocity + p), load(a.force + p), kick));
    store(a.angular_velocity + p,
          add_product(load(a.angular_velocity + p), load(a.torque + p), turn));
  }
  kick_particles_one_at_a_time(a, half_dt, p, end);
}

#endif

}  // namespace

void kick_particles_one_at_a_time(const DriftArrays& arrays, double half_dt, std::size_t begin,
                                  std::size_t end) {
  Vec3* const velocity = arrays.velocity;
  Vec3* const angular_velocity = arrays.angular_velocity;
  const Vec3* const force = arrays.force;
  const Vec3* const torque = arrays.torque;
  const double* const inv_mass = arrays.inv_mass;
  const double* const inv_inertia = arrays.inv_inertia;
  for (std::size_t p = begin; p != end; ++p) {
    velocity[p] += force[p] * (inv_mass[p] * half_dt);
    angular_velocity[p] += torque[p] * (inv_inertia[p] * half_dt);
  }
}

void kick_particles(const DriftArrays& arrays, double half_dt, std::size_t begin, std::size_t end) {
#if defined(__AVX2__)
  kick_on_lanes(arrays, half_dt, begin, end);
#else
  kick_particles_one_at_a_time(arrays, half_dt, begin, end);
#endif
}

bool drift_uses_lanes() {
#if defined(__AVX2__)
  return true;
#else
  return false;
#endif
}

DriftMaxima drift_particles_one_at_a_time(const DriftArrays& arrays,
                                          const DriftParameters& parameters, const Domain& domain,
                                          std::size_t begin, std::size_t end, DriftMaxima running) {
  const ParticleDrift one(arrays, parameters, domain);
  for (std::size_t p = begin; p != end; ++p) one(p, running);
  return running;
}

DriftMaxima drift_particles(const DriftArrays& arrays, const DriftParameters& parameters,
                            const Domain& domain, std::size_t begin, std::size_t end,
                            DriftMaxima running) {
#if defined(__AVX2__)
  // A kinematic group's members take its velocity: one at a time (the cells with rough walls).
  if (arrays.group == nullptr)
    return drift_on_lanes(arrays, parameters, domain, begin, end, running);
#endif
  return drift_particles_one_at_a_time(arrays, parameters, domain, begin, end, running);
}

}  // namespace millflow::dem
