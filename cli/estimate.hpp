#pragma once
// `millflow estimate FILE`: per task kind, what a campaign's tasks cost before they run
// (tasks/cost_model.hpp), and the same figures below a dry run's.
#include <CLI/CLI.hpp>
#include <optional>
#include <string>

#include "engine/campaign.hpp"

namespace millflow::cli {

void add_estimate_command(CLI::App& app, const engine::Registry& registry,
                          std::optional<int>& exit_code);

// The cost of the tasks a dry run would run, or nothing when none of their kinds has a model.
std::string dry_run_cost(const engine::DryRun& dry);

}  // namespace millflow::cli
