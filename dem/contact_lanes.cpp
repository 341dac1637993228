#include "dem/contact_lanes.hpp"

#include <stdexcept>

namespace millflow::dem {

#if defined(__AVX2__)

namespace {

Vec3Lanes gathered(const std::array<Vec3, 4>& v) {
  return Vec3Lanes::gather(v[0], v[1], v[2], v[3]);
}

std::array<Vec3, 4> scattered(const Vec3Lanes& v) {
  std::array<Vec3, 4> out;
  v.scatter(out[0], out[1], out[2], out[3]);
  return out;
}

// Lanes of four contacts' inputs, field by field.
template <class Field>
std::array<Vec3, 4> each(const std::array<ContactLawInputs, 4>& four, Field field) {
  return {field(four[0]), field(four[1]), field(four[2]), field(four[3])};
}
template <class Field>
Lanes4 lanes_of(const std::array<ContactLawInputs, 4>& four, Field field) {
  return Lanes4::of(field(four[0]), field(four[1]), field(four[2]), field(four[3]));
}

}  // namespace

bool contact_lanes_available() {
  return true;
}

std::array<ContactVec3Operations, 4> operations_in_lanes(const std::array<Vec3, 4>& a,
                                                         const std::array<Vec3, 4>& b,
                                                         const std::array<double, 4>& s) {
  const Vec3Lanes la = gathered(a), lb = gathered(b);
  const Lanes4 ls = Lanes4::of(s[0], s[1], s[2], s[3]);
  const std::array<Vec3, 4> sum = scattered(la + lb), difference = scattered(la - lb),
                            negated = scattered(-la), scaled_before = scattered(ls * la),
                            scaled_after = scattered(la * ls), divided = scattered(la / ls),
                            cross = scattered(la.cross(lb));
  const std::array<double, 4> dot = la.dot(lb).values(), squared_norm = la.squaredNorm().values();
  std::array<ContactVec3Operations, 4> out;
  for (std::size_t l = 0; l < 4; ++l) {
    out[l] = {sum[l],     difference[l], negated[l], scaled_before[l], scaled_after[l],
              divided[l], cross[l],      dot[l],     squared_norm[l]};
  }
  return out;
}

std::array<ContactResponse, 4> contact_law_in_lanes(const std::array<ContactLawInputs, 4>& four,
                                                    double dt) {
  const ContactGeometryOf<Vec3Lanes> geometry{
      gathered(each(four, [](const auto& c) { return c.geometry.normal; })),
      lanes_of(four, [](const auto& c) { return c.geometry.overlap; }),
      gathered(each(four, [](const auto& c) { return c.geometry.relative_velocity; })),
      gathered(each(four, [](const auto& c) { return c.geometry.step_velocity; }))};
  const ContactResponseOf<Vec3Lanes> response = linear_spring_dashpot_damped(
      gather_pair_params(four[0].params, four[1].params, four[2].params, four[3].params),
      lanes_of(four, [](const auto& c) { return c.damping_n; }), geometry,
      gathered(each(four, [](const auto& c) { return c.spring; })), dt);
  const std::array<Vec3, 4> force = scattered(response.force_on_a),
                            spring = scattered(response.spring);
  const int sliding = response.sliding.lanes();
  const std::array<double, 4> normal_force = response.normal_force.values(),
                              dissipated_normal = response.dissipated_normal.values(),
                              dissipated_tangential = response.dissipated_tangential.values(),
                              dissipated_friction = response.dissipated_friction.values(),
                              elastic_energy = response.elastic_energy.values();
  std::array<ContactResponse, 4> out;
  for (std::size_t l = 0; l < 4; ++l) {
    out[l].force_on_a = force[l];
    out[l].spring = spring[l];
    out[l].normal_force = normal_force[l];
    out[l].sliding = (sliding >> l & 1) != 0;
    out[l].dissipated_normal = dissipated_normal[l];
    out[l].dissipated_tangential = dissipated_tangential[l];
    out[l].dissipated_friction = dissipated_friction[l];
    out[l].elastic_energy = elastic_energy[l];
  }
  return out;
}

#else

bool contact_lanes_available() {
  return false;
}

std::array<ContactVec3Operations, 4> operations_in_lanes(const std::array<Vec3, 4>&,
                                                         const std::array<Vec3, 4>&,
                                                         const std::array<double, 4>&) {
  throw std::logic_error("operations_in_lanes: this build has no AVX2 lanes");
}

std::array<ContactResponse, 4> contact_law_in_lanes(const std::array<ContactLawInputs, 4>&,
                                                    double) {
  throw std::logic_error("contact_law_in_lanes: this build has no AVX2 lanes");
}

#endif

}  // namespace millflow::dem
