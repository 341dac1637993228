#pragma once
// A mill run's result (docs/method.md, step 1): what the `macro` task kind stores
// (method::MacroRun::finish produces it) and the average, sites, upscale and report tasks read.
// to_json and read_macro_result below are the one spelling of its keys.
//
// Result JSON (versioned by the kind's kMacroVersion, tasks/macro.hpp), SI units unless the key
// says otherwise:
//   n_balls, ball_mass_kg (total), media_diameter_m (mass-weighted mean), dt_s,
//   collision_time_s (shortest, sets dt), critical_speed_rad_s, angular_velocity_rad_s,
//   speed_fraction, fill, gravity_m_s2 (along -y), mill {radius_m, length_m, axial_ends,
//   lifter_count}, contacts {ball_ball, ball_liner: pair, normal_stiffness_n_m,
//   tangential_stiffness_n_m, restitution, friction, reference_mass_kg, collision_time_s},
//   measure_start_s, measure_end_s, measure_revolutions, sample_interval_s, frame_count,
//   segment_count, categories (dem::System category names by index, as in the flow frames),
//   power {mean_w, std_w (of the block means), mean_kw, std_kw, kw_per_m, kw_per_t_balls,
//          torque_arm_kw (M g x_com omega), torque_arm_relative_difference, dissipation_kw,
//          block_s},
//   correlations {bond_kw_per_t, hogg_fuerstenau_kw_per_t, hogg_fuerstenau_repose_deg,
//   ratio_to_bond, ratio_to_hogg_fuerstenau}, charge {toe_angle_deg, shoulder_angle_deg (null
//   when undefined), convention, contact_angle_bin_deg, contact_angle_counts}
//   (method/macro_measure.hpp ChargeShape),
//   collisions {ball_ball, ball_liner: category, count, rate_per_s, mean_impact_energy_j,
//   mean_dissipated_j, dissipated_power_w},
//   spectra {bin_edges_j, ball_ball, ball_liner: impact_energy and dissipated_energy histograms},
//   frame_means {frames, kinetic_energy_j {translational, rotational}, centre_of_mass_m {x, y},
//   drive_torque_n_m {liner, lifters, end_walls, total}, drive_power_w} (means over the flow
//   frames, method/macro_measure.hpp FrameMeans).
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "method/energy_histogram.hpp"

namespace millflow::method {

struct MacroMill {
  double radius_m = 0.0, length_m = 0.0;
  std::string axial_ends{};  // "walls" or "periodic"
  int lifter_count = 0;
};

// The contact parameters between balls (ball_ball) and between a ball and the liner (ball_liner).
struct MacroContact {
  std::string pair{};
  double normal_stiffness_n_m = 0.0, tangential_stiffness_n_m = 0.0, restitution = 0.0,
         friction = 0.0, reference_mass_kg = 0.0, collision_time_s = 0.0;
};

struct MacroPower {
  double mean_w = 0.0, std_w = 0.0, mean_kw = 0.0, std_kw = 0.0, kw_per_m = 0.0,
         kw_per_t_balls = 0.0, torque_arm_kw = 0.0, torque_arm_relative_difference = 0.0,
         dissipation_kw = 0.0, block_s = 0.0;
};

// The power from the Bond and the Hogg-Fuerstenau correlations, and the run's ratio to each.
struct MacroCorrelations {
  double bond_kw_per_t = 0.0, hogg_fuerstenau_kw_per_t = 0.0, hogg_fuerstenau_repose_deg = 0.0,
         ratio_to_bond = 0.0, ratio_to_hogg_fuerstenau = 0.0;
};

struct MacroCharge {
  std::optional<double> toe_angle_deg{}, shoulder_angle_deg{};  // none when undefined
  double contact_angle_bin_deg = 0.0;
  std::vector<double> contact_angle_counts{};
};

struct MacroFrameMeans {
  std::uint64_t frames = 0;
  double kinetic_translational_j = 0.0, kinetic_rotational_j = 0.0;
  double centre_of_mass_x_m = 0.0, centre_of_mass_y_m = 0.0;
  double liner_torque_n_m = 0.0, lifter_torque_n_m = 0.0, end_wall_torque_n_m = 0.0,
         drive_torque_n_m = 0.0;  // the total
  double drive_power_w = 0.0;
};

// The collisions of one tracked category (its label keys collisions and spectra).
struct MacroCollisions {
  std::string category{};  // the dem::System category name
  std::uint64_t count = 0;
  double rate_per_s = 0.0, mean_impact_energy_j = 0.0, mean_dissipated_j = 0.0,
         dissipated_power_w = 0.0;
  EnergyHistogram impact_energy{}, dissipated_energy{};
};

struct MacroResult {
  std::size_t n_balls = 0;
  double ball_mass_kg = 0.0, media_diameter_m = 0.0, dt_s = 0.0, collision_time_s = 0.0,
         critical_speed_rad_s = 0.0, angular_velocity_rad_s = 0.0, speed_fraction = 0.0, fill = 0.0,
         gravity_m_s2 = 0.0;
  MacroMill mill{};
  std::map<std::string, MacroContact> contacts{};  // by label
  double measure_start_s = 0.0, measure_end_s = 0.0, measure_revolutions = 0.0,
         sample_interval_s = 0.0;
  std::uint64_t frame_count = 0, segment_count = 0;
  std::vector<std::string> categories{};
  MacroPower power{};
  MacroCorrelations correlations{};
  MacroCharge charge{};
  MacroFrameMeans frame_means{};
  std::vector<double> spectrum_bin_edges_j{};           // none when no category is tracked
  std::map<std::string, MacroCollisions> collisions{};  // by label, e.g. "ball_ball"
};

void to_json(nlohmann::json& out, const MacroResult& result);

// Reads and checks a result: a missing or ill-typed field, or a spectrum whose counts do not
// match the bin edges, throws std::invalid_argument "<owner>: field <JSON pointer> <problem>; ..."
// (util/json_fields.hpp), e.g. owner "macro task <key>".
MacroResult read_macro_result(const nlohmann::json& in, const std::string& owner);
void from_json(const nlohmann::json& in, MacroResult& result);  // owner "macro result"

}  // namespace millflow::method
