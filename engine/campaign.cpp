#include "engine/campaign.hpp"

#include <fmt/format.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <unistd.h>

#include <fstream>
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

std::string detect_format(const nlohmann::json& document) {
  if (document.is_object() && document.contains("format") && document["format"].is_string()) {
    return document["format"].get<std::string>();
  }
  if (document.is_object() && document.contains("millflow_campaign")) return "millflow_campaign";
  throw InvalidInput(
      {{"", "the campaign format is not recognisable",
        "add \"millflow_campaign\": 1 for a mill campaign, or \"format\": \"millflow-test\""}});
}

std::string file_safe(const std::string& name) {
  std::string safe = name;
  for (char& c : safe) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') c = '_';
  }
  return safe;
}

std::shared_ptr<spdlog::logger> campaign_logger(const fs::path& db, const std::string& campaign) {
  const fs::path file = logs_dir(db) / (file_safe(campaign) + ".log");
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

// Counts tasks of the dry run from what the store already holds (nothing is written).
class DryRunCounter {
 public:
  DryRunCounter(const Registry& registry, std::optional<sql::Connection> db,
                ArtifactStore artifacts)
      : registry_(registry), db_(std::move(db)), artifacts_(std::move(artifacts)) {}

  void count(const TaskSpec& spec, bool declared_child) {
    if (!seen_.insert(spec.key).second) return;
    ++result_.total;
    if (declared_child) ++result_.known_expansions;
    if (is_cached(spec.key)) {
      ++result_.cached;
      for (const auto& child : child_keys(*db_, spec.key))
        count(find_task(*db_, child)->spec, true);
      return;
    }
    ++result_.would_run;
    if (registry_.kinds.contains(spec.kind) && registry_.kinds.get(spec.kind).may_expand)
      ++result_.may_expand;
  }
  const DryRun& result() const { return result_; }

 private:
  bool is_cached(const std::string& key) {
    if (!db_) return false;
    const auto record = find_task(*db_, key);
    if (!record || record->status != "done") return false;
    for (const auto& artifact : find_artifacts(*db_, key)) {
      if (!artifacts_.verify(artifact)) return false;
    }
    return true;
  }

  const Registry& registry_;
  std::optional<sql::Connection> db_;
  ArtifactStore artifacts_;
  std::set<std::string> seen_;
  DryRun result_;
};

}  // namespace

void Registry::add_format(CampaignFormat format) {
  const std::string name = format.name;
  if (!formats.emplace(name, std::move(format)).second)
    throw std::logic_error("campaign format registered twice: " + name);
}

const CampaignFormat& Registry::format(const std::string& name) const {
  const auto found = formats.find(name);
  if (found == formats.end()) {
    std::string known;
    for (const auto& [format_name, format] : formats)
      known += (known.empty() ? "" : ", ") + format_name;
    throw InvalidInput(
        {{"", "no loader is registered for campaign format \"" + name + "\" in this build",
          "formats this build reads: " + known}});
  }
  return found->second;
}

Campaign load_campaign_file(const Registry& registry, const fs::path& file) {
  const std::string format = detect_format(read_json_file(file));
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
  return fmt::format(
      "dry run: {} tasks in the DAG, {} cached, {} would run; {} of those may add tasks when they "
      "finish "
      "(pending expansions); {} tasks come from expansions already recorded",
      total, cached, would_run, may_expand, known_expansions);
}

DryRun dry_run(const Registry& registry, const Campaign& campaign, const fs::path& db) {
  std::optional<sql::Connection> connection;
  if (fs::exists(db)) connection.emplace(open_read_only(db));
  if (connection && connection->user_version() == 0) connection.reset();
  DryRunCounter counter(registry, std::move(connection), ArtifactStore(artifacts_dir(db)));
  for (const auto& spec : plan_campaign(registry, campaign)) counter.count(spec, false);
  return counter.result();
}

RunSummary submit_campaign(const Registry& registry, const Campaign& campaign,
                           const fs::path& given_db, const SubmitOptions& options) {
  const auto planned =
      plan_campaign(registry, campaign);  // bad input fails before anything is written
  const fs::path db = resolve_database(given_db, DatabaseUse::create);
  if (!db.parent_path().empty()) fs::create_directories(db.parent_path());
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
  const std::int64_t id =
      store.register_campaign(campaign.name, campaign.format, campaign.document, planned);
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
  const std::string outcome = summary.stopped      ? "interrupted"
                              : summary.failed > 0 ? "failed"
                                                   : "done";
  store.finish_campaign(id, outcome);
  store.clear_coordinator();
  logger->info("campaign \"{}\" {}: {}", campaign.name, outcome, summary.describe());
  return summary;
}

Campaign stored_campaign(const fs::path& db, const std::string& name) {
  auto connection = open_read_only(db);
  auto row = connection.prepare(
      name.empty() ? "SELECT name, format, document FROM campaigns ORDER BY submitted_at DESC, id "
                     "DESC LIMIT 1"
                   : "SELECT name, format, document FROM campaigns WHERE name = ?");
  if (!name.empty()) row.bind_all(name);
  if (!row.step()) {
    throw InvalidInput({{"",
                         name.empty() ? "the database " + db.string() + " holds no campaign"
                                      : "no campaign named \"" + name + "\" in " + db.string(),
                         "run `millflow status` to list the campaigns"}});
  }
  return Campaign{row.text(0), row.text(1), nlohmann::json::parse(row.text(2))};
}

}  // namespace millflow::engine
