#include "engine/campaign.hpp"

#include <fmt/format.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "engine/coordinator_lock.hpp"
#include "engine/database_path.hpp"
#include "engine/files.hpp"
#include "engine/json_text.hpp"
#include "engine/validation.hpp"
#include "engine/version.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

nlohmann::json read_json_file(const fs::path& file) {
  return parse_json_text(read_input_file(file)).document;
}

std::string detect_format(const Registry& registry, const nlohmann::json& document) {
  if (document.is_object() && document.contains("format") && document["format"].is_string()) {
    return document["format"].get<std::string>();
  }
  if (document.is_object() && document.contains("millflow_campaign")) return "millflow_campaign";
  throw InvalidInput(
      {{"", "the campaign format is not recognisable",
        "add \"millflow_campaign\": 1 for a mill campaign, or \"format\": \"<name>\" "
        "of a format this build reads: " +
            registry.format_names()}});
}

std::string file_safe(const std::string& name) {
  std::string safe = name;
  for (char& c : safe) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') c = '_';
  }
  return safe;
}

// A coordinator killed while it wrote a line (info lines are buffered) leaves the log without its
// last newline; the next coordinator's first line would be glued to the torn one.
void end_torn_line(const fs::path& log) {
  std::ifstream in(log, std::ios::binary | std::ios::ate);
  if (!in || in.tellg() <= 0) return;
  in.seekg(-1, std::ios::end);
  if (in.get() != '\n') std::ofstream(log, std::ios::app) << '\n';
}

std::shared_ptr<spdlog::logger> campaign_logger(const fs::path& db, const std::string& campaign) {
  const fs::path file = logs_dir(db) / (file_safe(campaign) + ".log");
  end_torn_line(file);
  // Warnings and errors (a stale lock taken over, a corrupt artifact re-run, a checkpoint
  // discarded) also go to the terminal, not only to the log file.
  auto terminal = std::make_shared<spdlog::sinks::stderr_sink_mt>();
  terminal->set_level(spdlog::level::warn);
  terminal->set_pattern("millflow: %l: %v");
  auto logger = std::make_shared<spdlog::logger>(
      "campaign",
      spdlog::sinks_init_list{std::make_shared<spdlog::sinks::basic_file_sink_mt>(file.string()),
                              terminal});
  logger->flush_on(spdlog::level::warn);  // info lines are buffered; the store holds the state
  return logger;
}

// Decides every task of the graph as the runtime would, from what the store holds.
class DryRunner {
 public:
  DryRunner(const Registry& registry, const fs::path& db, const RunOptions& options)
      : registry_(registry), artifacts_(artifacts_dir(db)), db_(open_read_only_if_submitted(db)) {
    if (db_) earlier_.emplace(*db_);
    judge_.emplace(artifacts_, options.force, earlier_ ? &*earlier_ : nullptr);
  }

  // previous: the task in the same place of the campaign's previous plan, if known.
  void add(const TaskSpec& spec, bool declared, const TaskSpec* previous = nullptr) {
    if (!seen_.insert(spec.key).second) return;
    std::optional<StoredTask> stored;
    if (db_) stored = find_stored_task(*db_, spec.key);
    result_.tasks.push_back({spec, judge_->decide(spec, stored, previous), declared, false, {}});
    if (!result_.tasks.back().decision.cached()) return;
    for (const auto& child : stored->children) add(find_task(*db_, child)->spec, true);
  }

  DryRun finish(const std::string& until) {
    if (!until.empty()) {
      std::vector<const TaskSpec*> graph;
      for (const auto& task : result_.tasks) graph.push_back(&task.spec);
      const auto beyond = beyond_until(graph, registry_.kinds, until);
      for (auto& task : result_.tasks) task.held = beyond.count(task.spec.key) > 0;
    }
    std::set<std::string> priced_inputs;
    for (const auto& task : result_.tasks) {
      if (task.decision.cached() || task.held || !registry_.kinds.contains(task.spec.kind))
        continue;
      const TaskKind& kind = registry_.kinds.get(task.spec.kind);
      if (kind.may_expand) ++result_.may_expand;
      if (kind.cost) priced_inputs.insert(task.spec.upstream.begin(), task.spec.upstream.end());
    }
    for (auto& task : result_.tasks) {
      if (db_ && task.decision.cached() && priced_inputs.contains(task.spec.key))
        task.result = find_result(*db_, task.spec.key);
    }
    return std::move(result_);
  }

 private:
  const Registry& registry_;
  ArtifactStore artifacts_;
  std::optional<sql::Connection> db_;
  std::optional<EarlierTasks> earlier_;
  std::optional<CacheJudge> judge_;
  std::set<std::string> seen_;
  DryRun result_;
};

// One kind's share of a dry run: its tasks by reason, in the order the reasons first appear.
struct KindTally {
  int total = 0;
  int would_run = 0;
  int held = 0;
  std::vector<std::pair<std::string, std::vector<const DryRunTask*>>> groups;

  void add(const DryRunTask& task) {
    ++total;
    if (task.held) {
      ++held;
      return;
    }
    if (task.decision.cached()) return;
    ++would_run;
    // Tasks whose parameters changed alike are one group; the other reasons group by name.
    std::string group = task.decision.summary();
    const RunReason reason = task.decision.reason;
    if (reason == RunReason::parameters_changed || reason == RunReason::version_changed) {
      for (const auto& line : task.decision.diff) group += "\n    " + line;
    }
    auto found = std::find_if(groups.begin(), groups.end(),
                              [&](const auto& entry) { return entry.first == group; });
    if (found == groups.end()) found = groups.insert(groups.end(), {group, {}});
    found->second.push_back(&task);
  }
};

// Reasons whose detail is the task's own (its artifact, its error): listed task by task.
bool detail_per_task(RunReason reason) {
  return reason == RunReason::artifact_bad || reason == RunReason::result_missing ||
         reason == RunReason::not_finished;
}

}  // namespace

void Registry::add_format(CampaignFormat format) {
  const std::string name = format.name;
  if (!formats.emplace(name, std::move(format)).second)
    throw std::logic_error("campaign format registered twice: " + name);
}

const CampaignFormat& Registry::format(const std::string& name) const {
  const auto found = formats.find(name);
  if (found == formats.end()) {
    throw InvalidInput(
        {{"", "no loader is registered for campaign format \"" + name + "\" in this build",
          "formats this build reads: " + format_names()}});
  }
  return found->second;
}

std::string Registry::format_names() const {
  std::string names;
  for (const auto& [name, format] : formats) names += (names.empty() ? "" : ", ") + name;
  return names;
}

Campaign load_campaign_file(const Registry& registry, const fs::path& file) {
  const std::string format = detect_format(registry, read_json_file(file));
  nlohmann::json document = registry.format(format).load(file);
  if (!document.contains("name") || !document["name"].is_string() ||
      document["name"].get<std::string>().empty()) {
    throw InvalidInput({{"/name", "the campaign has no name", "add a non-empty string \"name\""}});
  }
  if (const auto length = document["name"].get<std::string>().size(); length > kMaxCampaignName) {
    throw InvalidInput({{"/name",
                         fmt::format("the campaign name has {} characters, more than {}", length,
                                     kMaxCampaignName),
                         "use a shorter name (it names the campaign's log file)"}});
  }
  return Campaign{document["name"].get<std::string>(), format, std::move(document)};
}

std::vector<TaskSpec> plan_campaign(const Registry& registry, const Campaign& campaign) {
  Plan plan(registry.kinds);
  registry.format(campaign.format).plan(campaign.document, plan);
  return plan.tasks();
}

std::string DryRun::describe() const {
  int cached = 0;
  int held = 0;
  int declared = 0;
  std::vector<std::string> kinds;  // in graph order
  std::map<std::string, KindTally> tallies;
  for (const auto& task : tasks) {
    cached += task.decision.cached() && !task.held;
    held += task.held;
    declared += task.declared;
    if (tallies.count(task.spec.kind) == 0) kinds.push_back(task.spec.kind);
    tallies[task.spec.kind].add(task);
  }
  const int would_run = static_cast<int>(tasks.size()) - cached - held;
  std::string text = fmt::format("dry run of \"{}\": {} tasks, {} cached, {} would run", campaign,
                                 tasks.size(), cached, would_run);
  if (held > 0) text += fmt::format(", {} held back by --until", held);
  if (declared > 0)
    text += fmt::format("; {} of the tasks were declared by cached results", declared);
  if (may_expand > 0)
    text += fmt::format("; {} of them may declare more tasks when {} finishes", may_expand,
                        may_expand == 1 ? "it" : "each");
  text += "\n";
  for (const auto& kind : kinds) {
    const KindTally& tally = tallies.at(kind);
    text += fmt::format("{}: {} of {} would run", kind, tally.would_run, tally.total);
    if (tally.held > 0) text += fmt::format(", {} held back by --until", tally.held);
    text += "\n";
    for (const auto& [group, members] : tally.groups) {
      text += fmt::format("  {} {}\n", members.size(), group);
      if (!detail_per_task(members.front()->decision.reason)) continue;
      for (const DryRunTask* task : members)
        text += fmt::format("    {}: {}\n", task->spec.key.substr(0, 12), task->decision.detail);
    }
  }
  return text;
}

std::string DryRun::list() const {
  std::string text;
  for (const auto& task : tasks) {
    const auto lines = task.decision.lines();
    text += fmt::format("{} {}: {}\n", task.spec.kind, task.spec.key,
                        task.held ? "would not run: held back by --until" : lines.front());
    if (task.held) continue;
    for (size_t i = 1; i < lines.size(); ++i) text += lines[i] + "\n";
  }
  return text;
}

std::string DryRun::explain(const std::string& key_prefix) const {
  std::vector<const DryRunTask*> found;
  for (const auto& task : tasks) {
    if (!key_prefix.empty() && task.spec.key.rfind(key_prefix, 0) == 0) found.push_back(&task);
  }
  if (found.size() != 1) {
    throw InvalidInput({{"",
                         fmt::format("{} task of campaign \"{}\" has a key starting with \"{}\"",
                                     found.empty() ? "no" : "more than one", campaign, key_prefix),
                         found.empty() ? "`millflow explain FILE` lists every task with its key"
                                       : "give more characters of the key"}});
  }
  return explain_text(found.front()->spec, found.front()->decision);
}

DryRun dry_run(const Registry& registry, const Campaign& campaign, const fs::path& db,
               const RunOptions& options) {
  const auto planned = plan_campaign(registry, campaign);
  // The campaign as last submitted, planned again: its task in the same place of the same plan
  // shape is the earlier version a changed task is compared with.
  std::vector<TaskSpec> previous;
  if (fs::exists(db)) {
    try {
      previous = plan_campaign(registry, stored_campaign(db, campaign.name));
    } catch (const InvalidInput&) {  // never submitted, or no longer valid: compare by content
    }
  }
  if (previous.size() != planned.size()) previous.clear();
  DryRunner runner(registry, db, options);
  for (size_t i = 0; i < planned.size(); ++i) {
    const bool aligned = !previous.empty() && previous[i].kind == planned[i].kind;
    runner.add(planned[i], false, aligned ? &previous[i] : nullptr);
  }
  DryRun result = runner.finish(options.until);
  result.campaign = campaign.name;
  return result;
}

RunSummary submit_campaign(const Registry& registry, const Campaign& campaign,
                           const fs::path& given_db, const SubmitOptions& options) {
  const auto planned =
      plan_campaign(registry, campaign);  // bad input fails before anything is written
  const fs::path db = resolve_database(given_db, DatabaseUse::create);
  if (fs::exists(db) && ::access(db.c_str(), W_OK) != 0) {
    throw InvalidInput(
        {{"--db", fmt::format("cannot write {}: {}", db.string(), std::strerror(errno)),
          "make it writable (chmod u+w), or submit to a copy of it"}});
  }
  if (!db.parent_path().empty()) {
    std::error_code error;
    fs::create_directories(db.parent_path(), error);
    if (error) {
      throw InvalidInput({{"--db",
                           fmt::format("cannot create the directory {}: {}",
                                       db.parent_path().string(), error.message()),
                           "name a database in a directory you can write"}});
    }
  }
  CoordinatorLock lock(db);
  const SystemClock system_clock;
  const Clock& clock = options.clock ? *options.clock : system_clock;
  Store store(db, registry.views, clock);
  fs::create_directories(logs_dir(db));
  auto logger = campaign_logger(db, campaign.name);
  if (lock.stale_holder()) {
    logger->warn("took over the database from a coordinator that is gone: {}",
                 *lock.stale_holder());
  }
  store.set_coordinator(static_cast<int>(::getpid()), host_name(), campaign.name);
  // The campaign's outcome and the coordinator's record, written once however the run ends: an
  // error out of it (a damaged store, a full disk) leaves the database as an orderly end does,
  // the campaign failed and no coordinator recorded. Left behind, the record made the next
  // coordinator report taking over from one that was gone, and `status` call the campaign
  // interrupted by a coordinator that died.
  class RunEnd {
   public:
    explicit RunEnd(Store& store) : store_(store) {}
    void begin(std::int64_t campaign) { campaign_ = campaign; }
    void record(const std::string& outcome) {
      if (campaign_) store_.finish_campaign(*campaign_, outcome);
      store_.clear_coordinator();
      recorded_ = true;
    }
    ~RunEnd() {
      if (recorded_) return;
      try {
        record("failed");
      } catch (const std::exception&) {  // the store that failed may fail again: the lock is enough
      }
    }

   private:
    Store& store_;
    std::optional<std::int64_t> campaign_;
    bool recorded_ = false;
  } run_end(store);
  const std::int64_t id =
      store.register_campaign(campaign.name, campaign.format, campaign.document, planned);
  run_end.begin(id);
  logger->info("campaign \"{}\": {} planned tasks, code version {}", campaign.name, planned.size(),
               code_version());

  QuietProgress quiet;
  std::unique_ptr<Launcher> own_launcher;
  if (options.jobs)
    own_launcher = std::make_unique<InlineLauncher>();  // idle: the jobs run elsewhere
  else if (!options.launcher)
    own_launcher = std::make_unique<TbbLauncher>(options.run.jobs, options.run.threads_per_task);
  RunEnvironment environment{store,
                             registry.kinds,
                             options.launcher ? *options.launcher : *own_launcher,
                             options.progress ? *options.progress : quiet,
                             clock,
                             options.files ? *options.files : local_file_system(),
                             logger,
                             options.jobs};
  const RunSummary summary = run_campaign(environment, id, planned, options.run);
  const std::string outcome = summary.stopped         ? "interrupted"
                              : summary.failed > 0    ? "failed"
                              : summary.held_back > 0 ? "partial"
                                                      : "done";
  run_end.record(outcome);
  logger->info("campaign \"{}\" {}: {}", campaign.name, outcome, summary.describe());
  return summary;
}

Campaign stored_campaign(const fs::path& db, const std::string& name) {
  auto connection = open_read_only(db);
  auto stored = find_campaign(connection, name);
  if (!stored) {
    throw InvalidInput({{"",
                         name.empty() ? "the database " + db.string() + " holds no campaign"
                                      : "no campaign named \"" + name + "\" in " + db.string(),
                         "run `millflow status` to list the campaigns"}});
  }
  return Campaign{stored->name, stored->format, std::move(stored->document)};
}

}  // namespace millflow::engine
