#include "dem/contact_law.hpp"

#include <cmath>

namespace millflow::dem {

Vec3 rotate_spring_into_tangent_plane(const Vec3& spring, const Vec3& normal) {
  const double length_sq = spring.squaredNorm();
  if (length_sq == 0.0) return spring;
  const Vec3 projected = spring - spring.dot(normal) * normal;
  const double projected_sq = projected.squaredNorm();
  if (projected_sq == 0.0) return Vec3::Zero();
  return projected * std::sqrt(length_sq / projected_sq);
}

ContactResponse linear_spring_dashpot(const PairParams& params, double effective_mass,
                                      const ContactGeometry& geometry, const Vec3& spring,
                                      double dt) {
  ContactResponse out;
  const Vec3& n = geometry.normal;
  const double damping_n =
      normal_damping_coefficient(params.normal_stiffness, effective_mass, params.damping_ratio);
  const double damping_t = params.tangential_damping_ratio * damping_n;

  const double v_n = geometry.relative_velocity.dot(n);
  out.normal_force = params.normal_stiffness * geometry.overlap - damping_n * v_n;
  out.dissipated_normal = damping_n * v_n * v_n * dt;

  const Vec3 v_t = geometry.relative_velocity - v_n * n;
  const Vec3 trial_spring = rotate_spring_into_tangent_plane(spring, n) + v_t * dt;
  const Vec3 trial_force = -params.tangential_stiffness * trial_spring - damping_t * v_t;
  const double limit = params.friction * std::max(out.normal_force, 0.0);
  const double trial_sq = trial_force.squaredNorm();

  Vec3 tangential_force;
  if (trial_sq > limit * limit) {
    // Sliding: the force sits on the Coulomb limit and the spring holds exactly that force;
    // the spring energy cut away is what friction dissipated.
    out.sliding = true;
    tangential_force = trial_force * (limit / std::sqrt(trial_sq));
    out.spring = -tangential_force / params.tangential_stiffness;
    // Work the sliding contact absorbs minus what its spring now stores more than before.
    const Vec3 old_spring = trial_spring - v_t * dt;
    out.dissipated_friction =
        -tangential_force.dot(v_t) * dt -
        0.5 * params.tangential_stiffness * (out.spring.squaredNorm() - old_spring.squaredNorm());
  } else {
    tangential_force = trial_force;
    out.spring = trial_spring;
    out.dissipated_tangential = damping_t * v_t.squaredNorm() * dt;
  }
  out.force_on_a = out.normal_force * n + tangential_force;
  out.elastic_energy = 0.5 * params.normal_stiffness * geometry.overlap * geometry.overlap +
                       0.5 * params.tangential_stiffness * out.spring.squaredNorm();
  return out;
}

}  // namespace millflow::dem
