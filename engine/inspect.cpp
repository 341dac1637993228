#include "engine/inspect.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "engine/artifacts.hpp"
#include "engine/canonical_json.hpp"
#include "engine/clock.hpp"
#include "engine/coordinator_lock.hpp"
#include "engine/outputs.hpp"
#include "engine/store.hpp"
#include "engine/validation.hpp"
#include "util/durable_file.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

using Row = std::vector<std::string>;

struct Table {
  Row header;
  std::vector<Row> rows;
};

Table read_table(sql::Statement& statement) {
  Table table;
  for (int column = 0; column < statement.columns(); ++column)
    table.header.push_back(statement.column_name(column));
  while (statement.step()) {
    Row row;
    for (int column = 0; column < statement.columns(); ++column)
      row.push_back(statement.text(column));
    table.rows.push_back(std::move(row));
  }
  return table;
}

void print_csv(const Table& table, std::ostream& out) {
  auto print_row = [&](const Row& row) {
    for (size_t i = 0; i < row.size(); ++i) out << (i ? "," : "") << csv_field(row[i]);
    out << '\n';
  };
  print_row(table.header);
  for (const auto& row : table.rows) print_row(row);
}

void print_aligned(const Table& table, std::ostream& out) {
  std::vector<size_t> widths;
  for (const auto& name : table.header) widths.push_back(name.size());
  for (const auto& row : table.rows) {
    for (size_t i = 0; i < row.size(); ++i) widths[i] = std::max(widths[i], row[i].size());
  }
  auto print_row = [&](const Row& row) {
    for (size_t i = 0; i < row.size(); ++i)
      out << (i ? "  " : "") << fmt::format("{:<{}}", row[i], widths[i]);
    out << '\n';
  };
  print_row(table.header);
  for (size_t i = 0; i < widths.size(); ++i) out << (i ? "  " : "") << std::string(widths[i], '-');
  out << '\n';
  for (const auto& row : table.rows) print_row(row);
}

nlohmann::json cell_json(sql::Statement& statement, int column) {
  switch (statement.column_type(column)) {
    case SQLITE_NULL:
      return nullptr;
    case SQLITE_INTEGER:
      return statement.integer(column);
    case SQLITE_FLOAT:
      return statement.real(column);
    default: {
      // Text holding a JSON object or array (params, result, json_extract of a nested value)
      // is answered as that JSON, not as a string of it.
      std::string text = statement.text(column);
      if (!text.empty() && (text.front() == '{' || text.front() == '[')) {
        auto parsed = nlohmann::json::parse(text, nullptr, false);
        if (!parsed.is_discarded()) return parsed;
      }
      return text;
    }
  }
}

// Leaves of a JSON value by path ("/a/b"); arrays count as one leaf.
void flatten(const nlohmann::json& value, const std::string& path,
             std::map<std::string, std::string>& leaves) {
  if (value.is_object() && !value.empty()) {
    for (const auto& [key, member] : value.items()) flatten(member, path + "/" + key, leaves);
  } else {
    leaves[path.empty() ? "/" : path] = canonical_json(value);
  }
}

std::map<std::string, std::string> leaves_of(const nlohmann::json& value) {
  std::map<std::string, std::string> leaves;
  flatten(value, "", leaves);
  return leaves;
}

std::vector<std::string> param_diff(const nlohmann::json& before, const nlohmann::json& after) {
  const auto old_leaves = leaves_of(before);
  const auto new_leaves = leaves_of(after);
  std::set<std::string> paths;
  for (const auto& [path, value] : old_leaves) paths.insert(path);
  for (const auto& [path, value] : new_leaves) paths.insert(path);
  std::vector<std::string> lines;
  for (const auto& path : paths) {
    const auto old_value = old_leaves.count(path) ? old_leaves.at(path) : "(absent)";
    const auto new_value = new_leaves.count(path) ? new_leaves.at(path) : "(absent)";
    if (old_value != new_value)
      lines.push_back(fmt::format("{}: {} -> {}", path, old_value, new_value));
  }
  return lines;
}

// A task's status as shown (t: tasks, r: results): "skipped" for a done task whose result says
// it skipped its work (engine/runtime.hpp, RunSummary::skipped_their_work).
std::string shown_status_sql() {
  return "CASE WHEN t.status = 'done' AND json_extract(r.result, '$.skipped') IS NOT NULL THEN "
         "'skipped' ELSE t.status END";
}

std::int64_t campaign_id(sql::Connection& db, const std::string& name) {
  auto row = db.prepare("SELECT id FROM campaigns WHERE name = ?");
  row.bind_all(name);
  if (!row.step()) {
    throw InvalidInput({{"", "no campaign named \"" + name + "\"",
                         "run `millflow status` to list the campaigns"}});
  }
  return row.integer(0);
}

std::vector<std::string> lineage(sql::Connection& db, const std::string& key, bool upward) {
  auto next =
      db.prepare(upward ? "SELECT upstream FROM edges WHERE downstream = ? ORDER BY position"
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

std::string kind_and_status(sql::Connection& db, const std::string& key) {
  const auto record = find_task(db, key);
  return record ? fmt::format("{} {} [{}]", key.substr(0, 16), record->spec.kind, record->status)
                : key;
}

// Why a stored task would (or would not) run at the next submission.
std::vector<std::string> run_reasons(sql::Connection& db, const ArtifactStore& artifacts,
                                     const TaskRecord& task) {
  if (task.status == "done") {
    for (const auto& artifact : find_artifacts(db, task.spec.key)) {
      if (!artifacts.verify(artifact)) {
        return {fmt::format("would run: artifact {} ({}) is missing or corrupt", artifact.name,
                            artifact.sha256)};
      }
    }
    return {"would not run: done, result and artifacts intact (cached)"};
  }
  if (task.status == "failed") return {"would run: the previous attempt failed: " + task.error};
  if (task.status == "interrupted") return {"would run: the previous attempt was interrupted"};
  if (task.status == "running")
    return {"would run: its last attempt never finished (coordinator stopped or still running)"};
  if (task.status == "skipped") return {"would run: it was skipped because " + task.error};
  if (task.attempts > 0)
    return {"would run: " + (task.error.empty() ? std::string("not finished yet") : task.error)};
  return {"would run: new (never attempted)"};
}

size_t upstream_differences(const std::vector<std::string>& before,
                            const std::vector<std::string>& after) {
  size_t differences =
      std::max(before.size(), after.size()) - std::min(before.size(), after.size());
  for (size_t i = 0; i < std::min(before.size(), after.size()); ++i)
    differences += before[i] != after[i];
  return differences;
}

// Compares with the cached task of the same kind whose parameters differ least (then its inputs).
std::vector<std::string> compare_with_nearest(sql::Connection& db, const TaskRecord& task) {
  auto candidates = db.prepare(
      "SELECT key FROM tasks WHERE kind = ? AND status = 'done' AND key <> ? ORDER BY key");
  candidates.bind_all(task.spec.kind, task.spec.key);
  std::optional<TaskRecord> nearest;
  std::pair<size_t, size_t> fewest{std::numeric_limits<size_t>::max(), 0};
  while (candidates.step()) {
    auto candidate = find_task(db, candidates.text(0));
    const std::pair differences{param_diff(candidate->spec.params, task.spec.params).size(),
                                upstream_differences(candidate->spec.upstream, task.spec.upstream)};
    if (differences < fewest) {
      fewest = differences;
      nearest = std::move(candidate);
    }
  }
  if (!nearest) return {"no cached task of kind " + task.spec.kind + " to compare with"};
  std::vector<std::string> lines{"nearest cached " + task.spec.kind +
                                 " task: " + nearest->spec.key};
  const auto diff = param_diff(nearest->spec.params, task.spec.params);
  if (!diff.empty()) lines.push_back("parameters changed:");
  for (const auto& line : diff) lines.push_back("  " + line);
  if (nearest->spec.upstream != task.spec.upstream) {
    lines.push_back("upstream changed:");
    for (size_t i = 0; i < std::max(nearest->spec.upstream.size(), task.spec.upstream.size());
         ++i) {
      const auto before = i < nearest->spec.upstream.size() ? nearest->spec.upstream[i] : "(none)";
      const auto after = i < task.spec.upstream.size() ? task.spec.upstream[i] : "(none)";
      if (before != after) lines.push_back(fmt::format("  input {}: {} -> {}", i, before, after));
    }
  }
  if (nearest->spec.version != task.spec.version) {
    lines.push_back(
        fmt::format("kind version changed: {} -> {}", nearest->spec.version, task.spec.version));
  }
  return lines;
}

// The batch job of each task of the campaign that is not finished yet (latest attempt).
void print_unfinished_jobs(sql::Connection& db, std::int64_t campaign, std::ostream& out) {
  if (db.user_version() < 2) return;
  auto rows = db.prepare(
      "SELECT t.kind, substr(t.key, 1, 16) AS task, j.attempt, j.executor, j.job_id, j.state FROM "
      "campaign_tasks ct "
      "JOIN tasks t ON t.key = ct.task_key JOIN jobs j ON j.task_key = t.key AND j.attempt = "
      "t.attempts "
      "WHERE ct.campaign_id = ? AND t.status = 'running' ORDER BY j.job_id");
  rows.bind_all(campaign);
  const Table jobs = read_table(rows);
  if (jobs.rows.empty()) return;
  out << "\nbatch jobs of running tasks:\n";
  print_aligned(jobs, out);
}

}  // namespace

void print_status(const fs::path& db, const std::string& campaign, std::ostream& out) {
  auto connection = open_read_only(db);
  const auto coordinator = coordinator_state(db);
  if (coordinator) out << "coordinator: " << coordinator->description << '\n';
  // A campaign left 'running' by a coordinator that died is shown as what it is.
  const bool running = coordinator && coordinator->alive;
  if (campaign.empty()) {
    auto rows = connection.prepare(
        "SELECT c.name AS campaign, CASE WHEN c.outcome = 'running' AND NOT ? THEN 'interrupted' "
        "ELSE c.outcome END AS outcome, count(t.key) AS tasks, sum(t.status = 'done') AS "
        "done, "
        "sum(t.status = 'failed') AS failed, sum(t.status IN ('pending', 'running', "
        "'interrupted')) AS to_run "
        "FROM campaigns c LEFT JOIN campaign_tasks ct ON ct.campaign_id = c.id LEFT JOIN tasks t "
        "ON t.key = ct.task_key "
        "GROUP BY c.id ORDER BY c.submitted_at");
    rows.bind_all(running ? 1 : 0);
    print_aligned(read_table(rows), out);
    return;
  }
  auto rows = connection.prepare(
      "SELECT t.kind, " + shown_status_sql() +
      " AS status, count(*) AS tasks FROM campaign_tasks ct JOIN tasks t ON t.key = "
      "ct.task_key LEFT JOIN results r ON r.task_key = t.key "
      "WHERE ct.campaign_id = ? GROUP BY t.kind, 2 ORDER BY t.kind, 2");
  const std::int64_t id = campaign_id(connection, campaign);
  rows.bind_all(id);
  print_aligned(read_table(rows), out);
  print_unfinished_jobs(connection, id, out);
}

void run_query(const fs::path& db, const std::string& sql_text, TableFormat format,
               std::ostream& out) {
  auto connection = open_read_only(db);
  std::optional<sql::Statement> statement;
  try {
    statement.emplace(connection.prepare(sql_text));
  } catch (const sql::Error& error) {
    if (is_damaged_database_error(error.what()))
      throw InvalidInput(
          {{"--db", damaged_database_problem(db, error.what()), damaged_database_fix(db)}});
    throw InvalidInput(
        {{"", error.what(),
          "check the SQL; `millflow query \"SELECT name FROM sqlite_master\"` lists tables"}});
  }
  if (!statement->read_only()) {
    throw InvalidInput(
        {{"", "refused: the statement would modify the database",
          "millflow query only reads; the store is written by millflow submit/resume alone"}});
  }
  if (format == TableFormat::json) {
    nlohmann::json rows = nlohmann::json::array();
    while (statement->step()) {
      nlohmann::json row = nlohmann::json::object();
      for (int column = 0; column < statement->columns(); ++column)
        row[statement->column_name(column)] = cell_json(*statement, column);
      rows.push_back(std::move(row));
    }
    out << rows.dump(2) << '\n';
    return;
  }
  const Table table = read_table(*statement);
  if (format == TableFormat::csv)
    print_csv(table, out);
  else
    print_aligned(table, out);
}

std::string resolve_task(sql::Connection& db, const std::string& prefix) {
  auto rows =
      db.prepare("SELECT key FROM tasks WHERE key >= ? AND key < ? || 'g' ORDER BY key LIMIT 2");
  rows.bind_all(prefix, prefix);
  std::vector<std::string> keys;
  while (rows.step()) keys.push_back(rows.text(0));
  if (prefix.empty() || keys.empty()) {
    throw InvalidInput({{"", "no task key starts with \"" + prefix + "\"",
                         "copy a key from `millflow status` or `millflow query`"}});
  }
  if (keys.size() > 1)
    throw InvalidInput(
        {{"", "task prefix \"" + prefix + "\" is ambiguous", "give more characters of the key"}});
  return keys.front();
}

void print_show(const fs::path& db, const std::string& task, std::ostream& out) {
  auto connection = open_read_only(db);
  const std::string key = resolve_task(connection, task);
  const auto record = *find_task(connection, key);
  auto times = connection.prepare(
      "SELECT started_at, coalesce(duration_s, ''), coalesce(host, ''), coalesce(code_version, '') "
      "FROM tasks WHERE key = ?");
  times.bind_all(key);
  times.step();
  const std::string started = times.is_null(0) ? std::string("never") : iso8601_utc(times.real(0));
  out << fmt::format("task {}\nkind {} (version {})\nstatus {} after {} attempt(s){}\n", key,
                     record.spec.kind, record.spec.version, record.status, record.attempts,
                     record.error.empty() ? "" : "\nerror " + record.error);
  out << fmt::format("started {} duration {} s host {} code {}\n", started, times.text(1),
                     times.text(2), times.text(3));
  out << "params " << record.spec.params.dump(2) << '\n';
  if (const auto result = find_result(connection, key)) out << "result " << result->dump(2) << '\n';
  const ArtifactStore artifacts(artifacts_dir(db));
  for (const auto& artifact : find_artifacts(connection, key)) {
    out << fmt::format("artifact {} {} bytes sha256 {} {} ({})\n", artifact.name, artifact.size,
                       artifact.sha256, artifacts.path_of(artifact.sha256).string(),
                       artifacts.verify(artifact) ? "verified" : "MISSING OR CORRUPT");
  }
  for (const auto& job : find_jobs(connection, key)) {
    out << fmt::format("job {} {} attempt {} state {} name {}\n  stdout {}\n  stderr {}\n",
                       job.executor, job.job_id, job.attempt, job.state, job.job_name,
                       job.stdout_file.string(), job.stderr_file.string());
  }
  for (const auto& upstream : lineage(connection, key, true))
    out << "upstream   " << kind_and_status(connection, upstream) << '\n';
  for (const auto& downstream : lineage(connection, key, false))
    out << "downstream " << kind_and_status(connection, downstream) << '\n';
}

void print_explain(const fs::path& db, const std::string& task, std::ostream& out) {
  auto connection = open_read_only(db);
  const auto record = *find_task(connection, resolve_task(connection, task));
  out << "task " << record.spec.key << "\nhashed text (SHA-256 of exactly these bytes):\n"
      << record.spec.key_text;
  for (const auto& line : run_reasons(connection, ArtifactStore(artifacts_dir(db)), record))
    out << line << '\n';
  if (record.status != "done" && record.attempts == 0) {
    for (const auto& line : compare_with_nearest(connection, record)) out << line << '\n';
  }
}

void print_dag_dot(const fs::path& db, const std::string& campaign, std::ostream& out) {
  auto connection = open_read_only(db);
  const std::int64_t id = campaign_id(connection, campaign);
  static const std::map<std::string, std::string> kColours = {
      {"done", "palegreen"},    {"failed", "salmon"},     {"running", "lightblue"},
      {"skipped", "lightgrey"}, {"interrupted", "khaki"}, {"pending", "white"}};
  out << "digraph \"" << campaign << "\" {\n  node [shape=box, style=filled];\n";
  auto nodes = connection.prepare("SELECT t.key, t.kind, " + shown_status_sql() +
                                  " FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key "
                                  "LEFT JOIN results r ON r.task_key = t.key "
                                  "WHERE ct.campaign_id = ? ORDER BY t.rowid");
  nodes.bind_all(id);
  while (nodes.step()) {
    out << fmt::format("  \"{}\" [label=\"{}\\n{}\", fillcolor={}];\n", nodes.text(0),
                       nodes.text(1), nodes.text(0).substr(0, 12), kColours.at(nodes.text(2)));
  }
  auto edges = connection.prepare(
      "SELECT e.upstream, e.downstream FROM edges e JOIN campaign_tasks ct ON ct.task_key = "
      "e.downstream "
      "WHERE ct.campaign_id = ? ORDER BY e.downstream, e.position");
  edges.bind_all(id);
  while (edges.step()) out << fmt::format("  \"{}\" -> \"{}\";\n", edges.text(0), edges.text(1));
  out << "}\n";
}

std::vector<fs::path> export_campaign(const fs::path& db, const std::string& campaign,
                                      TableFormat format, const fs::path& out_dir) {
  auto connection = open_read_only(db);
  campaign_id(connection, campaign);
  auto rows = connection.prepare(
      "SELECT task_key, kind, status, params, coalesce(result, 'null') FROM task_results WHERE "
      "campaign = ? ORDER BY kind, task_key");
  rows.bind_all(campaign);
  nlohmann::json tasks = nlohmann::json::array();
  while (rows.step()) {
    tasks.push_back({{"task_key", rows.text(0)},
                     {"kind", rows.text(1)},
                     {"status", rows.text(2)},
                     {"params", nlohmann::json::parse(rows.text(3))},
                     {"result", nlohmann::json::parse(rows.text(4))}});
  }
  fs::create_directories(out_dir);
  if (format == TableFormat::json) {
    const fs::path file = out_dir / (campaign + ".json");
    util::write_file_durably(file, tasks.dump(2) + '\n');
    return {file};
  }
  std::map<std::string, std::vector<const nlohmann::json*>> by_kind;
  for (const auto& task : tasks) by_kind[task["kind"].get<std::string>()].push_back(&task);
  const SweepPoints points = read_sweep_points(connection, campaign_id(connection, campaign));
  std::vector<fs::path> files;
  for (const auto& [kind, members] : by_kind) {
    std::vector<std::map<std::string, std::string>> flat;
    std::set<std::string> columns;
    for (const auto* task : members) {
      std::map<std::string, std::string> row;
      for (const auto& [path, value] : csv_columns((*task)["params"])) row["params" + path] = value;
      for (const auto& [path, value] : csv_columns((*task)["result"])) row["result" + path] = value;
      for (const auto& [column, value] : row) columns.insert(column);
      row["task_key"] = (*task)["task_key"];
      row["status"] = (*task)["status"];
      if (const auto point = points.by_task.find(row["task_key"]); point != points.by_task.end())
        row.insert(point->second.begin(), point->second.end());
      flat.push_back(std::move(row));
    }
    // The sweep point first (engine/outputs.hpp), so every kind's table can be joined on it:
    // the coordinates the kind's tasks have.
    Table table{{"task_key", "status"}, {}};
    for (const auto& coordinate : points.columns) {
      if (std::any_of(flat.begin(), flat.end(),
                      [&](const auto& row) { return row.count(coordinate) > 0; }))
        table.header.push_back(coordinate);
    }
    table.header.insert(table.header.end(), columns.begin(), columns.end());
    for (const auto& row : flat) {
      Row cells;
      for (const auto& column : table.header)
        cells.push_back(row.count(column) ? row.at(column) : "");
      table.rows.push_back(std::move(cells));
    }
    files.push_back(out_dir / (kind + ".csv"));
    std::ostringstream csv;
    print_csv(table, csv);
    util::write_file_durably(files.back(), csv.str());
  }
  return files;
}

std::vector<TaskArtifacts> finished_task_artifacts(const fs::path& db, const std::string& campaign,
                                                   const std::string& kind) {
  auto connection = open_read_only(db);
  auto rows = connection.prepare(
      "SELECT t.key FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key "
      "WHERE ct.campaign_id = ? AND t.kind = ? AND t.status = 'done' ORDER BY t.key");
  rows.bind_all(campaign_id(connection, campaign), kind);
  std::vector<TaskArtifacts> tasks;
  while (rows.step()) tasks.push_back({rows.text(0), {}});
  for (TaskArtifacts& task : tasks) task.artifacts = find_artifacts(connection, task.task_key);
  return tasks;
}

std::vector<fs::path> copy_artifacts(const fs::path& db,
                                     const std::vector<StoredArtifact>& artifacts,
                                     const fs::path& out_dir, const FileSystem& files) {
  const ArtifactStore store(artifacts_dir(db), files);
  std::vector<fs::path> copied;
  for (const StoredArtifact& artifact : artifacts) {
    if (!store.verify(artifact)) {
      throw std::runtime_error(
          fmt::format("artifact {} ({}) is missing or corrupt in the store: re-run its task "
                      "(`millflow explain` on it says which)",
                      artifact.name, artifact.sha256));
    }
    copied.push_back(out_dir / artifact.name);
    files.copy_durably(store.path_of(artifact.sha256), copied.back());
  }
  return copied;
}

std::vector<std::string> collect_garbage(const fs::path& db, bool dry_run) {
  CoordinatorLock lock(db);
  auto connection = open_read_only(db);
  std::set<std::string> referenced;
  auto rows = connection.prepare("SELECT DISTINCT sha256 FROM artifacts");
  while (rows.step()) referenced.insert(rows.text(0));
  const ArtifactStore artifacts(artifacts_dir(db));
  std::vector<std::string> unreferenced;
  for (const auto& digest : artifacts.stored_digests()) {
    if (referenced.count(digest) > 0) continue;
    unreferenced.push_back(digest);
    if (!dry_run) artifacts.remove(digest);
  }
  return unreferenced;
}

}  // namespace millflow::engine
