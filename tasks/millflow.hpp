#pragma once
// Registers millflow's campaign format ("millflow_campaign": 1), its planner, task kinds and
// SQL views with the engine.
#include "engine/campaign.hpp"

namespace millflow::tasks {

void register_millflow(engine::Registry& registry);

// The initial DAG of a validated campaign: per sweep point macro -> average -> sites, then
// shear_cells (which declares one shear_cell per site) unless shear_cell.enabled is false; points
// that share a slice share its task.
void plan_millflow(const nlohmann::json& campaign, engine::Plan& plan);

}  // namespace millflow::tasks
