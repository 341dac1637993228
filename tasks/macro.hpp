#pragma once
// The `macro` task kind: one DEM run of the balls in a rotating mill slice (docs/method.md,
// step 1). Parameters: tasks::macro_params (materials, interactions, dem, mill, media, macro);
// their translation into a DEM mill is in tasks/macro_setup.hpp.
//
// Run: build the charge (tasks/macro_setup.hpp), dt = t_c / dem.steps_per_collision; settle
// for macro.settle_time with the shell at rest; turn it at speed_fraction x critical speed
// (dem::critical_speed with the mass-weighted mean ball diameter) for warmup_revolutions, then
// measure for measure_revolutions, rounded to a whole number of flow-sample intervals. All
// cadences are whole step counts fixed at the start, so that a run continued from a checkpoint
// gives the same bits as one that never stopped.
//
// Result JSON (SI units unless the key says otherwise):
//   n_balls, ball_mass_kg (total), media_diameter_m (mass-weighted mean), dt_s,
//   collision_time_s (shortest, sets dt), critical_speed_rad_s, angular_velocity_rad_s,
//   speed_fraction, fill, gravity_m_s2 (along -y), mill {radius_m, length_m, axial_ends,
//   lifter_count}, contacts {ball_ball, ball_liner: k_n, k_t, e, mu, reference mass, t_c},
//   measure_start_s, measure_end_s, measure_revolutions, sample_interval_s, frame_count,
//   segment_count, categories (dem::System category names by index, as in the flow frames),
//   power {mean_w, std_w (of the block means), mean_kw, std_kw, kw_per_m, kw_per_t_balls,
//          torque_arm_kw (M g x_com omega), torque_arm_relative_difference, dissipation_kw,
//          block_s},
//   correlations {bond_kw_per_t, hogg_fuerstenau_kw_per_t, ratio_to_bond,
//   ratio_to_hogg_fuerstenau}, charge {toe_angle_deg, shoulder_angle_deg (null when undefined),
//   convention,
//           contact_angle_bin_deg, contact_angle_counts} (see tasks/macro_measure.hpp),
//   collisions {ball_ball, ball_liner: count, rate_per_s, mean energies, dissipated_power_w},
//   spectra {bin_edges_j, ball_ball, ball_liner: impact_energy and dissipated_energy histograms},
//   frame_means {frames, kinetic_energy_j {translational, rotational}, centre_of_mass_m {x, y},
//   drive_torque_n_m {liner, lifters, end_walls, total}, drive_power_w} (means over the flow
//   frames, tasks/macro_measure.hpp FrameMeans).
// Artifacts: power.csv (time_s, power_w, torque_arm_power_w), collision_spectra.csv (per
// energy bin: energy_low_j, energy_high_j and <category>_<impact|dissipated>_energy_count, the
// spectra of the result as a table), flow/segment_NNNN.mfs (flow
// frames every sample interval of the measurement, dem/flow_sample.hpp, 16 frames a segment),
// vtk/particles_NNNN.vtp and vtk/mill_NNNN.vtp (the shell and lifters at the same angle) every
// vtk_interval from the start, and their collections vtk/particles.pvd and vtk/mill.pvd.
//
// Interruption: the stop token is polled every step; on a stop, and every
// checkpoint_interval_s of wall time, the DEM state, the measurement accumulators and the frames
// not yet in a segment are saved in the work directory (committed by renaming state.bin last);
// the next attempt continues from there.
#include <string>

#include "engine/campaign.hpp"

namespace millflow::tasks {

// Bump whenever the results of the same parameters change.
inline constexpr const char* kMacroVersion = "3";

engine::TaskOutcome run_macro(engine::TaskContext& context);

// macro_results: one row per (campaign, macro task).
// View macro_lineage: each task with the macro run of its sweep point (macro_key, fill,
// speed_fraction). Views of later stages join it; it must be installed before them.
engine::ViewDefinition macro_lineage_view();
engine::ViewDefinition macro_results_view();

// Specific power of ball mills from the classical correlations, kW per tonne of balls, for mill
// diameter D (m), fill J and speed fraction phi_c:
//   Bond: 4.879 D^0.3 (3.2 - 3 J) phi_c (1 - 0.1 / 2^(9 - 10 phi_c));
//   Hogg-Fuerstenau: P = 17.06 phi_c rho_c D^2.5 L J (1 - 1.065 J) sin(alpha) kW over the charge
//   mass rho_c J pi D^2 / 4 L t, i.e. 21.72 phi_c D^0.5 (1 - 1.065 J) sin(alpha).
double bond_kw_per_tonne(double diameter, double fill, double speed_fraction);
double hogg_fuerstenau_kw_per_tonne(double diameter, double fill, double speed_fraction,
                                    double repose_deg = 35.0);

}  // namespace millflow::tasks
