#include "engine/inspect.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "engine/artifacts.hpp"
#include "engine/cache.hpp"
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
  return record ? fmt::format("{} {} [{}]", key.substr(0, 16), record->spec.kind,
                              to_string(record->status))
                : key;
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
                     record.spec.kind, record.spec.version, to_string(record.status),
                     record.attempts, record.error.empty() ? "" : "\nerror " + record.error);
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
  EarlierTasks earlier(connection);
  const ArtifactStore artifacts(artifacts_dir(db));
  const CacheJudge judge(artifacts, {}, &earlier);
  out << explain_text(record.spec,
                      judge.decide(record.spec, find_stored_task(connection, record.spec.key)));
}

namespace {

const std::map<std::string, std::string>& status_colours() {
  static const std::map<std::string, std::string> colours = {
      {"done", "palegreen"},    {"failed", "salmon"},     {"running", "lightblue"},
      {"skipped", "lightgrey"}, {"interrupted", "khaki"}, {"pending", "white"}};
  return colours;
}

void print_task_graph(sql::Connection& db, std::int64_t campaign, std::ostream& out) {
  auto nodes = db.prepare(
      "SELECT t.key, t.kind, " + shown_status_sql() +
      " FROM campaign_tasks ct JOIN tasks t ON t.key = ct.task_key LEFT JOIN results r ON "
      "r.task_key = t.key WHERE ct.campaign_id = ? ORDER BY t.rowid");
  nodes.bind_all(campaign);
  while (nodes.step()) {
    out << fmt::format("  \"{}\" [label=\"{}\\n{}\", fillcolor={}];\n", nodes.text(0),
                       nodes.text(1), nodes.text(0).substr(0, 12),
                       status_colours().at(nodes.text(2)));
  }
  auto edges = db.prepare(
      "SELECT e.upstream, e.downstream FROM edges e JOIN campaign_tasks ct ON ct.task_key = "
      "e.downstream WHERE ct.campaign_id = ? ORDER BY e.downstream, e.position");
  edges.bind_all(campaign);
  while (edges.step()) out << fmt::format("  \"{}\" -> \"{}\";\n", edges.text(0), edges.text(1));
}

// One node per kind (its tasks counted by status, coloured by the most pressing status present),
// one edge per pair of kinds with the number of task edges between them.
void print_kind_graph(sql::Connection& db, std::int64_t campaign, std::ostream& out) {
  auto counts = db.prepare(
      "SELECT t.kind, " + shown_status_sql() +
      " AS shown, count(*), min(t.rowid) FROM campaign_tasks ct JOIN tasks t ON t.key = "
      "ct.task_key LEFT JOIN results r ON r.task_key = t.key WHERE ct.campaign_id = ? GROUP BY "
      "t.kind, shown");
  counts.bind_all(campaign);
  std::map<std::string, std::map<TaskStatus, std::int64_t>> by_kind;
  std::map<std::string, std::int64_t> first_row;  // kinds in graph order: planned upstream first
  while (counts.step()) {
    by_kind[counts.text(0)][task_status_from(counts.text(1))] = counts.integer(2);
    auto [where, inserted] = first_row.emplace(counts.text(0), counts.integer(3));
    if (!inserted) where->second = std::min(where->second, counts.integer(3));
  }
  std::vector<std::pair<std::int64_t, std::string>> kinds;
  for (const auto& [kind, row] : first_row) kinds.emplace_back(row, kind);
  std::sort(kinds.begin(), kinds.end());
  static constexpr std::array kPressing = {TaskStatus::failed,      TaskStatus::running,
                                           TaskStatus::interrupted, TaskStatus::pending,
                                           TaskStatus::skipped,     TaskStatus::done};
  for (const auto& [row, kind] : kinds) {
    const auto& statuses = by_kind.at(kind);
    std::int64_t total = 0;
    std::string parts;
    for (const auto& [status, number] : statuses) {
      total += number;
      parts += fmt::format("{}{} {}", parts.empty() ? "" : ", ", number, to_string(status));
    }
    const TaskStatus colour_of =
        *std::find_if(kPressing.begin(), kPressing.end(),
                      [&](TaskStatus status) { return statuses.count(status) > 0; });
    out << fmt::format("  \"{}\" [label=\"{}\\n{} task{}: {}\", fillcolor={}];\n", kind, kind,
                       total, total == 1 ? "" : "s", parts,
                       status_colours().at(std::string(to_string(colour_of))));
  }
  auto edges = db.prepare(
      "SELECT up.kind, down.kind, count(*) FROM edges e JOIN campaign_tasks ct ON ct.task_key = "
      "e.downstream AND ct.campaign_id = ? JOIN tasks up ON up.key = e.upstream JOIN tasks down "
      "ON down.key = e.downstream GROUP BY up.kind, down.kind ORDER BY min(down.rowid), "
      "min(up.rowid)");
  edges.bind_all(campaign);
  while (edges.step()) {
    out << fmt::format("  \"{}\" -> \"{}\" [label=\"{}\"];\n", edges.text(0), edges.text(1),
                       edges.integer(2));
  }
}

}  // namespace

void print_dag_dot(const fs::path& db, const std::string& campaign, bool every_task,
                   std::ostream& out) {
  auto connection = open_read_only(db);
  const std::int64_t id = campaign_id(connection, campaign);
  out << "digraph \"" << campaign << "\" {\n  node [shape=box, style=filled];\n";
  if (every_task)
    print_task_graph(connection, id, out);
  else
    print_kind_graph(connection, id, out);
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
