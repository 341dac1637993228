#pragma once
// The `shear_cell` task kind (docs/method.md, step 3): one microscale shear cell per site
// slot and powder load.
//
// Parameters: tasks::shear_cells_params (shear_cell, materials, interactions, media, dem.seed) plus
// slot {region, index}: the site "<region>-<index>" of the sites task, the one upstream task.
// The planner knows the regions and the sites per region but not which sites exist, so a slot may
// be empty (a region with fewer cells than sites, or none) or its site unusable (shear rate or
// normal stress not positive); the task then finishes at once with
//   {skipped: reason, slot, powder_load}.
// Otherwise a dem::ShearCell at the site's shear rate and normal stress. Translation:
//   media diameter   the mass-weighted mean of /media (as the macro run's);
//   contacts         tasks::interaction_spec of the campaign interaction of each pair; a
//                    collision-time stiffness is for the pair's two reference particles (media
//                    balls of that diameter, powder grains of diameter_ratio x it);
//   boundary         "walls" -> rough walls, "lees_edwards" -> Lees-Edwards;
//   servo gain       /shear_cell/stress_control/gain;
//   time step        t_c / /shear_cell/steps_per_collision (not /dem's: the cells' energy
//                    balance needs finer steps than the macro runs, see campaigns/README.md);
//   seed             tasks::macro_seed(dem.seed, task key);
//   stiffness        /shear_cell/stiffness (apply_stiffness_policy below), logged and stored in
//                    the result as stiffness {by pair: k_n_n_m, kappa, given_n_m,
//                    static_bound_n_m, impact_bound_n_m, governing};
//   stiffness_factor F, only in the parameters of the stiff cells that
//                    /shear_cell/stiffness/sensitivity plans (tasks/kinds.hpp, plan_stiff_cells):
//                    the powder pairs' (media-powder, powder-powder) k_n are F x what the policy
//                    derived, where its bounds govern and the results move with it
//                    (docs/cell_validation.md, table 1); the balls' pair keeps its k_n. Logged,
//                    and stored as the result's stiffness_factor (absent in the default cells).
// Run: a dem::ShearCellRun of shear_cell_protocol (warm-up in windows of warmup_strain /
// kWarmupWindows until stationary or max_warmup_strain, then measure_strain measured and on to
// convergence up to convergence/max_strain). The stop token is polled every kStepsBetweenPolls
// steps (while it compacts, at the end of the control interval that reaches them); on a stop, and
// every /shear_cell/checkpoint_interval_s of wall time, the run is saved to cell.ckpt in the work
// directory (the format is beside dem::ShearCellRun), and the next attempt continues from it with
// the same bits. A checkpoint that cannot be read (truncated, altered, of another cell, or written
// by another version of this kind) is logged and removed, and the cell starts again from scratch.
// The file goes when the cell is done. Result: method::CellResult (method/cell_result.hpp), its
// JSON keys and their meaning.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dem/shear_cell.hpp"
#include "dem/stiffness_policy.hpp"
#include "engine/task.hpp"

namespace millflow::tasks {

// Bump whenever the results of the same parameters change (tests/tasks/golden/shear_cell.json).
// Its cells' checkpoints carry it (dem::ShearCellProtocol::code_version): a cell interrupted
// under one version is not continued by another (`millflow cell --out` reuses its directory).
inline constexpr const char* kShearCellVersion = "17";
inline constexpr int kWarmupWindows = 4;
inline constexpr std::uint64_t kStepsBetweenPolls = 100;

// The site id of a slot: "<region>-<index>".
std::string slot_site_id(const nlohmann::json& slot);

// The site of a slot in a sites task's result, or the reason there is none to shear.
struct SlotSite {
  nlohmann::json site;  // null when there is no usable site
  std::string skipped;  // empty when `site` can drive a cell
};
SlotSite find_slot_site(const nlohmann::json& sites_result, const nlohmann::json& slot);

// The cell of a shear_cell task's parameters at a site. Throws engine::InvalidInput or
// nlohmann::json::exception for missing values, std::invalid_argument for unusable ones.
dem::ShearCellSetup shear_cell_setup(const nlohmann::json& params, const nlohmann::json& site,
                                     const std::string& task_key);

// The shear_cell block's stiffness policy (/shear_cell/stiffness, docs/shear_cells.md) applied to
// a setup: "overlap_bound" raises each pair's k_n (dem::apply_overlap_bound), "campaign" keeps
// them; then a stiff cell's factor multiplies the powder pairs' k_n. Returns what was derived
// (the powder pairs' k_n_n_m and kappa with the factor) for the result's "stiffness" and the log.
std::vector<dem::PairStiffness> apply_stiffness_policy(const nlohmann::json& params,
                                                       dem::ShearCellSetup& setup);
std::string stiffness_log(const std::vector<dem::PairStiffness>& pairs,
                          const dem::ShearCellSetup& setup, std::optional<double> factor);

// A stiff cell's stiffness_factor; none for the default cells.
std::optional<double> stiffness_factor(const nlohmann::json& params);

// The warm-up and measurement of a shear_cell task's parameters.
dem::ShearCellProtocol shear_cell_protocol(const nlohmann::json& params);

// A cell that ran also leaves the artifact cell.vtp: its particles at the end of the measurement
// (dem::write_particles_vtp; media and powder told apart by "material"), for ParaView.
engine::TaskOutcome run_shear_cell(engine::TaskContext& context);

}  // namespace millflow::tasks
