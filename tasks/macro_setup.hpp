#pragma once
// Parameters of a `macro` task (tasks/kinds.hpp: macro_params) translated into a DEM mill and
// the run's settings (method/macro_run.hpp).
//
// Contact stiffness per material pair, from the campaign's `stiffness`:
//   {"normal": k}           k_n = k directly;
//   {"collision_time": t}   k_n = the stiffness that gives contact duration t (with the pair's
//                           restitution) for two reference particles: each the ball of the media's
//                           mass-weighted mean diameter; the liner is a wall, so a ball-liner
//                           contact is the reference ball alone (m_eff = m_ball, against m_ball / 2
//                           for two balls). When the media and the liner share a material, its one
//                           interaction gives both contacts the same t_c, hence two different k_n.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "dem/mill_setup.hpp"
#include "method/macro_run.hpp"

namespace millflow::tasks {

// Throws engine::InvalidInput naming the parameter path for a missing or unusable value.
method::MacroSettings macro_settings(const nlohmann::json& params, const std::string& task_key);

// The contact parameters of one campaign interaction, for contacts of effective mass
// `reference_mass` (used only for a collision-time stiffness).
dem::InteractionSpec interaction_spec(const nlohmann::json& interaction, double reference_mass);

// The campaign interaction (params /interactions) of materials a and b, in either order. Throws
// engine::InvalidInput when there is none.
const nlohmann::json& find_interaction(const nlohmann::json& params, const std::string& a,
                                       const std::string& b);

// params /dem/neighbor_skin_fraction: the number, or empty for "auto" (chosen by trial, each
// shear cell after its first warm-up window and each macro run at the end of its warm-up).
std::optional<double> neighbor_skin_fraction(const nlohmann::json& params);

// The mass-weighted mean diameter of params /media (its diameter or size distribution), m.
double media_diameter(const nlohmann::json& params);

// The run's random seed: dem.seed mixed with the task key (FNV-1a of its text), so that every
// task of a sweep packs its own bed, and the same task always the same one.
std::uint64_t macro_seed(std::uint64_t dem_seed, const std::string& task_key);

}  // namespace millflow::tasks
