#pragma once
// A shear cell's result (docs/method.md, step 3): what the `shear_cell` task kind stores
// (tasks/shear_cell.hpp runs the cell) and the upscaling reads. to_json and from_json below are
// the one spelling of its keys; cell_result() copies a dem::ShearCellMeasurements into it (that
// type says how each quantity is measured, docs/shear_cells.md gives the rules).
//
// Result JSON (versioned by the kind's kShearCellVersion, tasks/shear_cell.hpp), SI units. A cell
// that did not run: {skipped: reason, slot, powder_load}. A cell that ran: site (the sites task's
// entry), slot, powder_load, media_count, powder_count, wall_ball_count, stiffness {by pair:
// k_n_n_m, kappa, given_n_m, static_bound_n_m, impact_bound_n_m, governing (from kind version
// 7)}, strain, duration_s, steps,
// *_shear_rate_per_s (target, bulk, nominal), wall_speed_m_s, wall_slip_m_s, gap_m, volume_m3,
// shear_stress_pa, normal_stress_pa, friction (tau / p_yy), friction_mean_pressure (tau / p),
// stresses {xx, yy, zz, xy, xz, yz, mean_pressure_pa, p_yy_pa} (compression positive),
// inertial_number (imposed rate in LE), inertial_number_measured_rate, media/powder/total
// solid_fraction, power_density_w_m3, dissipation_w_m3 {by contact type, total},
// powder_dissipation_w_m3 (every type involving powder), collisions {by contact type, media,
// powder: count, rate_per_m3_s}, spectra {bin_edges_j, media, powder: dissipated energy histograms
// {counts, underflow, overflow}}, energy {work_in_j, kinetic_change_j, elastic_change_j,
// dissipated_j, stress_control_work_j (in work_in_j), balance_error}, steady_state
// {shear_stress_first_half_pa, shear_stress_second_half_pa, deviation, steady (the halves agree)},
// steady (stationary and the halves agree), stationary_strain (null when the warm-up never passed
// the test), converged, standard_errors {friction, friction_mean_pressure, shear_stress_pa,
// normal_stress_pa, power_density_w_m3, powder_dissipation_w_m3, dissipation_w_m3 {by contact type,
// total}, blocks, batch_blocks}, overlap {by contact type that touched: mean_fraction,
// p95_fraction, max_fraction, contact_samples}, overlap_{mean,p95,max}_fraction (the type with the
// largest p95; 0 without contacts), overlap_ok, neighbor_skin_fraction (the skin stepped at over
// the smallest diameter; absent in cells stored before it, read as none).
//
// A stiff cell of /shear_cell/stiffness/sensitivity, skipped or not, also has stiffness_factor F
// (its powder pairs' k_n are F x the policy's, stiffness.<pair> gives them); the default cells
// have no such key (read as 1).
//
// Reading an older cell: without `steady` the cell is steady when steady_state.steady is; without
// `converged` it counts as converged when steady; without standard_errors it has none.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dem/shear_cell.hpp"
#include "dem/stiffness_policy.hpp"
#include "method/energy_histogram.hpp"

namespace millflow::method {

template <class T>
using ByContactType = std::array<T, dem::kContactTypeCount>;  // indexed by dem::ContactType

struct CellCollisions {
  double count = 0.0, rate_per_m3_s = 0.0;
};

struct CellOverlap {
  double mean_fraction = 0.0, p95_fraction = 0.0, max_fraction = 0.0, contact_samples = 0.0;
};

// Standard errors of the window's means (batch means).
struct CellStandardErrors {
  double friction = 0.0, friction_mean_pressure = 0.0, shear_stress_pa = 0.0,
         normal_stress_pa = 0.0, power_density_w_m3 = 0.0, powder_dissipation_w_m3 = 0.0;
  ByContactType<double> dissipation_w_m3{};
  double dissipation_total_w_m3 = 0.0;
  std::size_t blocks = 0, batch_blocks = 0;
};

struct CellResult {
  // What the task was asked, written back as its parameters gave it (an integer load stays one).
  nlohmann::json site{};         // the sites task's entry (`millflow cell` gives only some keys)
  nlohmann::json slot{};         // {region, index}
  nlohmann::json powder_load{};  // U
  std::string skipped{};         // why no cell ran; then nothing below is set or written
  // The factor on the powder pairs' k_n of a stiff cell (/shear_cell/stiffness/sensitivity);
  // none (written as no key, read as 1) for the default cells.
  std::optional<double> stiffness_factor{};

  std::size_t media_count = 0, powder_count = 0, wall_ball_count = 0;
  std::vector<dem::PairStiffness> stiffness{};  // smaller_diameter is not stored

  double strain = 0.0, duration_s = 0.0;
  std::uint64_t steps = 0;
  double target_shear_rate_per_s = 0.0, bulk_shear_rate_per_s = 0.0, nominal_shear_rate_per_s = 0.0;
  double wall_speed_m_s = 0.0, wall_slip_m_s = 0.0, gap_m = 0.0, volume_m3 = 0.0;
  double shear_stress_pa = 0.0, normal_stress_pa = 0.0, friction = 0.0,
         friction_mean_pressure = 0.0;
  std::array<double, 6> stresses_pa{};  // xx, yy, zz, xy, xz, yz
  double mean_pressure_pa = 0.0;
  double inertial_number = 0.0, inertial_number_measured_rate = 0.0;
  double media_solid_fraction = 0.0, powder_solid_fraction = 0.0;
  double power_density_w_m3 = 0.0;
  ByContactType<double> dissipation_w_m3{};
  double dissipation_total_w_m3 = 0.0, powder_dissipation_w_m3 = 0.0;
  ByContactType<CellCollisions> collisions{};
  CellCollisions media_collisions{}, powder_collisions{};
  std::vector<double> spectrum_bin_edges_j{};
  EnergyHistogram media_spectrum{}, powder_spectrum{};  // dissipated energy
  double work_in_j = 0.0, kinetic_change_j = 0.0, elastic_change_j = 0.0, dissipated_j = 0.0,
         stress_control_work_j = 0.0, energy_balance_error = 0.0;
  double shear_stress_first_half_pa = 0.0, shear_stress_second_half_pa = 0.0,
         steady_deviation = 0.0;
  bool steady = false;
  std::optional<double> stationary_strain{};
  bool converged = false;
  std::optional<CellStandardErrors> standard_errors{};
  ByContactType<std::optional<CellOverlap>> overlaps{};  // none for a type that never touched
  bool overlap_ok = true;
  // The neighbour skin the cell stepped at, as a fraction of its smallest diameter (the campaign's
  // number, or what "auto" chose); costs only. Cells stored before it was reported lack it.
  std::optional<double> neighbor_skin_fraction{};

  // The contact type with the largest p95 overlap (the first of equals), zeros without contacts.
  CellOverlap worst_overlap() const;
};

// The measured quantities of a cell (the task's fields above it are left empty).
CellResult cell_result(const dem::ShearCellMeasurements& m);

void to_json(nlohmann::json& out, const CellResult& cell);
void from_json(const nlohmann::json& in, CellResult& cell);

}  // namespace millflow::method
