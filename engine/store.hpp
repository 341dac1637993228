#pragma once
// The provenance store: one SQLite file, written by exactly one connection (this class), owned by
// the coordinating thread. Readers open their own read-only connections (open_read_only).
//
// Schema version 4 (PRAGMA user_version = 4); times are Unix seconds (REAL), JSON is canonical
// text.
//   campaigns      id PK, name UNIQUE, format, document (the loaded campaign JSON), submitted_at,
//                  finished_at, outcome ('running'|'done'|'failed'|'interrupted'|'partial':
//                  tasks beyond `--until` left pending)
//   tasks          key PK (SHA-256 hex), kind, kind_version, params, key_text (exactly what was
//                  hashed), parent_key (the task whose result declared it; NULL for planned tasks),
//                  status ('pending'|'running'|'done'|'failed'|'interrupted'|'skipped'),
//                  attempts (launches ever), created_at, started_at, finished_at, duration_s,
//                  host, code_version, error
//   campaign_tasks campaign_id, task_key: which tasks belong to which campaign (tasks are shared)
//   edges          downstream, position, upstream: the DAG (position = input order)
//   results        task_key PK, result (JSON), committed_at (since version 4 WITHOUT ROWID)
//   artifacts      task_key, name, sha256, size, path (relative to the database's directory);
//                  files live in <db>.artifacts/<sha[0:2]>/<sha>
//   status_history id, task_key, status, attempt, at, message: every status change (since
//                  version 4 not indexed by task: it is written far more often than read)
//   log_lines      id, task_key (NULL for campaign-level lines), at, level, message
//   coordinator    the one row (id = 1) of the coordinator holding the database: pid, host,
//                  started_at, campaign
//   jobs           (since version 2) task_key, attempt (PK together), executor ('slurm'), job_id
//                  ('' while state is SUBMITTING: recorded before the scheduler got the job),
//                  state (the scheduler's last reported state), output_dir, stdout_path,
//                  stderr_path, submitted_at, updated_at, job_name (since version 3; the
//                  scheduler's job name, '' in rows of version 2): the batch job of each attempt
//                  run by a JobExecutor; `resume` re-attaches to the job of a task's current
//                  attempt, finding one recorded without id by its job name
// Views: task_results (campaign, task_key, kind, status, params, result), plus the views that
// tasks/ registers (ViewDefinition), recreated each time a writer opens the database.
// Indexes: tasks by kind (since version 4 not by status: a status change then writes no index
// page), by parent; campaign_tasks, edges (by upstream) and artifacts (by digest) as keyed above.
// Migrations are forward only: migration i takes user_version i to i + 1; a database with a newer
// version than this build knows is refused (SchemaTooNew) and never touched.
//
// Durability: WAL journal, synchronous = NORMAL, one transaction per task completion. A commit is
// atomic, and once it has returned it survives the coordinator's death (kill -9, a crash: the WAL
// frames are in the operating system's cache; tests/engine/test_crash_safety.cpp checks this).
// It is not synced to disk at each commit (a sync costs ~2 ms here, ten times the engine's whole
// cost per trivial task): a power loss or operating-system crash keeps the database consistent but
// may roll it back to its last checkpoint (at most ~16 MB of WAL, see the Store constructor).
// Nothing is lost then beyond repeated work: rolled-back tasks are pending or running again and
// run again on resume (their artifacts are content-addressed, so storing them again is harmless).
// One exception: a batch job whose submission record was rolled back may be submitted twice.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "engine/artifacts.hpp"
#include "engine/clock.hpp"
#include "engine/job_executor.hpp"
#include "engine/sqlite.hpp"
#include "engine/task.hpp"

namespace millflow::engine {

inline constexpr int kSchemaVersion = 4;

// The SQL of migration i takes a database from user_version i to i + 1 (tests build old versions).
const std::vector<std::string>& schema_migrations();

class SchemaTooNew : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A read-only SQL view added by a domain (tasks/): CREATE VIEW <name> AS <select_sql>.
struct ViewDefinition {
  std::string name;
  std::string select_sql;
};

// A task's status column; the strings are the schema's ('pending', 'running', ...).
enum class TaskStatus { pending, running, done, failed, interrupted, skipped };
std::string_view to_string(TaskStatus status);
TaskStatus task_status_from(std::string_view text);  // throws std::runtime_error for unknown text

struct TaskRecord {
  TaskSpec spec;
  TaskStatus status = TaskStatus::pending;
  int attempts = 0;
  std::optional<std::string> parent_key;
  std::string error;
};

// Paths beside a database file: <dir>/<name>.artifacts, <name>.work, <name>.lock, <name>.logs,
// <name>.jobs (the default run directory of batch jobs).
std::filesystem::path artifacts_dir(const std::filesystem::path& db);
std::filesystem::path work_dir(const std::filesystem::path& db);
std::filesystem::path jobs_dir(const std::filesystem::path& db);
std::filesystem::path lock_file(const std::filesystem::path& db);
std::filesystem::path logs_dir(const std::filesystem::path& db);

// Wording for a database file SQLite cannot read (garbage, truncated, damaged pages): what is
// wrong, and how to fix it. is_damaged_database_error tells such an SQLite message from others.
bool is_damaged_database_error(std::string_view sqlite_message);
std::string damaged_database_problem(const std::filesystem::path& db,
                                     std::string_view sqlite_message);
std::string damaged_database_fix(const std::filesystem::path& db);

// Read-only connection to an existing database whose schema this build understands. A file that
// is not a readable SQLite database is InvalidInput (path "--db").
sql::Connection open_read_only(const std::filesystem::path& db);

// Reads shared by the writer and the read-only tools.
std::optional<TaskRecord> find_task(sql::Connection& db, const std::string& key);
std::optional<nlohmann::json> find_result(sql::Connection& db, const std::string& key);
std::vector<StoredArtifact> find_artifacts(sql::Connection& db, const std::string& key);
std::vector<std::string> child_keys(sql::Connection& db, const std::string& parent_key);
// What the cache decision needs to know of a stored task (engine/cache.hpp).
struct StoredTask {
  TaskStatus status = TaskStatus::pending;
  int attempts = 0;
  std::string error;
  bool has_result = false;
  std::vector<StoredArtifact> artifacts;
  std::vector<std::string> children;  // declared by its result, in declaration order
};
std::optional<StoredTask> find_stored_task(sql::Connection& db, const std::string& key);
// Every member of a campaign, read in a few bulk queries (the runtime's start).
std::unordered_map<std::string, StoredTask> find_campaign_tasks(sql::Connection& db,
                                                                std::int64_t campaign);
// The tasks of one kind with this status (e.g. the cached ones a changed task is compared with).
std::vector<TaskRecord> find_tasks_of_kind(sql::Connection& db, const std::string& kind,
                                           TaskStatus status);
// A campaign as submitted: by name, or the most recently submitted one when name is empty.
struct StoredCampaign {
  std::string name;
  std::string format;
  nlohmann::json document;
};
std::optional<StoredCampaign> find_campaign(sql::Connection& db, const std::string& name);
// The batch jobs of a task, by attempt (none before schema version 2, no job names before 3).
std::vector<JobRecord> find_jobs(sql::Connection& db, const std::string& key);

class Store {
 public:
  Store(const std::filesystem::path& db, const std::vector<ViewDefinition>& views,
        const Clock& clock);

  const std::filesystem::path& path() const { return path_; }
  // For reads shared with the read-only tools (find_task & co.) and for tests; writes go through
  // the methods below.
  sql::Connection& connection() { return db_; }
  // Groups the writes of several methods into one commit (they nest as savepoints).
  sql::Transaction transaction() { return sql::Transaction(db_); }

  // Creates or updates the campaign (its document and membership start afresh) and adds the
  // planned tasks, all in one transaction. Returns the campaign id.
  std::int64_t register_campaign(const std::string& name, const std::string& format,
                                 const nlohmann::json& document,
                                 const std::vector<TaskSpec>& tasks);
  // Adds existing tasks (e.g. children of a cached task) to a campaign.
  void add_members(std::int64_t campaign, const std::vector<std::string>& keys);

  // Marks the task running and returns its attempt number (1 for the first attempt ever).
  int mark_running(const std::string& key);
  // One transaction: result, artifacts, declared children (tasks, edges, membership), status done.
  void commit_done(std::int64_t campaign, const std::string& key, const nlohmann::json& result,
                   const std::vector<StoredArtifact>& artifacts,
                   const std::vector<TaskSpec>& children, double duration_s);
  void mark_finished(const std::string& key, TaskStatus status, int attempt,
                     const std::string& message, double duration_s);
  void mark_skipped(const std::vector<std::string>& keys, const std::string& reason);
  void mark_pending(const std::string& key, const std::string& reason);
  // Records newly submitted jobs, or the new state of known ones (by task and attempt).
  void record_jobs(const std::vector<JobRecord>& jobs);
  void append_log(const std::optional<std::string>& key, const std::string& level,
                  const std::string& message);
  void finish_campaign(std::int64_t campaign, const std::string& outcome);
  void set_coordinator(int pid, const std::string& host, const std::string& campaign);
  void clear_coordinator();

 private:
  void insert_tasks(std::int64_t campaign, const std::vector<TaskSpec>& tasks,
                    const std::optional<std::string>& parent);
  // Prepared once per connection: a task's commit reuses the same handful of statements.
  sql::Statement& statement(std::string_view sql) { return db_.cached(sql); }
  void record_history(const std::string& key, TaskStatus status, int attempt,
                      const std::string& message);

  std::filesystem::path path_;
  const Clock& clock_;
  sql::Connection db_;
};

}  // namespace millflow::engine
