#include "cli/estimate.hpp"

#include <iostream>
#include <map>
#include <set>

#include "cli/commands.hpp"
#include "tasks/cost_model.hpp"

namespace millflow::cli {
namespace {

bool any_estimated(const std::map<std::string, tasks::KindEstimate>& by_kind) {
  for (const auto& [kind, estimate] : by_kind)
    if (estimate.estimated > 0) return true;
  return false;
}

constexpr const char* kCostNote =
    "core-hours: the least strains - the strain caps (tasks/cost_model.hpp, docs/cost_model.md)\n";

}  // namespace

void add_estimate_command(CLI::App& app, const engine::Registry& registry,
                          std::optional<int>& exit_code) {
  auto* command = app.add_subcommand(
      "estimate",
      "Per task kind: tasks, particles, steps and core-hours of a campaign file, before it runs");
  auto file = std::make_shared<std::string>();
  command->add_option("FILE", *file, "Campaign JSON file")->required();
  command->callback([&registry, &exit_code, file] {
    exit_code = guarded([&] {
      const auto campaign = engine::load_campaign_file(registry, *file);
      const auto planned = engine::plan_campaign(registry, campaign);
      std::cout << "estimate of \"" << campaign.name << "\", " << planned.size()
                << " planned tasks\n"
                << tasks::format_estimate(tasks::estimate_plan(planned)) << kCostNote;
      return 0;
    });
  });
}

std::string dry_run_cost(const engine::DryRun& dry) {
  std::vector<engine::TaskSpec> specs;
  std::set<std::string> would_run;
  std::map<std::string, const nlohmann::json*> stored;
  for (const auto& task : dry.tasks) {
    specs.push_back(task.spec);
    if (!task.decision.cached() && !task.held) would_run.insert(task.spec.key);
    if (task.result) stored[task.spec.key] = &*task.result;
  }
  // Cells whose sites are stored are priced at them, as the ETA prices them.
  const auto by_kind = tasks::estimate_plan(
      specs, [&would_run](const engine::TaskSpec& spec) { return would_run.contains(spec.key); },
      [&stored](const std::string& key) -> const nlohmann::json* {
        const auto found = stored.find(key);
        return found == stored.end() ? nullptr : found->second;
      });
  if (!any_estimated(by_kind)) return {};
  return "cost of what would run:\n" + tasks::format_estimate(by_kind) + kCostNote;
}

}  // namespace millflow::cli
