#pragma once
// The `sites` task kind: the flow regions and sites (method/sites.hpp) of one averaged mill run.
#include <nlohmann/json.hpp>

#include "engine/campaign.hpp"
#include "engine/task.hpp"
#include "method/sites.hpp"

namespace millflow::tasks {

// Bump whenever the results change (tests/tasks/golden/sites.json guards it).
inline constexpr const char* kSitesVersion = "3";

// /sites/rules (every field present, as validation leaves it), with `overrides` (an alternative
// rule set's partial /sites/alternatives/*/rules) on top.
method::RegionRules region_rules_from_json(
    const nlohmann::json& rules, const nlohmann::json& overrides = nlohmann::json::object());

// Parameters: {"sites": {"per_region": n, "regions": [...], "weight_by", "rules": {...},
// "alternatives": [{"name", "rules": {...}}]}}. Inputs, by kind: the average task (its
// fields.json) and the macro task (its charge's toe and shoulder angles). Artifact: regions.vti
// (region index per cell, with the fields it used). Result: method::SitesResult
// (method/sites_result.hpp, the one spelling of its keys): the macro run's fill and
// speed_fraction, the average_task's key, the rules, the regions with volumes, solid volumes and
// dissipation shares, the empty regions, the toe (angle, disc, impact zone) and shoulder angle,
// the sites, and rule_sets: per rule set (the default first, then each alternative) its name,
// rules and regions.
engine::TaskOutcome run_sites(engine::TaskContext& context);

// The SQL view `sites`: one row per (campaign, sites task, site) with the macro run's fill and
// speed fraction.
engine::ViewDefinition sites_view();

}  // namespace millflow::tasks
