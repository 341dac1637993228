#pragma once
// Visits the candidate pairs of a system that touch, with the force on the first particle and the
// minimum-image vector from it to the second: the one loop behind the shear cell's contact sums
// (virial, stress tensor, overlaps).
#include <cstddef>

#include "dem/system.hpp"

namespace millflow::dem {

// visit(k, force, branch) for every touching candidate pair k.
template <class Visit>
void for_each_touching_pair(const System& system, Visit&& visit) {
  const auto pairs = system.candidate_pairs();
  const auto x = system.positions();
  const PeriodicImages images(system.domain());  // once per pass, not per pair
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    if (!system.pair_touching(k)) continue;
    visit(k, system.pair_force(k), images.separation(x[pairs[k].i], x[pairs[k].j]));
  }
}

}  // namespace millflow::dem
