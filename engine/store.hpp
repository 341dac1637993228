#pragma once
// The provenance store: one SQLite file, written by exactly one connection (this class), owned by
// the coordinating thread. Readers open their own read-only connections (open_read_only).
//
// Schema version 6 (PRAGMA user_version = 6); times are Unix seconds (REAL), JSON is canonical
// text.
//   campaigns      id PK, name UNIQUE, format, document (the loaded campaign JSON), submitted_at,
//                  finished_at, outcome ('running'|'done'|'failed'|'interrupted'|'partial':
//                  tasks beyond `--until` left pending), document_sha256 (since version 6: the
//                  SHA-256 hex of the document's text; find_campaign refuses a document that is
//                  not it; NULL in rows of earlier versions, not checked)
//   tasks          key PK (SHA-256 hex), kind, kind_version, params, key_text (exactly what was
//                  hashed: find_task takes the parameters from it, and insert_tasks writes a row
//                  that disagrees with its spec back), parent_key (the task whose result declared
//                  it; NULL for planned tasks), status
//                  ('pending'|'running'|'done'|'failed'|'interrupted'|'skipped'), attempts
//                  (launches ever), created_at, started_at, finished_at, duration_s, host,
//                  code_version, error
//   campaign_tasks campaign_id, task_key: which tasks belong to which campaign (tasks are shared)
//   edges          downstream, position, upstream: the DAG (position = input order)
//   results        task_key PK, result (JSON), committed_at (since version 4 WITHOUT ROWID),
//                  sha256 (since version 5: the SHA-256 hex of the result's text, checked when
//                  the runtime reads whether a task is done: a result that is not its text any
//                  more, or not JSON, is no result and its task runs again; NULL in rows committed
//                  by earlier versions, which are not checked)
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
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "engine/artifacts.hpp"
#include "engine/clock.hpp"
#include "engine/job_executor.hpp"
#include "engine/sqlite.hpp"
#include "engine/task.hpp"

namespace millflow::engine {

inline constexpr int kSchemaVersion = 6;

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

// Read-only connection to an existing database whose schema this build understands. A missing
// file, one without millflow tables and one that is not a readable SQLite database are
// InvalidInput (path "--db").
sql::Connection open_read_only(const std::filesystem::path& db);

// The same for a database that may not hold a campaign yet: none for a missing file or one
// without millflow tables (a first submit killed before creating them), which a submit takes
// as an empty store (the dry run too).
std::optional<sql::Connection> open_read_only_if_submitted(const std::filesystem::path& db);

// Refuses, before anything is written beside it, a database file SQLite cannot read
// (InvalidInput, path "--db") or one of a newer schema (SchemaTooNew). A missing file, or one
// without millflow tables yet, passes.
void check_database_readable(const std::filesystem::path& db);

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
  // And it is JSON with the digest stored beside it: a damaged one counts as none, and the task
  // runs again.
  bool has_result = false;
  bool skipped_its_work = false;  // its result says it skipped its work (RunSummary)
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

// Reads of the inspection and export commands (engine/inspect.hpp, engine/outputs.hpp). A task's
// "shown" status is its status, except "skipped" for a done task whose result says it skipped
// its work (engine/runtime.hpp, RunSummary::skipped_their_work_done and _cached).
std::optional<std::int64_t> find_campaign_id(sql::Connection& db, const std::string& name);
// Up to `limit` task keys starting with `prefix`, in key order.
std::vector<std::string> find_task_keys_with_prefix(sql::Connection& db, const std::string& prefix,
                                                    int limit);
// What `show` prints of a task beside its record: started_at (none before its first launch), and
// SQLite's text of duration_s, host and code_version ('' where NULL).
struct TaskRunInfo {
  std::optional<double> started_at;
  std::string duration_s;
  std::string host;
  std::string code_version;
};
TaskRunInfo find_task_run_info(sql::Connection& db, const std::string& key);
// Every task upstream (inputs, their inputs, ...) or downstream of a task, from the edges table,
// each once, in the order a depth-first walk meets them (inputs by position, outputs by key).
enum class LineageDirection { upstream, downstream };
std::vector<std::string> find_lineage(sql::Connection& db, const std::string& key,
                                      LineageDirection direction);
// A task's log lines, oldest first.
struct LogLine {
  double at = 0;
  std::string level;
  std::string message;
};
std::vector<LogLine> find_log_lines(sql::Connection& db, const std::string& key);
// Every artifact digest some task references.
std::set<std::string> find_referenced_digests(sql::Connection& db);

// A table as the status command prints it: column names (the SQL's) and each cell as SQLite's
// text of it ('' for NULL).
struct TextTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};
// Per campaign, in submission order: campaign, outcome, tasks, done, failed, to_run (pending,
// running or interrupted). Unless a coordinator is running, a campaign left 'running' is shown
// as 'interrupted' (its coordinator died).
TextTable campaign_summaries(sql::Connection& db, bool coordinator_running);
// One campaign's task counts: kind, status (shown), tasks. Unless a coordinator is running, a task
// left 'running' without a batch job of its attempt is shown as 'interrupted'.
TextTable campaign_status_counts(sql::Connection& db, std::int64_t campaign,
                                 bool coordinator_running);
// The same rule for one task: held 'running', no coordinator running, no batch job of its attempt.
bool left_running_by_dead_coordinator(sql::Connection& db, const std::string& key,
                                      bool coordinator_running);
// The batch job of the latest attempt of each running task of the campaign: kind, task (key
// prefix), attempt, executor, job_id, state; empty before schema version 2.
TextTable unfinished_jobs(sql::Connection& db, std::int64_t campaign);

// The campaign's members in the order they were stored, with their shown status.
struct TaskNode {
  std::string key;
  std::string kind;
  std::string shown_status;
};
std::vector<TaskNode> find_campaign_task_nodes(sql::Connection& db, std::int64_t campaign);
// The edges into the campaign's members (upstream, downstream), by downstream and position.
std::vector<std::pair<std::string, std::string>> find_campaign_edges(sql::Connection& db,
                                                                     std::int64_t campaign);
// The campaign's members counted by kind and shown status; first_row orders kinds as stored
// (planned upstream kinds first).
struct KindStatusCount {
  std::string kind;
  std::string shown_status;
  std::int64_t tasks = 0;
  std::int64_t first_row = 0;
};
std::vector<KindStatusCount> count_campaign_tasks_by_kind(sql::Connection& db,
                                                          std::int64_t campaign);
// The task edges into the campaign's members counted per (upstream kind, downstream kind), in
// the order the kinds were stored.
struct KindEdge {
  std::string upstream_kind;
  std::string downstream_kind;
  std::int64_t edges = 0;
};
std::vector<KindEdge> count_campaign_edges_by_kind(sql::Connection& db, std::int64_t campaign);

// The campaign's members with their status, params and result (null before it is done), by kind
// and key: the rows of the task_results view.
struct TaskResultRow {
  std::string task_key;
  std::string kind;
  std::string status;
  nlohmann::json params;
  nlohmann::json result;
};
std::vector<TaskResultRow> find_task_results(sql::Connection& db, const std::string& campaign);
// The done members of a campaign, by key: of one kind, or (kind and key, by kind then key) those
// with at least one artifact.
std::vector<std::string> find_done_task_keys(sql::Connection& db, std::int64_t campaign,
                                             const std::string& kind);
struct KindAndKey {
  std::string kind;
  std::string key;
};
std::vector<KindAndKey> find_done_tasks_with_artifacts(sql::Connection& db, std::int64_t campaign);
// The rows of a view with a task_key column (such as sweep_points, engine/outputs.hpp) whose task
// belongs to the campaign: the view's column names and each row's cells as SQLite's text (none
// for NULL). No value when the database has no such view.
struct ViewRows {
  std::vector<std::string> columns;
  std::vector<std::vector<std::optional<std::string>>> rows;
};
std::optional<ViewRows> find_campaign_view_rows(sql::Connection& db, const std::string& view,
                                                std::int64_t campaign);

// The coordinator row (engine/coordinator_lock.hpp); none when no coordinator ever held the
// database or when the file has no schema yet (a first submit that died before creating it).
struct CoordinatorRecord {
  std::int64_t pid = 0;
  std::string host;
  double started_at = 0;
  std::string campaign;
};
std::optional<CoordinatorRecord> find_coordinator(sql::Connection& db);

// `millflow query`: runs one read-only statement of the user's and returns every row. A
// statement SQLite cannot prepare, one that would write, or one whose rows hold more than
// max_values values (a recursive query without end would fill the memory) is InvalidInput.
struct QueryValue {
  int type = SQLITE_NULL;  // SQLITE_NULL, SQLITE_INTEGER, SQLITE_FLOAT, SQLITE_TEXT or SQLITE_BLOB
  // integer and real are set for their own type only.
  std::int64_t integer = 0;
  double real = 0;
  std::string text;  // SQLite's text of the value ('' for NULL)
};
struct QueryRows {
  std::vector<std::string> columns;
  std::vector<std::vector<QueryValue>> rows;
};
// What one query may return: values, and bytes of their text, in all and in any one value (a
// few large values, zeroblob(1e9) x 41 rows, went past any memory with few values).
inline constexpr std::size_t kMaxQueryValues = 10'000'000;
inline constexpr std::size_t kMaxQueryBytes = std::size_t{256} << 20;
QueryRows run_read_only_query(sql::Connection& db, const std::filesystem::path& db_path,
                              const std::string& sql_text, std::size_t max_values = kMaxQueryValues,
                              std::size_t max_bytes = kMaxQueryBytes);

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
