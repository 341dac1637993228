#pragma once
// Coarse-grained continuum fields of the ball flow in a mill slice (Goldhirsch 2010; Weinhart et
// al. 2012), averaged over the slice length (z) and over all flow-sample frames, on a grid over
// the cross-section.
//
// Kernel. A Gaussian in the x-y plane of standard deviation w (the kernel width), truncated at
// 3w, and normalised per point over the cells inside the mill as the grid samples it:
//     W_c(x) = phi(|x_c - x|) / (A * sum_{c' inside the mill} phi(|x_c' - x|)),   A = cell area,
// so sum_c W_c(x) A = 1 for every point: the coarse-graining conserves mass, momentum and the
// stress virial exactly, and none of it lands outside the shell (the kernel of a ball next to the
// shell is folded back inside, the usual boundary correction). Dividing by the slice length L
// turns it into a density per unit volume averaged over z. The kernel must reach a cell centre
// from any point: w >= half the cell size (std::invalid_argument otherwise).
//
// Fields (SI units; tensors with tension positive, the continuum convention):
//   density rho = sum_p m_p W / L and solid fraction nu = sum_p V_p W / L (V_p = 4/3 pi r^3);
//   velocity V = momentum / rho, where nu reaches `min_solid_fraction_for_velocity` (else 0);
//   kinetic stress sigma_k = -sum_p m_p v'_p (x) v'_p W / L, with v'_p = v_p - V(x_p) the velocity
//     relative to the time-mean field at the particle (V(x_p) is the kernel-weighted mean of the
//     cells' V around x_p; a second pass over the frames, since the mean is needed first);
//   contact stress sigma_c = sum_contacts f_a (x) b_ab * (line kernel along b_ab) / L, with f_a the
//     force on particle a and b_ab the branch from a's centre to b's centre (to the contact point
//     for a wall contact); the line integral of W along the branch is the midpoint rule on
//     ceil(|b_xy| / (w/2)) pieces;
//   stress sigma = sigma_k + sigma_c; pressure p = -tr(sigma)/3 (compressive positive);
//   velocity gradient L_ab = dV_a/dx_b (b in x, y; the z derivatives vanish after averaging over
//     z) by central differences between cells where V is defined, one-sided at the edge of the
//     flow; strain rate D = (L + L^T)/2; shear rate gdot = sqrt(2 D':D') with D' = D - tr(D)/3 I,
//     which is gdot for a simple shear u = gdot y;
//   normal stress on the shear plane: of the two in-plane planes of maximum shear rate (normals
//     (e1 +- e2)/sqrt(2), e1, e2 the in-plane principal directions of D), the one whose normal n
//     is most nearly the velocity-gradient direction (larger |L n|: for layered flow, the plane of
//     the layers); sigma_n = -n.sigma.n (compressive positive). Where D vanishes the choice is
//     arbitrary and sigma_n lies between the in-plane principal stresses;
//   shear stress on the same plane: tau = |t.sigma.n|, t the in-plane unit vector normal to n
//     (what a simple-shear cell with layers along the plane measures as its shear stress);
//   granular temperature T = -tr(sigma_k) / (3 rho) (m^2/s^2);
//   collision frequency = sum_events W / (L * event_window) (collisions per m^3 per s) and
//     dissipation power density = sum_events E_dissipated W / (L * event_window) (W/m^3), in total
//     and per contact category, at the events' last contact points.
//
// Determinism: frames are summed in segment order, each segment's frames in their order; up to
// kParallelSegments segments are read and summed at once into their own sums, which are then added
// in segment order. The bits do not depend on the thread count.
#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "dem/flow_sample.hpp"
#include "method/cross_section_grid.hpp"

namespace millflow::method {

inline constexpr std::size_t kParallelSegments = 4;

struct ShearPlaneTraction {
  double normal = 0.0;  // -n.sigma.n, compressive positive
  double shear = 0.0;   // |t.sigma.n|
};

// The traction on the shear plane (the plane of maximum shear rate nearest the flow's layers,
// above) of a cell with velocity gradient L, strain rate D and stress sigma.
ShearPlaneTraction shear_plane_traction(const Eigen::Matrix3d& gradient,
                                        const Eigen::Matrix3d& strain_rate,
                                        const Eigen::Matrix3d& stress);

struct CoarseGrainSettings {
  CrossSectionGrid grid;                // half_width: the mill's inner radius
  double slice_length = 0.0;            // L, m
  double kernel_width = 0.0;            // w, m
  double media_density = 0.0;           // kg/m^3, of every particle
  double event_window = 0.0;            // s: the time the frames' collision events span together
  std::vector<std::string> categories;  // contact category names, by the index events carry
  double min_solid_fraction_for_velocity = 0.01;

  // Throws std::invalid_argument naming the bad value.
  void validate() const;
};

using Tensor3 = Eigen::Matrix3d;

struct CoarseFields {
  CrossSectionGrid grid;
  double slice_length = 0.0;
  std::size_t frame_count = 0;
  double media_volume = 0.0;  // mean over frames of the particles' volume, m^3
  std::vector<std::string> categories;

  std::vector<double> solid_fraction, density;
  std::vector<Eigen::Vector3d> velocity;
  std::vector<Tensor3> kinetic_stress, contact_stress, stress;
  std::vector<Tensor3> velocity_gradient, strain_rate;
  std::vector<double> shear_rate, pressure, shear_plane_normal_stress, shear_plane_shear_stress,
      granular_temperature;
  std::vector<double> collision_frequency, dissipation;
  std::vector<std::vector<double>> collision_frequency_by_category, dissipation_by_category;

  // The integral of the solid fraction over the cross-section times L, m^3.
  double solid_volume() const;
  // The integral of a per-cell density over the cross-section times L.
  double integral(const std::vector<double>& per_cell) const;
};

// Loads the frames of segment `index` (0-based); called once per segment in each of two passes,
// possibly from several threads at once.
using SegmentLoader = std::function<std::vector<dem::FlowFrame>(std::size_t index)>;

// Throws std::invalid_argument for bad settings, no frames, a particle outside the mill or an
// event category with no name.
CoarseFields coarse_grain(const CoarseGrainSettings& settings, std::size_t segment_count,
                          const SegmentLoader& load);

// The fields as named cell arrays: scalars, vectors (3) and tensors (9, row-major), for VTK and
// JSON. Names: solid_fraction, density_kg_m3, velocity_m_s, kinetic_stress_pa, contact_stress_pa,
// stress_pa, strain_rate_per_s, shear_rate_per_s, pressure_pa, normal_stress_pa,
// granular_temperature_m2_s2, collision_frequency_per_m3_s, dissipation_w_m3, and per category
// collision_frequency_per_m3_s.<name>, dissipation_w_m3.<name>.
std::vector<CellArray> cell_arrays(const CoarseFields& fields);

}  // namespace millflow::method
