#pragma once
// The shear cell's stiffness policy: how stiff each pair's contacts must be for the particles to
// stay rigid at the cell's own normal stress and shear rate (docs/shear_cells.md).
//
// A contact of the smaller diameter d_s overlaps by delta = F / k_n under a force F. In a dense bed
// sheared between balls every contact, powder too, carries a ball-scale force, because powder
// caught between two balls passes on what the balls press with:
//   static   F_s = sigma_n d_m^2               (the mean contact force of a bed of balls of
//                                               diameter d_m under sigma_n, to within its
//                                               coordination number x solid fraction ~ 3 / pi)
//   impact   delta = v sqrt(m_eff / k_n),  v = gdot d_m (the velocity fluctuation of dense flow)
// The policy asks each pair for a mean overlap of at most f d_s (f = mean_fraction):
//   k_static    = S F_s / (f d_s)
//   k_impact    = m_eff (v / (f d_s))^2
//   k_n         = max(k_given, k_static, k_impact)
// with the safety factor S = kOverlapSafety on the static force (force chains carry several
// times the mean; tests/dem/test_physics_shear_cell_policy.cpp measures the result: mean 0.3% and
// p95 1% of d_s against bounds of 1% and 3%), none on the impact speed (gdot d_m is already above
// the velocity fluctuation of dense flow, ~0.1-0.5 gdot d_m at I ~ 0.1). The stiffness the campaign
// gave is a floor: the policy never softens a pair. The dimensionless stiffness reported beside
// each pair is kappa = k_n / (sigma_n d_s).
#include <string>
#include <vector>

#include "dem/shear_cell.hpp"

namespace millflow::dem {

inline constexpr double kOverlapSafety = 2.0;

// What the policy derived for one pair.
struct PairStiffness {
  std::string pair;               // contact type name, "media-powder" ...
  double smaller_diameter = 0.0;  // d_s, m
  double given = 0.0;             // k_n the campaign gave, N/m
  double static_bound = 0.0;      // k_static, N/m
  double impact_bound = 0.0;      // k_impact, N/m
  double chosen = 0.0;            // k_n used, N/m
  double kappa = 0.0;             // chosen / (sigma_n d_s)
};

// Raises each pair's normal stiffness in `setup` to the overlap bound of setup.overlap_bound
// (mean fraction) and returns what it derived, media-media, media-powder, powder-powder.
std::vector<PairStiffness> apply_overlap_bound(ShearCellSetup& setup);

// The same figures without changing anything (the stiffness as given is `chosen`).
std::vector<PairStiffness> describe_stiffness(const ShearCellSetup& setup);

}  // namespace millflow::dem
