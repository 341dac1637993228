#pragma once
// The shear cell's stiffness policy: how stiff each pair's contacts must be for the particles to
// stay rigid at the cell's own normal stress and shear rate (docs/shear_cells.md).
//
// A contact of the smaller diameter d_s overlaps by delta = F / k_n under a force F. In a dense bed
// sheared between balls every contact, powder too, carries a ball-scale force, because powder
// caught between two balls passes on what the balls press with. Two criteria, the larger wins:
//
//   static  the mean contact force of a bed of balls of diameter d_m under sigma_n, F_s =
//           sigma_n d_m^2 (to within its coordination number x solid fraction ~ 3 / pi), times
//           the safety factor S = kOverlapSafety (force chains carry several times the mean),
//           for a mean overlap of at most f d_s (f = mean_fraction):
//             k_static = S F_s / (f d_s)
//   impact  the tail: two balls colliding at the relative normal speed v = c gdot d_m
//           (c = kImpactSpeedFactor) with a grain caught between them. The balls' pair mass
//           m_mm = m_m / 2 compresses the n contacts in series between them (n = 1 for a
//           ball-ball contact, 2 for a grain between balls), each by delta = v sqrt(m_mm / (n k));
//           for the 95th percentile overlap to stay within q d_s (q = p95_fraction):
//             k_impact = m_mm (v / (q d_s))^2 / n
//           A powder-powder contact is not on a ball-ball line at low load, and at high load the
//           grains between two balls share the impact among many contacts (measured: powder-powder
//           p95 0.1% of d_s where ball-powder reaches 4%), so it takes its own pair mass, n = 1.
//
//   rigidity  (media-media only, when media_rigidity > 0) the balls' own k_n / (sigma_n d_m)
//           at least kappa_m = media_rigidity:
//             k_rigid = kappa_m sigma_n d_m
//           Opt-in, not a default: one run per cell found the friction of a cell with powder
//           rising with the ball-ball stiffness above the overlap bounds (tau / p +3.7% from
//           kappa 1.16e4 to 4.6e4), a second seed found it falling (-1.5 to -2.1%), so whether
//           the balls' stiffness moves it is not settled (docs/cell_validation.md, table 1).
//
//   k_n = max(k_given, k_static, k_impact, k_rigid)
//
// Why the impact criterion uses the balls' mass and not the grain's: a grain hit by one free ball
// is stopped by its own tiny mass, but a grain between two colliding balls has to stop the balls.
// At low powder load single grains sit at most ball-ball contacts, and with the static criterion
// alone the ball-powder overlaps' p95 measured 4.3% of d_s at load 0.05 and 3.2% at load 0.3
// against a bound of 3% (docs/cell_validation.md, table 5); raising k_n shrank them as k_n^-0.55,
// an impact's k_n^-1/2 rather than a static force's k_n^-1. Those tails give c ~ 1.9; c = 2.5
// holds the bound with a margin for the cells' scatter with restitution and friction (p95
// 2.4-3.3% at c = 2 over seeds and e = 0.3-0.5, mu = 0.5-0.75; 2.2% at c = 2.5). The stiffness the
// campaign gave is a floor: the policy never softens a pair. The dimensionless stiffness reported
// beside each pair is kappa = k_n / (sigma_n d_s).
#include <string>
#include <vector>

#include "dem/shear_cell.hpp"

namespace millflow::dem {

inline constexpr double kOverlapSafety = 2.0;
// The balls' relative normal speed at impact the tail is sized for, in units of gdot d_m (the
// measured 95th percentile ~1.9, with a margin).
inline constexpr double kImpactSpeedFactor = 2.5;

// What the policy derived for one pair.
struct PairStiffness {
  std::string pair;               // contact type name, "media-powder" ...
  double smaller_diameter = 0.0;  // d_s, m
  double given = 0.0;             // k_n the campaign gave, N/m
  double static_bound = 0.0;      // k_static, N/m
  double impact_bound = 0.0;      // k_impact, N/m
  double rigidity_bound = 0.0;    // k_rigid, N/m (0 for the pairs with powder, or when off)
  double chosen = 0.0;            // k_n used, N/m
  double kappa = 0.0;             // chosen / (sigma_n d_s)
  std::string governing;          // which is chosen: "given", "static", "impact", "rigidity"
};

// Raises each pair's normal stiffness in `setup` to the overlap bounds of setup.overlap_bound
// and returns what it derived, media-media, media-powder, powder-powder.
std::vector<PairStiffness> apply_overlap_bound(ShearCellSetup& setup);

// The same figures without changing anything (the stiffness as given is `chosen`).
std::vector<PairStiffness> describe_stiffness(const ShearCellSetup& setup);

}  // namespace millflow::dem
