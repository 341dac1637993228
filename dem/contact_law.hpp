#pragma once
// The contact law of the paper (Cleary, eq. 1-2) as pure functions, free of any state.
//
//   F_n = k_n dx - C_n v_n                      (along the normal, on body a)
//   F_t = -(k_t s + C_t v_t), |F_t| <= mu F_n    (s: incremental tangential spring, sum of v_t dt)
//
// The caller keeps the spring s per contact (the contact-history store) and passes it in; the
// function returns the updated spring. When the Coulomb limit is reached the spring is truncated
// to mu F_n / k_t, so sliding dissipates energy instead of storing it. Friction dissipation is
// the work the sliding contact absorbs, -F_t . v_t dt, less the change of its spring energy.
// The normal force is not clipped at zero as the pair separates: the contact ends when the overlap
// returns to zero, which makes the measured restitution equal the analytic e of the pair.
#include "dem/material.hpp"
#include "dem/vec.hpp"

namespace millflow::dem {

struct ContactGeometry {
  Vec3 normal;             // unit, from body b towards body a
  double overlap = 0.0;    // > 0 while touching, m
  Vec3 relative_velocity;  // velocity of a's contact point minus b's, m/s
};

struct ContactResponse {
  Vec3 force_on_a = Vec3::Zero();  // body b gets the opposite force
  Vec3 spring = Vec3::Zero();      // updated tangential spring s, m
  double normal_force = 0.0;       // signed magnitude along the normal, N
  bool sliding = false;
  // Energy dissipated during this step, J (>= 0 up to O(dt^2) while a sliding contact turns).
  double dissipated_normal = 0.0;
  double dissipated_tangential = 0.0;
  double dissipated_friction = 0.0;
  double elastic_energy = 0.0;  // stored in both springs after the step, J
};

// Rotates a stored tangential spring into the plane normal to `normal`, keeping its length, so a
// contact that rolls around a particle keeps its stored energy without gaining any.
Vec3 rotate_spring_into_tangent_plane(const Vec3& spring, const Vec3& normal);

// One step of the linear spring-dashpot law with Coulomb friction.
ContactResponse linear_spring_dashpot(const PairParams& params, double effective_mass,
                                      const ContactGeometry& geometry, const Vec3& spring,
                                      double dt);

}  // namespace millflow::dem
