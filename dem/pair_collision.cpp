#include "dem/pair_collision.hpp"

#include <stdexcept>

#include "dem/system.hpp"

namespace millflow::dem {

Rebound pair_rebound(const MaterialTable& materials, const PairCollision& c) {
  const double ra = c.radius_a, rb = c.radius_b;
  Domain box;
  box.lo = Vec3::Constant(-2.0 * (ra + rb));
  box.hi = Vec3::Constant(2.0 * (ra + rb));
  System pair(materials, box, Vec3::Zero());
  pair.add_particle({.velocity = Vec3(0.5, -0.5 * c.tangential_speed, 0),
                     .radius = ra,
                     .material = c.material_a});
  pair.add_particle({.position = Vec3(ra + rb, 0, 0),
                     .velocity = Vec3(-0.5, 0.5 * c.tangential_speed, 0),
                     .radius = rb,
                     .material = c.material_b});
  pair.set_time_step(c.time_step);
  do {
    pair.step();
  } while (pair.active_contact_count() > 0 && pair.step_count() < 1000000);
  if (pair.active_contact_count() > 0)
    throw std::runtime_error("pair_rebound: the contact did not end within a million steps");
  const auto v = pair.velocities();
  const auto w = pair.angular_velocities();
  // Contact points: +ra x on a, -rb x on b; (w x r)_y = w_z r_x.
  const double across = (v[1].y() - rb * w[1].z()) - (v[0].y() + ra * w[0].z());
  return {.normal = v[1].x() - v[0].x(),
          .tangential = c.tangential_speed > 0.0 ? across / c.tangential_speed : 0.0};
}

}  // namespace millflow::dem
