#include "dem/packed_vec3.hpp"

#include <type_traits>

namespace millflow::dem {
namespace {

Vec3 stored(const ContactVec3& a) {
  Vec3 out;
  store_contact_vec3(out, a);
  return out;
}

}  // namespace

bool contact_vec3_is_packed() {
  return !std::is_same_v<ContactVec3, Vec3>;
}

ContactVec3Operations contact_vec3_operations(const Vec3& a, const Vec3& b, double s) {
  const ContactVec3 pa = load_contact_vec3(a), pb = load_contact_vec3(b);
  return {.sum = stored(pa + pb),
          .difference = stored(pa - pb),
          .negated = stored(-pa),
          .scaled_before = stored(s * pa),
          .scaled_after = stored(pa * s),
          .divided = stored(pa / s),
          .cross = stored(pa.cross(pb)),
          .dot = pa.dot(pb),
          .squared_norm = pa.squaredNorm()};
}

ContactResponse contact_law_on_contact_vec3(const PairParams& params, double damping_n,
                                            const ContactGeometry& geometry, const Vec3& spring,
                                            double dt) {
  const ContactGeometryOf<ContactVec3> packed{load_contact_vec3(geometry.normal), geometry.overlap,
                                              load_contact_vec3(geometry.relative_velocity),
                                              load_contact_vec3(geometry.step_velocity)};
  const ContactResponseOf<ContactVec3> response =
      linear_spring_dashpot_damped(params, damping_n, packed, load_contact_vec3(spring), dt);
  ContactResponse out;
  out.force_on_a = stored(response.force_on_a);
  out.spring = stored(response.spring);
  out.normal_force = response.normal_force;
  out.sliding = response.sliding;
  out.dissipated_normal = response.dissipated_normal;
  out.dissipated_tangential = response.dissipated_tangential;
  out.dissipated_friction = response.dissipated_friction;
  out.elastic_energy = response.elastic_energy;
  return out;
}

}  // namespace millflow::dem
