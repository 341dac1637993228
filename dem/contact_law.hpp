#pragma once
// The contact law of the paper (Cleary, eq. 1-2) as pure functions, free of any state.
//
//   F_n = k_n dx - C_n v_n                      (along the normal, on body a)
//   F_t = -(k_t s + C_t v_t), |F_t| <= mu |F_n|  (s: incremental tangential spring, the sum of
//                                                the contact points' tangential displacements)
//
// The caller keeps the spring s per contact (the contact-history store) and passes it in; the
// function returns the updated spring. The normal force is not clipped at
// zero as the pair separates: the contact ends when the overlap returns to zero, which makes the
// measured restitution equal the analytic e of the pair.
//
// Sliding follows LAMMPS's granular pair styles (without limit_damping) and MercuryDPM, so that
// the same case gives the same contacts in all three: the limit takes F_n with its dashpot and in
// magnitude (in the damped tail of an unloading contact, where the dashpot pulls harder than the
// spring pushes, F_n < 0 and the contact still holds up to mu |F_n|), and a sliding contact's
// spring is reset so that spring and dashpot together give the limit force. Until 5 December
// 2026 millflow took mu max(F_n, 0) and put the whole limit force in the spring: a ball and a
// grain meeting at 45 degrees turned their contact points back 1.3x as fast as in LAMMPS, and a
// shear cell of 0.125 d powder came out 10-17% less frictional than LAMMPS's on the same state
// (docs/cell_validation.md, "Oblique collisions").
//
// The energy books of a step: the normal dashpot C_n v_n^2 dt, the tangential dashpot
// C_t |v_t|^2 dt while the contact sticks, and friction the rest of the tangential work the
// contact absorbs, -F_t . v_t dt, less what its spring stores more than before. The kinetic
// energy changes by each step's force times the velocity at the step (velocity Verlet), the spring
// by its force over each step's displacement, half a step later; the two agree over a run of
// sticking steps but not at its ends, where a contact starts or stops sliding with a finite
// spring force. Booking friction as the rest puts that half step in the books; until 6 December
// 2026 friction was booked in sliding steps only, and the energy balance of a sheared cell at I =
// 0.3 missed a part of first order in the time step, +0.5% of the work at 40 steps per collision
// (campaigns/README.md). In a sticking step friction's share is small and of either sign; over a
// contact it sums to what the slips' edges and the parting take.
#include <cmath>
#include <type_traits>
#include <utility>

#include "dem/material.hpp"
#include "dem/vec.hpp"

namespace millflow::dem {

// The law is written once for one contact and for four in the lanes of AVX2 registers. Its
// vectors are of a type V: Vec3, the pair pass's PackedVec3 (one contact, dem/packed_vec3.hpp) or
// Vec3Lanes (four, dem/contact_lanes.hpp), whose operations give Vec3's bits, element by element.
// V::Scalar is double or Lanes4, and a condition on it a bool or a mask of lanes: the law's
// branches are selections, and its slow paths run when any() lane needs them.
template <class V>
using LawScalar = typename V::Scalar;
template <class V>
using LawMask = decltype(std::declval<LawScalar<V>>() < std::declval<LawScalar<V>>());

inline bool any(bool condition) {
  return condition;
}
template <class T>
[[gnu::always_inline]] inline T select(bool condition, const T& if_true, const T& if_false) {
  return condition ? if_true : if_false;
}

template <class V>
struct ContactGeometryOf {
  V normal;                                  // unit, from body b towards body a
  LawScalar<V> overlap = LawScalar<V>(0.0);  // > 0 while touching, m
  // Velocity of a's contact point minus b's, m/s, at the end of the step: the dashpots act on it.
  V relative_velocity;
  // The same over the step (the half-step velocities that moved the bodies): the contact points'
  // relative displacement in the step over dt, which the tangential spring follows, as the overlap
  // follows the positions. A spring advanced by the end-of-step velocity instead (millflow until 6
  // December 2026) gave a sticking oblique grain-ball collision at a cell's 113 steps per contact
  // a tangential rebound 11% short of the converged law, where LAMMPS's, which advances its spring
  // by the half-step velocity, was 1.5% short (docs/cell_validation.md, "The tangential spring's
  // increment").
  V step_velocity;
};
using ContactGeometry = ContactGeometryOf<Vec3>;

template <class V>
struct ContactResponseOf {
  using S = LawScalar<V>;
  V force_on_a = V::Zero();  // body b gets the opposite force
  V spring = V::Zero();      // updated tangential spring s, m
  S normal_force = S(0.0);   // signed magnitude along the normal, N
  LawMask<V> sliding{};
  // Energy dissipated during this step, J. The dashpots' >= 0. Friction's is the tangential work
  // the contact absorbs less the change of its spring energy and the tangential dashpot's share
  // (above): it can be negative, in a sticking step, or in a sliding one where the tangential
  // dashpot alone exceeds the Coulomb limit (an oblique impact's first steps, an unloading
  // contact's tail), as the spring is then reset to the limit force less the dashpot's, which may
  // point back; that energy is given back or dissipated later (a spring left when a contact ends
  // counts as friction).
  S dissipated_normal = S(0.0);
  S dissipated_tangential = S(0.0);
  S dissipated_friction = S(0.0);
  S elastic_energy = S(0.0);  // stored in both springs after the step, J
};
using ContactResponse = ContactResponseOf<Vec3>;

// Both functions are inline: they run for every contact and step, and the caller uses only part
// of the response (the compiler drops the rest).

// Below this turn c = (s.n)^2 / |s|^2 the rescale comes from a series; the first term it drops,
// 35 c^4 / 128, is under 3e-17 there, a quarter of a double's last place. In the benches' dense
// cells and mills c stays below 1e-5 per step, most contacts between 1e-12 and 1e-8.
inline constexpr double kSpringTurnSeriesLimit = 1e-4;

// Rotates a stored tangential spring into the plane normal to `normal`, keeping its length, so a
// contact that rolls around a particle keeps its stored energy without gaining any. The
// projection has length |s| sqrt(1 - c), so the rescale is (1 - c)^(-1/2): for the small turns of
// a step the series 1 + c/2 + 3c^2/8 + 5c^3/16, whose one division (by |s|^2) does not wait for
// the normal, instead of a division and a square root in a row on every contact's path to its
// force (docs/benchmarks.md, "The spring's turn by a series"). A spring of length 0 stays 0.
template <class V>
[[gnu::always_inline]] inline V rotate_spring_into_tangent_plane(
    const V& spring, const std::type_identity_t<V>& normal) {
  using S = LawScalar<V>;
  using std::sqrt;
  const S length_sq = spring.squaredNorm();
  const S along = spring.dot(normal);
  const V projected = spring - along * normal;
  const S turn = along * along / length_sq;  // NaN for a spring of length 0, not used then
  V turned = projected * (1.0 + turn * (0.5 + turn * (0.375 + turn * 0.3125)));
  const LawMask<V> beyond_series = !((turn < kSpringTurnSeriesLimit) | (length_sq == 0.0));
  if (any(beyond_series)) {
    const S projected_sq = projected.squaredNorm();
    turned = select(
        beyond_series,
        select(projected_sq == 0.0, V(V::Zero()), V(projected * sqrt(length_sq / projected_sq))),
        turned);
  }
  return select(length_sq == 0.0, spring, turned);
}

// One step of the linear spring-dashpot law with Coulomb friction, given the normal dashpot's
// coefficient C_n (normal_damping_coefficient of the pair's effective mass: a contact works it
// out once, at first touch, instead of a square root and a division every step). Params: a
// PairParams, or for four contacts in lanes the same fields as Lanes4.
template <class V, class Params>
[[gnu::always_inline]] inline ContactResponseOf<V> linear_spring_dashpot_damped(
    const Params& params, const std::type_identity_t<LawScalar<V>>& damping_n,
    const ContactGeometryOf<V>& geometry, const std::type_identity_t<V>& spring, double dt) {
  using S = LawScalar<V>;
  using std::abs;
  using std::sqrt;
  ContactResponseOf<V> out;
  const V& n = geometry.normal;
  const S damping_t = params.tangential_damping_ratio * damping_n;

  const S v_n = geometry.relative_velocity.dot(n);
  out.normal_force = params.normal_stiffness * geometry.overlap - damping_n * v_n;
  out.dissipated_normal = damping_n * v_n * v_n * dt;

  const V v_t = geometry.relative_velocity - v_n * n;
  const V slip = (geometry.step_velocity - geometry.step_velocity.dot(n) * n) * dt;
  const V turned_spring = rotate_spring_into_tangent_plane(spring, n);
  const V trial_spring = turned_spring + slip;
  const V trial_force = -params.tangential_stiffness * trial_spring - damping_t * v_t;
  const S limit = params.friction * abs(out.normal_force);
  const S trial_sq = trial_force.squaredNorm();

  out.sliding = trial_sq > limit * limit;
  V tangential_force = trial_force;
  out.spring = trial_spring;
  out.dissipated_tangential = select(out.sliding, S(0.0), S(damping_t * v_t.squaredNorm() * dt));
  if (any(out.sliding)) {
    // Sliding: the force sits on the Coulomb limit, and the spring is reset so that spring and
    // dashpot together give it, F_t = -(k_t s + C_t v_t), as LAMMPS and MercuryDPM reset theirs.
    // A contact that cannot hold a tangential force keeps no spring.
    const V on_limit = trial_force * (limit / sqrt(trial_sq));
    tangential_force = select(out.sliding, on_limit, trial_force);
    out.spring =
        select(out.sliding,
               select(limit > 0.0, V(-(on_limit + damping_t * v_t) / params.tangential_stiffness),
                      V(V::Zero())),
               trial_spring);
  }
  // The tangential books of every step, sliding or not: the work the contact absorbs, less what
  // its spring stores more than before and what its dashpot took, is friction's.
  out.dissipated_friction =
      -tangential_force.dot(v_t) * dt -
      0.5 * params.tangential_stiffness * (out.spring.squaredNorm() - turned_spring.squaredNorm()) -
      out.dissipated_tangential;
  out.force_on_a = out.normal_force * n + tangential_force;
  out.elastic_energy = 0.5 * params.normal_stiffness * geometry.overlap * geometry.overlap +
                       0.5 * params.tangential_stiffness * out.spring.squaredNorm();
  return out;
}

// The same with C_n worked out from the pair's effective mass.
template <class V>
[[gnu::always_inline]] inline ContactResponseOf<V> linear_spring_dashpot(
    const PairParams& params, double effective_mass, const ContactGeometryOf<V>& geometry,
    const std::type_identity_t<V>& spring, double dt) {
  return linear_spring_dashpot_damped(
      params,
      normal_damping_coefficient(params.normal_stiffness, effective_mass, params.damping_ratio),
      geometry, spring, dt);
}

}  // namespace millflow::dem
