#include "engine/store.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "engine/canonical_json.hpp"
#include "engine/validation.hpp"
#include "engine/version.hpp"
#include "util/sha256.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;

// Migration i takes the schema from version i to i + 1. Append only; never edit a released one.
const std::vector<std::string>& schema_migrations() {
  static const std::vector<std::string> steps = {
      R"sql(
CREATE TABLE campaigns (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  format TEXT NOT NULL,
  document TEXT NOT NULL,
  submitted_at REAL NOT NULL,
  finished_at REAL,
  outcome TEXT NOT NULL DEFAULT 'running'
);
CREATE TABLE tasks (
  key TEXT PRIMARY KEY,
  kind TEXT NOT NULL,
  kind_version TEXT NOT NULL,
  params TEXT NOT NULL,
  key_text TEXT NOT NULL,
  parent_key TEXT REFERENCES tasks(key),
  status TEXT NOT NULL DEFAULT 'pending'
    CHECK (status IN ('pending', 'running', 'done', 'failed', 'interrupted', 'skipped')),
  attempts INTEGER NOT NULL DEFAULT 0,
  created_at REAL NOT NULL,
  started_at REAL,
  finished_at REAL,
  duration_s REAL,
  host TEXT,
  code_version TEXT,
  error TEXT
);
CREATE INDEX tasks_by_kind ON tasks(kind, status);
CREATE INDEX tasks_by_parent ON tasks(parent_key);
CREATE TABLE campaign_tasks (
  campaign_id INTEGER NOT NULL REFERENCES campaigns(id) ON DELETE CASCADE,
  task_key TEXT NOT NULL REFERENCES tasks(key),
  PRIMARY KEY (campaign_id, task_key)
) WITHOUT ROWID;
CREATE INDEX campaign_tasks_by_task ON campaign_tasks(task_key);
CREATE TABLE edges (
  downstream TEXT NOT NULL REFERENCES tasks(key),
  position INTEGER NOT NULL,
  upstream TEXT NOT NULL REFERENCES tasks(key),
  PRIMARY KEY (downstream, position)
) WITHOUT ROWID;
CREATE INDEX edges_by_upstream ON edges(upstream);
CREATE TABLE results (
  task_key TEXT PRIMARY KEY REFERENCES tasks(key),
  result TEXT NOT NULL,
  committed_at REAL NOT NULL
);
CREATE TABLE artifacts (
  task_key TEXT NOT NULL REFERENCES tasks(key),
  name TEXT NOT NULL,
  sha256 TEXT NOT NULL,
  size INTEGER NOT NULL,
  path TEXT NOT NULL,
  PRIMARY KEY (task_key, name)
);
CREATE INDEX artifacts_by_digest ON artifacts(sha256);
CREATE TABLE status_history (
  id INTEGER PRIMARY KEY,
  task_key TEXT NOT NULL REFERENCES tasks(key),
  status TEXT NOT NULL,
  attempt INTEGER NOT NULL,
  at REAL NOT NULL,
  message TEXT
);
CREATE INDEX status_history_by_task ON status_history(task_key);
CREATE TABLE log_lines (
  id INTEGER PRIMARY KEY,
  task_key TEXT REFERENCES tasks(key),
  at REAL NOT NULL,
  level TEXT NOT NULL,
  message TEXT NOT NULL
);
CREATE TABLE coordinator (
  id INTEGER PRIMARY KEY CHECK (id = 1),
  pid INTEGER NOT NULL,
  host TEXT NOT NULL,
  started_at REAL NOT NULL,
  campaign TEXT
);
CREATE VIEW task_results AS
  SELECT c.name AS campaign, t.key AS task_key, t.kind, t.status, t.params, r.result
  FROM campaign_tasks ct
  JOIN campaigns c ON c.id = ct.campaign_id
  JOIN tasks t ON t.key = ct.task_key
  LEFT JOIN results r ON r.task_key = t.key;
)sql",
      R"sql(
CREATE TABLE jobs (
  task_key TEXT NOT NULL REFERENCES tasks(key),
  attempt INTEGER NOT NULL,
  executor TEXT NOT NULL,
  job_id TEXT NOT NULL,
  state TEXT NOT NULL,
  output_dir TEXT NOT NULL,
  stdout_path TEXT NOT NULL,
  stderr_path TEXT NOT NULL,
  submitted_at REAL NOT NULL,
  updated_at REAL NOT NULL,
  PRIMARY KEY (task_key, attempt)
);
)sql",
      R"sql(
ALTER TABLE jobs ADD COLUMN job_name TEXT NOT NULL DEFAULT '';
)sql",
      // Fewer pages written per task commit (each page is a WAL frame): the kind index no longer
      // holds the status, so status changes leave it alone; status_history is not indexed (it is
      // written on every status change and read only by audits); results become a WITHOUT ROWID
      // table, one b-tree instead of a table and its key index. Views are left alone by the rename
      // (legacy_alter_table): they name results, which exists again when the step commits.
      R"sql(
DROP INDEX tasks_by_kind;
CREATE INDEX tasks_by_kind ON tasks(kind);
DROP INDEX status_history_by_task;
CREATE TABLE results_rebuilt (
  task_key TEXT PRIMARY KEY REFERENCES tasks(key),
  result TEXT NOT NULL,
  committed_at REAL NOT NULL
) WITHOUT ROWID;
INSERT INTO results_rebuilt (task_key, result, committed_at) SELECT task_key, result, committed_at FROM results;
DROP TABLE results;
PRAGMA legacy_alter_table = ON;
ALTER TABLE results_rebuilt RENAME TO results;
PRAGMA legacy_alter_table = OFF;
)sql",
      // Each result's SHA-256 (hex) of its text: a result changed in the file, to other valid
      // JSON, reads as no result, and its task runs again. Rows of earlier versions keep NULL and
      // are not checked.
      R"sql(
ALTER TABLE results ADD COLUMN sha256 TEXT;
)sql",
      // The same for each campaign's document, which `resume` runs: a changed one is a damaged
      // store.
      R"sql(
ALTER TABLE campaigns ADD COLUMN document_sha256 TEXT;
)sql",
  };
  return steps;
}

namespace {

// The schema version, or InvalidInput when the file is not a readable SQLite database.
int readable_user_version(sql::Connection& connection, const fs::path& db) {
  try {
    return connection.user_version();
  } catch (const sql::Error& error) {
    // Reading a WAL database takes its -shm file, which SQLite creates when it is missing: in a
    // directory the user cannot write, even reading fails.
    if (std::string_view(error.what()).find("attempt to write a readonly database") !=
        std::string_view::npos) {
      throw InvalidInput({{"--db",
                           fmt::format("{} cannot be read where it is: SQLite needs to create "
                                       "{}-shm beside it ({})",
                                       db.string(), db.string(), error.what()),
                           "copy the database to a directory you can write and pass the copy"}});
    }
    if (!is_damaged_database_error(error.what())) throw;
    throw InvalidInput(
        {{"--db", damaged_database_problem(db, error.what()), damaged_database_fix(db)}});
  }
}

void refuse_newer_schema(const fs::path& db, int version) {
  if (version > kSchemaVersion) {
    throw SchemaTooNew(fmt::format(
        "database {} has schema version {}, but this millflow ({}) understands versions up to {}: "
        "use a newer millflow, or another --db",
        db.string(), version, code_version(), kSchemaVersion));
  }
}

void migrate(sql::Connection& db, const fs::path& path) {
  const int current = db.user_version();
  refuse_newer_schema(path, current);
  for (int version = current; version < kSchemaVersion; ++version) {
    sql::Transaction transaction(db);
    db.exec(schema_migrations()[static_cast<size_t>(version)]);
    db.exec(fmt::format("PRAGMA user_version = {}", version + 1));
    transaction.commit();
  }
}

void install_views(sql::Connection& db, const std::vector<ViewDefinition>& views) {
  if (views.empty()) return;
  sql::Transaction transaction(db);
  for (const auto& view : views) {
    db.exec("DROP VIEW IF EXISTS \"" + view.name + "\"");
    db.exec("CREATE VIEW \"" + view.name + "\" AS " + view.select_sql);
  }
  transaction.commit();
}

fs::path beside(const fs::path& db, const std::string& suffix) {
  return db.parent_path() / (db.filename().string() + suffix);
}

constexpr std::array<std::string_view, 6> kStatusNames = {"pending", "running",     "done",
                                                          "failed",  "interrupted", "skipped"};

}  // namespace

std::string_view to_string(TaskStatus status) {
  return kStatusNames.at(static_cast<size_t>(status));
}

TaskStatus task_status_from(std::string_view text) {
  for (size_t i = 0; i < kStatusNames.size(); ++i) {
    if (kStatusNames[i] == text) return static_cast<TaskStatus>(i);
  }
  throw std::runtime_error("unknown task status '" + std::string(text) + "' in the store");
}

fs::path artifacts_dir(const fs::path& db) {
  return beside(db, ".artifacts");
}
fs::path work_dir(const fs::path& db) {
  return beside(db, ".work");
}
fs::path jobs_dir(const fs::path& db) {
  return beside(db, ".jobs");
}
fs::path lock_file(const fs::path& db) {
  return beside(db, ".lock");
}
fs::path logs_dir(const fs::path& db) {
  return beside(db, ".logs");
}

bool is_damaged_database_error(std::string_view sqlite_message) {
  return sqlite_message.find("file is not a database") != std::string_view::npos ||
         sqlite_message.find("database disk image is malformed") != std::string_view::npos ||
         sqlite_message.find("malformed database schema") != std::string_view::npos;
}

std::string damaged_database_problem(const fs::path& db, std::string_view sqlite_message) {
  return fmt::format("{} is not a readable millflow database (SQLite: {})", db.string(),
                     sqlite_message);
}

std::string damaged_database_fix(const fs::path& db) {
  return fmt::format(
      "check that --db names the right file; if it does, the file is damaged: restore it from a "
      "backup (`sqlite3 {} 'PRAGMA integrity_check'` shows the damage)",
      db.string());
}

std::optional<sql::Connection> open_read_only_if_submitted(const fs::path& db) {
  if (!fs::exists(db)) return std::nullopt;
  sql::Connection connection(db, sql::Access::read_only);
  const int version = readable_user_version(connection, db);
  if (version == 0) return std::nullopt;  // the schema and its version are committed together
  refuse_newer_schema(db, version);
  return connection;
}

sql::Connection open_read_only(const fs::path& db) {
  if (!fs::exists(db)) {
    throw InvalidInput(
        {{"--db", "no database at " + db.string(), "submit a campaign first, or pass --db"}});
  }
  std::optional<sql::Connection> connection = open_read_only_if_submitted(db);
  if (!connection) {  // bad input, as a file that is no database is: exit 2, not a failed run
    throw InvalidInput({{"--db",
                         "the database " + db.string() +
                             " has no millflow tables (nothing was submitted to it, or its first "
                             "submit stopped before creating them)",
                         "submit the campaign again"}});
  }
  return std::move(*connection);
}

void check_database_readable(const fs::path& db) {
  if (!fs::exists(db)) return;
  sql::Connection connection(db, sql::Access::read_only);
  refuse_newer_schema(db, readable_user_version(connection, db));
}

// JSON text the store holds, parsed; text that is not JSON (a byte of the file changed) is a
// damaged store, named, with what to do: the library's parse error said neither.
nlohmann::json stored_json(const std::string& text, const std::string& what) {
  nlohmann::json parsed = nlohmann::json::parse(text, nullptr, false);
  if (!parsed.is_discarded()) return parsed;
  throw InvalidInput({{"--db", "the stored " + what + " is not JSON: the database is damaged",
                       "submit the campaign again, which runs a task whose result is damaged "
                       "again; for a damaged campaign or parameters, restore the database from a "
                       "backup"}});
}

std::optional<TaskRecord> find_task(sql::Connection& db, const std::string& key) {
  auto row = db.prepare(
      "SELECT kind, kind_version, key_text, parent_key, status, attempts, coalesce(error, '') "
      "FROM tasks WHERE key = ?");
  row.bind_all(key);
  if (!row.step()) return std::nullopt;
  // The parameters as hashed into the key: the key text's, when it still hashes to the key (the
  // params column is a copy for the views, which a changed byte could make another task's).
  const std::string key_text = row.text(2);
  if (util::sha256_hex(key_text) != key) {
    throw InvalidInput({{"--db",
                         "the stored key text of task " + key +
                             " does not hash to its key: the database is damaged",
                         "submit the campaign again, which writes a planned task's key text "
                         "anew; for a task another declared, restore the database from a backup"}});
  }
  TaskRecord record;
  record.spec = TaskSpec{
      .key = key,
      .kind = row.text(0),
      .version = row.text(1),
      .params = stored_json(std::string(key_text_params(key_text)), "parameters of task " + key),
      .upstream = {},
      .key_text = key_text};
  if (!row.is_null(3)) record.parent_key = row.text(3);
  record.status = task_status_from(row.text(4));
  record.attempts = static_cast<int>(row.integer(5));
  record.error = row.text(6);
  auto edges = db.prepare("SELECT upstream FROM edges WHERE downstream = ? ORDER BY position");
  edges.bind_all(key);
  while (edges.step()) record.spec.upstream.push_back(edges.text(0));
  return record;
}

std::optional<nlohmann::json> find_result(sql::Connection& db, const std::string& key) {
  auto row = db.prepare("SELECT result FROM results WHERE task_key = ?");
  row.bind_all(key);
  if (!row.step()) return std::nullopt;
  return stored_json(row.text(0), "result of task " + key);
}

std::vector<StoredArtifact> find_artifacts(sql::Connection& db, const std::string& key) {
  auto rows =
      db.prepare("SELECT name, sha256, size FROM artifacts WHERE task_key = ? ORDER BY name");
  rows.bind_all(key);
  std::vector<StoredArtifact> artifacts;
  while (rows.step()) artifacts.push_back({rows.text(0), rows.text(1), rows.integer(2)});
  return artifacts;
}

std::vector<std::string> child_keys(sql::Connection& db, const std::string& parent_key) {
  auto rows = db.prepare("SELECT key FROM tasks WHERE parent_key = ? ORDER BY rowid");
  rows.bind_all(parent_key);
  std::vector<std::string> keys;
  while (rows.step()) keys.push_back(rows.text(0));
  return keys;
}

std::optional<StoredCampaign> find_campaign(sql::Connection& db, const std::string& name) {
  const std::string columns =
      fmt::format("name, format, document, {}", db.user_version() < 6 ? "NULL" : "document_sha256");
  auto row = db.prepare(
      name.empty()
          ? fmt::format("SELECT {} FROM campaigns ORDER BY submitted_at DESC, id DESC LIMIT 1",
                        columns)
          : fmt::format("SELECT {} FROM campaigns WHERE name = ?", columns));
  if (!name.empty()) row.bind_all(name);
  if (!row.step()) return std::nullopt;
  const std::string text = row.text(2);
  if (!row.is_null(3) && util::sha256_hex(text) != row.text(3)) {
    throw InvalidInput({{"--db",
                         "the stored document of campaign " + row.text(0) +
                             " is not the text submitted: the database is damaged",
                         "submit the campaign file again (resume runs what the store holds)"}});
  }
  return StoredCampaign{row.text(0), row.text(1),
                        stored_json(text, "document of campaign " + row.text(0))};
}

namespace {

// A task's result says it skipped its work (r: results; RunSummary::skipped_their_work_done and
// _cached). CASE, not AND: SQLite does not promise to skip the second operand of AND, and
// json_extract on text that is not JSON (a damaged result) fails the whole query.
constexpr std::string_view kResultSaysSkipped =
    "CASE WHEN json_valid(r.result) THEN json_extract(r.result, '$.skipped') IS NOT NULL ELSE 0 "
    "END";

// A task's status as shown (t: tasks, r: results): "skipped" for a done task whose result says
// it skipped its work.
const std::string& shown_status() {
  static const std::string status = fmt::format(
      "CASE WHEN t.status = 'done' AND {} THEN 'skipped' ELSE t.status END", kResultSaysSkipped);
  return status;
}

// A stored task's columns (t: tasks, r: results), from column `first` on: what StoredTask holds
// but its artifacts and children (the result and its digest, which stored_task_from checks).
std::string stored_task_columns(sql::Connection& db) {
  return fmt::format("t.status, t.attempts, coalesce(t.error, ''), r.result, {}, {}",
                     db.user_version() < 5 ? "NULL" : "r.sha256", kResultSaysSkipped);
}
// A result counts when it has the digest the store holds beside it (the canonical JSON that was
// committed), or, in a row of a version without digests, when it is JSON.
bool result_intact(sql::Statement& row, int result, int digest) {
  if (row.is_null(result)) return false;
  const std::string text = row.text(result);
  return row.is_null(digest) ? nlohmann::json::accept(text)
                             : util::sha256_hex(text) == row.text(digest);
}
StoredTask stored_task_from(sql::Statement& row, int first) {
  return StoredTask{.status = task_status_from(row.text(first)),
                    .attempts = static_cast<int>(row.integer(first + 1)),
                    .error = row.text(first + 2),
                    .has_result = result_intact(row, first + 3, first + 4),
                    .skipped_its_work = row.integer(first + 5) != 0,
                    .artifacts = {},
                    .children = {}};
}

}  // namespace

std::optional<StoredTask> find_stored_task(sql::Connection& db, const std::string& key) {
  auto row = db.prepare(fmt::format(
      "SELECT {} FROM tasks t LEFT JOIN results r ON r.task_key = t.key WHERE t.key = ?",
      stored_task_columns(db)));
  row.bind_all(key);
  if (!row.step()) return std::nullopt;
  StoredTask task = stored_task_from(row, 0);
  task.artifacts = find_artifacts(db, key);
  task.children = child_keys(db, key);
  return task;
}

std::unordered_map<std::string, StoredTask> find_campaign_tasks(sql::Connection& db,
                                                                std::int64_t campaign) {
  std::unordered_map<std::string, StoredTask> tasks;
  auto rows = db.prepare(
      fmt::format("SELECT t.key, {} FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key "
                  "LEFT JOIN results r ON r.task_key = t.key WHERE ct.campaign_id = ?",
                  stored_task_columns(db)));
  rows.bind_all(campaign);
  while (rows.step()) tasks.emplace(rows.text(0), stored_task_from(rows, 1));
  auto artifacts = db.prepare(
      "SELECT a.task_key, a.name, a.sha256, a.size FROM campaign_tasks ct JOIN artifacts a ON "
      "a.task_key = ct.task_key WHERE ct.campaign_id = ? ORDER BY a.task_key, a.name");
  artifacts.bind_all(campaign);
  while (artifacts.step()) {
    tasks.at(artifacts.text(0))
        .artifacts.push_back({artifacts.text(1), artifacts.text(2), artifacts.integer(3)});
  }
  auto children = db.prepare(
      "SELECT t.parent_key, t.key FROM campaign_tasks ct JOIN tasks t ON t.parent_key = "
      "ct.task_key WHERE ct.campaign_id = ? ORDER BY t.rowid");
  children.bind_all(campaign);
  while (children.step()) tasks.at(children.text(0)).children.push_back(children.text(1));
  return tasks;
}

std::vector<TaskRecord> find_tasks_of_kind(sql::Connection& db, const std::string& kind,
                                           TaskStatus status) {
  auto rows = db.prepare("SELECT key FROM tasks WHERE kind = ? AND status = ? ORDER BY key");
  rows.bind_all(kind, to_string(status));
  std::vector<TaskRecord> tasks;
  while (rows.step()) tasks.push_back(*find_task(db, rows.text(0)));
  return tasks;
}

std::vector<JobRecord> find_jobs(sql::Connection& db, const std::string& key) {
  std::vector<JobRecord> jobs;
  const int version = db.user_version();
  if (version < 2) return jobs;
  auto rows =
      db.prepare(fmt::format("SELECT attempt, executor, job_id, state, {}, output_dir, "
                             "stdout_path, stderr_path FROM jobs WHERE task_key = ? "
                             "ORDER BY attempt",
                             version < 3 ? "''" : "job_name"));
  rows.bind_all(key);
  while (rows.step()) {
    jobs.push_back(JobRecord{key, static_cast<int>(rows.integer(0)), rows.text(1), rows.text(2),
                             rows.text(3), rows.text(4), rows.text(5), rows.text(6), rows.text(7)});
  }
  return jobs;
}

Store::Store(const fs::path& db, const std::vector<ViewDefinition>& views, const Clock& clock)
    : path_(db), clock_(clock), db_(db, sql::Access::read_write) {
  // Check the version before anything can write (journal_mode changes the file header).
  refuse_newer_schema(db, readable_user_version(db_, db));
  db_.exec("PRAGMA journal_mode = WAL");
  db_.exec("PRAGMA synchronous = NORMAL");
  // Checkpoint every ~16 MB of WAL instead of 4 MB: task commits rewrite the same few pages, and
  // a checkpoint writes each of them (and syncs) once.
  db_.exec("PRAGMA wal_autocheckpoint = 4000");
  // Up to 64 MiB of page cache instead of 2 MiB: a 10,000-task campaign's tables and indexes
  // (~10 MB) stay in memory, so registering it does not spill and a commit's lookups do not read.
  db_.exec("PRAGMA cache_size = -65536");
  migrate(db_, db);
  install_views(db_, views);
}

std::int64_t Store::register_campaign(const std::string& name, const std::string& format,
                                      const nlohmann::json& document,
                                      const std::vector<TaskSpec>& tasks) {
  sql::Transaction transaction(db_);
  const std::string text = canonical_json(document);
  statement(
      "INSERT INTO campaigns (name, format, document, submitted_at, document_sha256) VALUES (?, "
      "?, ?, ?, ?) ON CONFLICT(name) DO UPDATE SET format = excluded.format, document = "
      "excluded.document, submitted_at = excluded.submitted_at, finished_at = NULL, outcome = "
      "'running', document_sha256 = excluded.document_sha256")
      .bind_all(name, format, text, clock_.now(), util::sha256_hex(text))
      .run();
  auto& id_row = statement("SELECT id FROM campaigns WHERE name = ?");
  id_row.bind_all(name);
  id_row.step();
  const std::int64_t campaign = id_row.integer(0);
  id_row.reset();
  statement("DELETE FROM campaign_tasks WHERE campaign_id = ?").bind_all(campaign).run();
  insert_tasks(campaign, tasks, std::nullopt);
  transaction.commit();
  return campaign;
}

void Store::insert_tasks(std::int64_t campaign, const std::vector<TaskSpec>& tasks,
                         const std::optional<std::string>& parent) {
  // A task's key is the SHA-256 of its key text, which holds its kind, version and parameters:
  // a stored row that says otherwise was changed behind the store's back, and the spec, whose
  // key text hashes to the key, puts it right (a row that agrees is not written).
  auto& task = statement(
      "INSERT INTO tasks (key, kind, kind_version, params, key_text, parent_key, created_at) "
      "VALUES (?, ?, ?, ?, ?, ?, ?) ON CONFLICT (key) DO UPDATE SET kind = excluded.kind, "
      "kind_version = excluded.kind_version, params = excluded.params, key_text = "
      "excluded.key_text WHERE tasks.kind IS NOT excluded.kind OR tasks.kind_version IS NOT "
      "excluded.kind_version OR tasks.params IS NOT excluded.params OR tasks.key_text IS NOT "
      "excluded.key_text");
  auto& edge =
      statement("INSERT OR IGNORE INTO edges (downstream, position, upstream) VALUES (?, ?, ?)");
  auto& member =
      statement("INSERT OR IGNORE INTO campaign_tasks (campaign_id, task_key) VALUES (?, ?)");
  const double now = clock_.now();
  for (const auto& spec : tasks) {
    task.bind_all(spec.key, spec.kind, spec.version, canonical_json(spec.params), spec.key_text,
                  parent, now);
    task.run();
    for (size_t position = 0; position < spec.upstream.size(); ++position) {
      edge.bind_all(spec.key, static_cast<std::int64_t>(position), spec.upstream[position]);
      edge.run();
    }
    member.bind_all(campaign, spec.key);
    member.run();
  }
}

void Store::add_members(std::int64_t campaign, const std::vector<std::string>& keys) {
  sql::Transaction transaction(db_);
  auto& member =
      statement("INSERT OR IGNORE INTO campaign_tasks (campaign_id, task_key) VALUES (?, ?)");
  for (const auto& key : keys) {
    member.bind_all(campaign, key);
    member.run();
  }
  transaction.commit();
}

void Store::record_history(const std::string& key, TaskStatus status, int attempt,
                           const std::string& message) {
  statement(
      "INSERT INTO status_history (task_key, status, attempt, at, message) VALUES (?, ?, ?, ?, ?)")
      .bind_all(key, to_string(status), attempt, clock_.now(), message)
      .run();
}

int Store::mark_running(const std::string& key) {
  static const std::string host = host_name();
  sql::Transaction transaction(db_);
  auto& update = statement(
      "UPDATE tasks SET status = 'running', attempts = attempts + 1, started_at = ?, finished_at = "
      "NULL, "
      "duration_s = NULL, host = ?, code_version = ?, error = NULL WHERE key = ? RETURNING "
      "attempts");
  update.bind_all(clock_.now(), host, code_version(), key);
  update.step();
  const int attempt = static_cast<int>(update.integer(0));
  update.reset();
  record_history(key, TaskStatus::running, attempt, "");
  transaction.commit();
  return attempt;
}

void Store::commit_done(std::int64_t campaign, const std::string& key, const nlohmann::json& result,
                        const std::vector<StoredArtifact>& artifacts,
                        const std::vector<TaskSpec>& children, double duration_s) {
  sql::Transaction transaction(db_);
  const double now = clock_.now();
  const std::string text = canonical_json(result);
  statement(
      "INSERT OR REPLACE INTO results (task_key, result, committed_at, sha256) VALUES (?, ?, ?, ?)")
      .bind_all(key, text, now, util::sha256_hex(text))
      .run();
  statement("DELETE FROM artifacts WHERE task_key = ?").bind_all(key).run();
  auto& artifact = statement(
      "INSERT INTO artifacts (task_key, name, sha256, size, path) VALUES (?, ?, ?, ?, ?)");
  const std::string artifact_root = artifacts_dir(path_).filename().string();
  for (const auto& stored : artifacts) {
    artifact.bind_all(key, stored.name, stored.sha256, stored.size,
                      artifact_root + "/" + stored.sha256.substr(0, 2) + "/" + stored.sha256);
    artifact.run();
  }
  insert_tasks(campaign, children, key);
  auto& update = statement(
      "UPDATE tasks SET status = 'done', finished_at = ?, duration_s = ?, error = NULL WHERE key = "
      "? "
      "RETURNING attempts");
  update.bind_all(now, duration_s, key);
  update.step();
  const int attempt = static_cast<int>(update.integer(0));
  update.reset();
  record_history(key, TaskStatus::done, attempt, "");
  transaction.commit();
}

void Store::mark_finished(const std::string& key, TaskStatus status, int attempt,
                          const std::string& message, double duration_s) {
  sql::Transaction transaction(db_);
  statement("UPDATE tasks SET status = ?, finished_at = ?, duration_s = ?, error = ? WHERE key = ?")
      .bind_all(to_string(status), clock_.now(), duration_s, message, key)
      .run();
  record_history(key, status, attempt, message);
  transaction.commit();
}

void Store::mark_skipped(const std::vector<std::string>& keys, const std::string& reason) {
  if (keys.empty()) return;
  sql::Transaction transaction(db_);
  auto& update =
      statement("UPDATE tasks SET status = 'skipped', error = ? WHERE key = ? RETURNING attempts");
  for (const auto& key : keys) {
    update.bind_all(reason, key);
    update.step();
    const int attempt = static_cast<int>(update.integer(0));
    update.reset();
    record_history(key, TaskStatus::skipped, attempt, reason);
  }
  transaction.commit();
}

void Store::mark_pending(const std::string& key, const std::string& reason) {
  sql::Transaction transaction(db_);
  auto& update =
      statement("UPDATE tasks SET status = 'pending', error = ? WHERE key = ? RETURNING attempts");
  update.bind_all(reason, key);
  update.step();
  const int attempt = static_cast<int>(update.integer(0));
  update.reset();
  record_history(key, TaskStatus::pending, attempt, reason);
  transaction.commit();
}

void Store::record_jobs(const std::vector<JobRecord>& jobs) {
  if (jobs.empty()) return;
  sql::Transaction transaction(db_);
  auto& upsert = statement(
      "INSERT INTO jobs (task_key, attempt, executor, job_id, state, job_name, output_dir, "
      "stdout_path, stderr_path, "
      "submitted_at, updated_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
      "ON CONFLICT(task_key, attempt) DO UPDATE SET job_id = excluded.job_id, state = "
      "excluded.state, "
      "updated_at = excluded.updated_at");
  const double now = clock_.now();
  for (const auto& job : jobs) {
    upsert.bind_all(job.task_key, job.attempt, job.executor, job.job_id, job.state, job.job_name,
                    job.output_dir.string(), job.stdout_file.string(), job.stderr_file.string(),
                    now, now);
    upsert.run();
  }
  transaction.commit();
}

void Store::append_log(const std::optional<std::string>& key, const std::string& level,
                       const std::string& message) {
  statement("INSERT INTO log_lines (task_key, at, level, message) VALUES (?, ?, ?, ?)")
      .bind_all(key, clock_.now(), level, message)
      .run();
}

void Store::finish_campaign(std::int64_t campaign, const std::string& outcome) {
  statement("UPDATE campaigns SET finished_at = ?, outcome = ? WHERE id = ?")
      .bind_all(clock_.now(), outcome, campaign)
      .run();
}

void Store::set_coordinator(int pid, const std::string& host, const std::string& campaign) {
  statement(
      "INSERT OR REPLACE INTO coordinator (id, pid, host, started_at, campaign) VALUES (1, ?, ?, "
      "?, ?)")
      .bind_all(pid, host, clock_.now(), campaign)
      .run();
}

void Store::clear_coordinator() {
  db_.exec("DELETE FROM coordinator");
}

namespace {

TextTable read_text_table(sql::Statement& statement) {
  TextTable table;
  for (int column = 0; column < statement.columns(); ++column)
    table.header.push_back(statement.column_name(column));
  while (statement.step()) {
    std::vector<std::string> row;
    for (int column = 0; column < statement.columns(); ++column)
      row.push_back(statement.text(column));
    table.rows.push_back(std::move(row));
  }
  return table;
}

}  // namespace

std::optional<std::int64_t> find_campaign_id(sql::Connection& db, const std::string& name) {
  auto row = db.prepare("SELECT id FROM campaigns WHERE name = ?");
  row.bind_all(name);
  if (!row.step()) return std::nullopt;
  return row.integer(0);
}

std::vector<std::string> find_task_keys_with_prefix(sql::Connection& db, const std::string& prefix,
                                                    int limit) {
  auto rows =
      db.prepare("SELECT key FROM tasks WHERE key >= ? AND key < ? || 'g' ORDER BY key LIMIT ?");
  rows.bind_all(prefix, prefix, limit);
  std::vector<std::string> keys;
  while (rows.step()) keys.push_back(rows.text(0));
  return keys;
}

TaskRunInfo find_task_run_info(sql::Connection& db, const std::string& key) {
  auto row = db.prepare(
      "SELECT started_at, coalesce(duration_s, ''), coalesce(host, ''), coalesce(code_version, '') "
      "FROM tasks WHERE key = ?");
  row.bind_all(key);
  row.step();
  TaskRunInfo info;
  if (!row.is_null(0)) info.started_at = row.real(0);
  info.duration_s = row.text(1);
  info.host = row.text(2);
  info.code_version = row.text(3);
  return info;
}

std::vector<std::string> find_lineage(sql::Connection& db, const std::string& key,
                                      LineageDirection direction) {
  auto next =
      db.prepare(direction == LineageDirection::upstream
                     ? "SELECT upstream FROM edges WHERE downstream = ? ORDER BY position"
                     : "SELECT downstream FROM edges WHERE upstream = ? ORDER BY downstream");
  std::vector<std::string> found;
  std::set<std::string> seen{key};
  std::vector<std::string> frontier{key};
  while (!frontier.empty()) {
    const std::string current = frontier.back();
    frontier.pop_back();
    next.bind_all(current);
    while (next.step()) {
      const std::string other = next.text(0);
      if (seen.insert(other).second) {
        found.push_back(other);
        frontier.push_back(other);
      }
    }
  }
  return found;
}

std::vector<LogLine> find_log_lines(sql::Connection& db, const std::string& key) {
  auto rows = db.prepare("SELECT at, level, message FROM log_lines WHERE task_key = ? ORDER BY id");
  rows.bind_all(key);
  std::vector<LogLine> lines;
  while (rows.step()) lines.push_back({rows.real(0), rows.text(1), rows.text(2)});
  return lines;
}

std::set<std::string> find_referenced_digests(sql::Connection& db) {
  auto rows = db.prepare("SELECT DISTINCT sha256 FROM artifacts");
  std::set<std::string> digests;
  while (rows.step()) digests.insert(rows.text(0));
  return digests;
}

TextTable campaign_summaries(sql::Connection& db, bool coordinator_running) {
  auto rows = db.prepare(
      "SELECT c.name AS campaign, CASE WHEN c.outcome = 'running' AND NOT ? THEN 'interrupted' "
      "ELSE c.outcome END AS outcome, count(t.key) AS tasks, sum(t.status = 'done') AS done, "
      "sum(t.status = 'failed') AS failed, sum(t.status IN ('pending', 'running', "
      "'interrupted')) AS to_run "
      "FROM campaigns c LEFT JOIN campaign_tasks ct ON ct.campaign_id = c.id LEFT JOIN tasks t "
      "ON t.key = ct.task_key "
      "GROUP BY c.id ORDER BY c.submitted_at");
  rows.bind_all(coordinator_running ? 1 : 0);
  return read_text_table(rows);
}

namespace {

// True for a task row `t` left 'running' by a coordinator that died (the one parameter: whether a
// coordinator runs now), unless a batch job of its current attempt may still run it (resume
// re-attaches to it): such a task is interrupted.
std::string left_running_sql(sql::Connection& db) {
  const std::string has_job = db.user_version() < 2
                                  ? "0"
                                  : "EXISTS (SELECT 1 FROM jobs j WHERE j.task_key = t.key AND "
                                    "j.attempt = t.attempts)";
  return fmt::format("(t.status = 'running' AND NOT ? AND NOT {})", has_job);
}

}  // namespace

bool left_running_by_dead_coordinator(sql::Connection& db, const std::string& key,
                                      bool coordinator_running) {
  auto row =
      db.prepare(fmt::format("SELECT {} FROM tasks t WHERE t.key = ?", left_running_sql(db)));
  row.bind_all(coordinator_running ? 1 : 0, key);
  return row.step() && row.integer(0) != 0;
}

TextTable campaign_status_counts(sql::Connection& db, std::int64_t campaign,
                                 bool coordinator_running) {
  auto rows = db.prepare(fmt::format(
      "SELECT t.kind, CASE WHEN {} THEN 'interrupted' ELSE {} END AS status, count(*) AS tasks "
      "FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key LEFT JOIN results r ON "
      "r.task_key = t.key WHERE ct.campaign_id = ? GROUP BY t.kind, 2 ORDER BY t.kind, 2",
      left_running_sql(db), shown_status()));
  rows.bind_all(coordinator_running ? 1 : 0, campaign);
  return read_text_table(rows);
}

TextTable unfinished_jobs(sql::Connection& db, std::int64_t campaign) {
  if (db.user_version() < 2) return {};
  auto rows = db.prepare(
      "SELECT t.kind, substr(t.key, 1, 16) AS task, j.attempt, j.executor, j.job_id, j.state FROM "
      "campaign_tasks ct "
      "JOIN tasks t ON t.key = ct.task_key JOIN jobs j ON j.task_key = t.key AND j.attempt = "
      "t.attempts "
      "WHERE ct.campaign_id = ? AND t.status = 'running' ORDER BY j.job_id");
  rows.bind_all(campaign);
  return read_text_table(rows);
}

std::vector<TaskNode> find_campaign_task_nodes(sql::Connection& db, std::int64_t campaign) {
  auto rows = db.prepare(fmt::format(
      "SELECT t.key, t.kind, {} FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key LEFT "
      "JOIN results r ON r.task_key = t.key WHERE ct.campaign_id = ? ORDER BY t.rowid",
      shown_status()));
  rows.bind_all(campaign);
  std::vector<TaskNode> nodes;
  while (rows.step()) nodes.push_back({rows.text(0), rows.text(1), rows.text(2)});
  return nodes;
}

std::vector<std::pair<std::string, std::string>> find_campaign_edges(sql::Connection& db,
                                                                     std::int64_t campaign) {
  auto rows = db.prepare(
      "SELECT e.upstream, e.downstream FROM edges e JOIN campaign_tasks ct ON ct.task_key = "
      "e.downstream WHERE ct.campaign_id = ? ORDER BY e.downstream, e.position");
  rows.bind_all(campaign);
  std::vector<std::pair<std::string, std::string>> edges;
  while (rows.step()) edges.emplace_back(rows.text(0), rows.text(1));
  return edges;
}

std::vector<KindStatusCount> count_campaign_tasks_by_kind(sql::Connection& db,
                                                          std::int64_t campaign) {
  auto rows = db.prepare(fmt::format(
      "SELECT t.kind, {} AS shown, count(*), min(t.rowid) FROM campaign_tasks ct JOIN tasks t ON "
      "t.key = ct.task_key LEFT JOIN results r ON r.task_key = t.key WHERE ct.campaign_id = ? "
      "GROUP BY t.kind, shown",
      shown_status()));
  rows.bind_all(campaign);
  std::vector<KindStatusCount> counts;
  while (rows.step())
    counts.push_back({rows.text(0), rows.text(1), rows.integer(2), rows.integer(3)});
  return counts;
}

std::vector<KindEdge> count_campaign_edges_by_kind(sql::Connection& db, std::int64_t campaign) {
  auto rows = db.prepare(
      "SELECT up.kind, down.kind, count(*) FROM edges e JOIN campaign_tasks ct ON ct.task_key = "
      "e.downstream AND ct.campaign_id = ? JOIN tasks up ON up.key = e.upstream JOIN tasks down "
      "ON down.key = e.downstream GROUP BY up.kind, down.kind ORDER BY min(down.rowid), "
      "min(up.rowid)");
  rows.bind_all(campaign);
  std::vector<KindEdge> edges;
  while (rows.step()) edges.push_back({rows.text(0), rows.text(1), rows.integer(2)});
  return edges;
}

std::vector<TaskResultRow> find_task_results(sql::Connection& db, const std::string& campaign) {
  auto rows = db.prepare(
      "SELECT task_key, kind, status, params, coalesce(result, 'null') FROM task_results WHERE "
      "campaign = ? ORDER BY kind, task_key");
  rows.bind_all(campaign);
  std::vector<TaskResultRow> tasks;
  while (rows.step()) {
    const std::string key = rows.text(0);
    tasks.push_back({key, rows.text(1), rows.text(2),
                     stored_json(rows.text(3), "parameters of task " + key),
                     stored_json(rows.text(4), "result of task " + key)});
  }
  return tasks;
}

std::vector<std::string> find_done_task_keys(sql::Connection& db, std::int64_t campaign,
                                             const std::string& kind) {
  auto rows = db.prepare(
      "SELECT t.key FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key "
      "WHERE ct.campaign_id = ? AND t.kind = ? AND t.status = 'done' ORDER BY t.key");
  rows.bind_all(campaign, kind);
  std::vector<std::string> keys;
  while (rows.step()) keys.push_back(rows.text(0));
  return keys;
}

std::vector<KindAndKey> find_done_tasks_with_artifacts(sql::Connection& db, std::int64_t campaign) {
  auto rows = db.prepare(
      "SELECT t.kind, t.key FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key "
      "WHERE ct.campaign_id = ? AND t.status = 'done' AND EXISTS (SELECT 1 FROM artifacts a "
      "WHERE a.task_key = t.key) ORDER BY t.kind, t.key");
  rows.bind_all(campaign);
  std::vector<KindAndKey> tasks;
  while (rows.step()) tasks.push_back({rows.text(0), rows.text(1)});
  return tasks;
}

std::optional<ViewRows> find_campaign_view_rows(sql::Connection& db, const std::string& view,
                                                std::int64_t campaign) {
  auto exists = db.prepare("SELECT 1 FROM sqlite_master WHERE type = 'view' AND name = ?");
  exists.bind_all(view);
  if (!exists.step()) return std::nullopt;
  auto rows = db.prepare(
      fmt::format("SELECT s.* FROM {} s JOIN campaign_tasks ct ON ct.task_key = s.task_key "
                  "WHERE ct.campaign_id = ?",
                  view));
  rows.bind_all(campaign);
  ViewRows found;
  for (int column = 0; column < rows.columns(); ++column)
    found.columns.push_back(rows.column_name(column));
  while (rows.step()) {
    std::vector<std::optional<std::string>> row;
    for (int column = 0; column < rows.columns(); ++column) {
      if (rows.is_null(column))
        row.emplace_back();
      else
        row.emplace_back(rows.text(column));
    }
    found.rows.push_back(std::move(row));
  }
  return found;
}

std::optional<CoordinatorRecord> find_coordinator(sql::Connection& db) {
  if (db.user_version() == 0) return std::nullopt;
  auto row = db.prepare("SELECT pid, host, started_at, coalesce(campaign, '') FROM coordinator");
  if (!row.step()) return std::nullopt;
  return CoordinatorRecord{row.integer(0), row.text(1), row.real(2), row.text(3)};
}

namespace {

// What an error of the statement itself names as its place: `millflow query`'s argument (the
// database's errors name --db).
constexpr const char* kQueryArgument = "SQL";

// An error of a query's statement: the database's fault when SQLite cannot read it, else the
// SQL's, whether preparing or running it found it (ATTACH of a missing file, an integer overflow).
InvalidInput query_error(const fs::path& db_path, const sql::Error& error) {
  if (is_damaged_database_error(error.what()))
    return InvalidInput(
        {{"--db", damaged_database_problem(db_path, error.what()), damaged_database_fix(db_path)}});
  return InvalidInput(
      {{kQueryArgument, error.what(),
        "check the SQL; `millflow query \"SELECT name FROM sqlite_master\"` lists tables"}});
}

}  // namespace

QueryRows run_read_only_query(sql::Connection& db, const fs::path& db_path,
                              const std::string& sql_text, std::size_t max_values,
                              std::size_t max_bytes) {
  // No one value beyond the total: SQLite refuses to build it ("string or blob too big").
  sqlite3_limit(db.handle(), SQLITE_LIMIT_LENGTH,
                static_cast<int>(std::min<std::size_t>(max_bytes, INT32_MAX)));
  std::optional<sql::Statement> statement;
  try {
    statement.emplace(db.prepare(sql_text));
  } catch (const sql::Error& error) {
    throw query_error(db_path, error);
  }
  if (!statement->read_only()) {
    throw InvalidInput(
        {{kQueryArgument, "refused: the statement would modify the database",
          "millflow query only reads; the store is written by millflow submit/resume alone"}});
  }
  QueryRows result;
  for (int column = 0; column < statement->columns(); ++column)
    result.columns.push_back(statement->column_name(column));
  const std::size_t columns = std::max<std::size_t>(result.columns.size(), 1);
  std::size_t bytes = 0;
  try {
    while (statement->step()) {
      if ((result.rows.size() + 1) * columns > max_values) {
        throw InvalidInput(
            {{kQueryArgument, fmt::format("the result holds more than {} values", max_values),
              "add a LIMIT, or select fewer rows or columns"}});
      }
      std::vector<QueryValue> row;
      for (int column = 0; column < statement->columns(); ++column) {
        QueryValue value;
        value.type = statement->column_type(column);
        if (value.type == SQLITE_INTEGER) value.integer = statement->integer(column);
        if (value.type == SQLITE_FLOAT) value.real = statement->real(column);
        value.text = statement->text(column);
        bytes += value.text.size();
        if (bytes > max_bytes) {
          throw InvalidInput(
              {{kQueryArgument,
                fmt::format("the result holds more than {} bytes of text", max_bytes),
                "add a LIMIT, or select fewer or shorter values"}});
        }
        row.push_back(std::move(value));
      }
      result.rows.push_back(std::move(row));
    }
  } catch (const sql::Error& error) {
    if (std::string_view(error.what()).ends_with("string or blob too big")) {
      throw InvalidInput(
          {{kQueryArgument, fmt::format("a value of the result is longer than {} bytes", max_bytes),
            "select a part of it (substr), or fewer values"}});
    }
    throw query_error(db_path, error);
  }
  return result;
}

}  // namespace millflow::engine
