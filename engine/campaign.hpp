#pragma once
// Campaign files, their formats, and the submit / resume / dry-run entry points.
//
// A campaign file is JSON; its format is detected from the top-level keys:
//   "format": "<name>"        that format (the engine itself handles "millflow-test");
//   "millflow_campaign": 1    the multiscale method's campaigns (format "millflow_campaign"),
//                             whose loader and planner tasks/ registers.
// A format has a loader (file -> validated document; throws InvalidInput listing every error)
// and a planner (document -> initial DAG). Documents are stored, so `resume` replans from the
// stored document without the file.
#include <filesystem>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "engine/cache.hpp"
#include "engine/progress.hpp"
#include "engine/runtime.hpp"
#include "engine/store.hpp"
#include "engine/task.hpp"

namespace millflow::engine {

struct CampaignFormat {
  std::string name;
  std::function<nlohmann::json(const std::filesystem::path&)> load;
  std::function<void(const nlohmann::json& document, Plan& plan)> plan;
};

// Everything a domain plugs into the engine.
struct Registry {
  KindRegistry kinds;
  std::map<std::string, CampaignFormat> formats;
  std::vector<ViewDefinition> views;

  void add_format(CampaignFormat format);
  const CampaignFormat& format(const std::string& name) const;  // throws InvalidInput if unknown
  std::string format_names() const;                             // "a, b"
};

struct Campaign {
  std::string name;
  std::string format;
  nlohmann::json document;
};

// A campaign's name names its log file: longer names are refused.
inline constexpr std::size_t kMaxCampaignName = 200;

// Reads, detects and validates a campaign file. Throws InvalidInput.
Campaign load_campaign_file(const Registry& registry, const std::filesystem::path& file);
std::vector<TaskSpec> plan_campaign(const Registry& registry, const Campaign& campaign);

// What a submission would do, decided task by task as the runtime decides (engine/cache.hpp):
// the planned graph, plus the tasks that cached tasks' results declared. Nothing is written.
struct DryRunTask {
  TaskSpec spec;
  CacheDecision decision;
  bool declared = false;  // declared by a cached task's result (not planned)
  bool held = false;      // beyond --until
  // The stored result of a cached task that a task which would run, of a kind with a cost model,
  // takes as an input (its sites, say): what the cost model prices that task from.
  std::optional<nlohmann::json> result;
};
struct DryRun {
  std::string campaign;
  std::vector<DryRunTask> tasks;  // upstream first
  int may_expand = 0;             // tasks that would run and may declare more when they finish

  // The header line, then per kind (in graph order) how many would run, grouped by reason, with
  // the parameter diff of changed tasks and the task behind a missing artifact or an unfinished
  // attempt.
  std::string describe() const;
  // Every task: "<kind> <key>: would run: <reason>" (or would not run, or held back), then the
  // reason's diff lines.
  std::string list() const;
  // explain_text of the one task whose key starts with key_prefix (InvalidInput otherwise).
  std::string explain(const std::string& key_prefix) const;
};
DryRun dry_run(const Registry& registry, const Campaign& campaign, const std::filesystem::path& db,
               const RunOptions& options = {});

struct SubmitOptions {
  RunOptions run;
  ProgressView* progress = nullptr;   // default: quiet
  const Clock* clock = nullptr;       // default: the system clock
  Launcher* launcher = nullptr;       // default: TbbLauncher(jobs, threads_per_task)
  const FileSystem* files = nullptr;  // default: the local disk
  JobExecutor* jobs = nullptr;  // run attempts as batch jobs (Slurm); default: in this process
};

// Takes the coordinator lock (CoordinatorBusy), registers the campaign and runs it.
RunSummary submit_campaign(const Registry& registry, const Campaign& campaign,
                           const std::filesystem::path& db, const SubmitOptions& options);
// The stored campaign by name, or the most recently submitted one when name is empty.
Campaign stored_campaign(const std::filesystem::path& db, const std::string& name);

}  // namespace millflow::engine
