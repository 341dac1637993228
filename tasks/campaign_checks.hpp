#pragma once
// Cross-field checks of a campaign: what no single field's rule can see (materials named by one
// field and defined by another, lifters that fit the mill, balls that fit the slice...).
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/validation.hpp"

namespace millflow::tasks {

// The shortest contact duration a campaign may give a pair (/interactions/*/stiffness/
// collision_time, or a normal stiffness between the pair's reference particles): the runs step at
// a fraction of it.
inline constexpr double kShortestCollisionTime = 1e-7;
// The longest one: a softer contact lets the particles pass through each other.
inline constexpr double kLongestCollisionTime = 1e-1;
// Assumed voids of a ball bed, for estimates of ball and powder counts.
inline constexpr double bed_void_fraction = 0.4;
// Below this many balls there is no bed to average over or to split into flow regions.
inline constexpr double min_balls_in_charge = 50;
// A shear cell with more powder particles than this is beyond a workstation's reach.
inline constexpr double max_powder_particles = 2.0e6;
// The averaging needs at least this many flow samples over the measured revolutions.
inline constexpr double min_flow_samples = 10;
// The defaults of a campaign's /limits: what one macro run may cost before validation refuses it
// (a run past them takes days or exhausts a workstation's memory or disk). Estimates: balls from
// the fill (bed voids bed_void_fraction); time step t_c / steps_per_collision with t_c the
// shortest contact among the media's interactions (an undamped estimate for a normal stiffness:
// pi sqrt(m_eff / k_n) with the smallest ball); steps over settle time and all revolutions; VTK
// files one per vtk_interval over that time.
inline constexpr double default_max_steps_per_task = 1e8;
inline constexpr double default_max_particles_per_task = 2e6;
inline constexpr double default_max_output_files_per_task = 1e4;

// The errors of `campaign` (the validator's normalized document) that involve several fields.
// Fields that already have an error in `field_errors` (or sit above or below one) are skipped, so
// one mistake is reported once.
std::vector<engine::ValidationError> check_campaign_consistency(
    const nlohmann::json& campaign, const std::vector<engine::ValidationError>& field_errors);

}  // namespace millflow::tasks
