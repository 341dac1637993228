#pragma once
// The pair contacts in force of a system split by contact category (System::pair_category): which
// pairs of materials carry the stress (media-media, media-powder, powder-powder).
#include <algorithm>
#include <cstddef>
#include <vector>

#include "dem/system.hpp"
#include "dem/touching_pairs.hpp"

namespace millflow::dem {

// The pair contacts in force of one category, summed.
struct CategoryContacts {
  std::size_t contacts = 0;
  // Sum of F b^T as in System::contact_virial(): -V sigma of these contacts alone.
  Eigen::Matrix3d virial = Eigen::Matrix3d::Zero();
  double overlap_fraction = 0.0;  // sum of overlap / smaller diameter
};

// Per pair category (index System::pair_category(a, b); the entries of material pairs written in
// the other order stay empty), the contacts in force now. Their virials add up to
// System::contact_virial() (to rounding: another order of summation).
inline std::vector<CategoryContacts> contacts_by_category(const System& system) {
  const std::size_t materials = system.materials().size();
  std::vector<CategoryContacts> sums(materials * materials);
  const auto pairs = system.candidate_pairs();
  const auto r = system.radii();
  const auto material = system.particle_materials();
  for_each_touching_pair(system, [&](std::size_t k, const Vec3& force, const Vec3& branch) {
    const auto [i, j] = pairs[k];
    CategoryContacts& c = sums[system.pair_category(material[i], material[j])];
    c.contacts += 1;
    c.virial += force * branch.transpose();
    c.overlap_fraction += (r[i] + r[j] - branch.norm()) / (2.0 * std::min(r[i], r[j]));
  });
  return sums;
}

}  // namespace millflow::dem
