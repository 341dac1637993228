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
using Table = TextTable;

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

nlohmann::json cell_json(const QueryValue& value) {
  switch (value.type) {
    case SQLITE_NULL:
      return nullptr;
    case SQLITE_INTEGER:
      return value.integer;
    case SQLITE_FLOAT:
      return value.real;
    default: {
      // Text holding a JSON object or array (params, result, json_extract of a nested value)
      // is answered as that JSON, not as a string of it.
      const std::string& text = value.text;
      if (!text.empty() && (text.front() == '{' || text.front() == '[')) {
        auto parsed = nlohmann::json::parse(text, nullptr, false);
        if (!parsed.is_discarded()) return parsed;
      }
      return text;
    }
  }
}

std::int64_t campaign_id(sql::Connection& db, const std::string& name) {
  const auto id = find_campaign_id(db, name);
  if (!id) {
    throw InvalidInput({{"", "no campaign named \"" + name + "\"",
                         "run `millflow status` to list the campaigns"}});
  }
  return *id;
}

std::string kind_and_status(sql::Connection& db, const std::string& key) {
  const auto record = find_task(db, key);
  return record ? fmt::format("{} {} [{}]", key.substr(0, 16), record->spec.kind,
                              to_string(record->status))
                : key;
}

// The batch job of each task of the campaign that is not finished yet (latest attempt).
void print_unfinished_jobs(sql::Connection& db, std::int64_t campaign, std::ostream& out) {
  const Table jobs = unfinished_jobs(db, campaign);
  if (jobs.rows.empty()) return;
  out << "\nbatch jobs of running tasks:\n";
  print_aligned(jobs, out);
}

}  // namespace

void print_status(const fs::path& db, const std::string& campaign, std::ostream& out) {
  auto connection = open_read_only(db);
  const auto coordinator = coordinator_state(db);
  if (coordinator) out << "coordinator: " << coordinator->description << '\n';
  // A campaign, and its tasks, left 'running' by a coordinator that died are shown as what they
  // are.
  const bool running = coordinator && coordinator->alive;
  if (campaign.empty()) {
    print_aligned(campaign_summaries(connection, running), out);
    return;
  }
  const std::int64_t id = campaign_id(connection, campaign);
  print_aligned(campaign_status_counts(connection, id, running), out);
  print_unfinished_jobs(connection, id, out);
}

void run_query(const fs::path& db, const std::string& sql_text, TableFormat format,
               std::ostream& out) {
  auto connection = open_read_only(db);
  const QueryRows result = run_read_only_query(connection, db, sql_text);
  if (format == TableFormat::json) {
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& values : result.rows) {
      nlohmann::json row = nlohmann::json::object();
      for (size_t column = 0; column < values.size(); ++column)
        row[result.columns[column]] = cell_json(values[column]);
      rows.push_back(std::move(row));
    }
    // Text SQLite holds need not be UTF-8 (a blob, CAST(x'ff' AS TEXT)): such bytes print as
    // U+FFFD.
    out << rows.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
    return;
  }
  Table table{result.columns, {}};
  for (const auto& values : result.rows) {
    Row row;
    for (const auto& value : values) row.push_back(value.text);
    table.rows.push_back(std::move(row));
  }
  if (format == TableFormat::csv)
    print_csv(table, out);
  else
    print_aligned(table, out);
}

std::string resolve_task(sql::Connection& db, const std::string& prefix) {
  const std::vector<std::string> keys = find_task_keys_with_prefix(db, prefix, 2);
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
  const TaskRunInfo run = find_task_run_info(connection, key);
  // A task a dead coordinator left 'running' is interrupted, as `status` shows it.
  const auto coordinator = coordinator_state(db);
  const bool left_running =
      left_running_by_dead_coordinator(connection, key, coordinator && coordinator->alive);
  const std::string started = run.started_at ? iso8601_utc(*run.started_at) : std::string("never");
  out << fmt::format("task {}\nkind {} (version {})\nstatus {} after {} attempt(s){}\n", key,
                     record.spec.kind, record.spec.version,
                     left_running ? to_string(TaskStatus::interrupted) : to_string(record.status),
                     record.attempts, record.error.empty() ? "" : "\nerror " + record.error);
  out << fmt::format("started {} duration {} host {} code {}\n", started,
                     run.duration_s.empty() ? "-" : run.duration_s + " s", run.host,
                     run.code_version);
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
  for (const auto& upstream : find_lineage(connection, key, LineageDirection::upstream))
    out << "upstream   " << kind_and_status(connection, upstream) << '\n';
  for (const auto& downstream : find_lineage(connection, key, LineageDirection::downstream))
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
  for (const TaskNode& node : find_campaign_task_nodes(db, campaign)) {
    out << fmt::format("  \"{}\" [label=\"{}\\n{}\", fillcolor={}];\n", node.key, node.kind,
                       node.key.substr(0, 12), status_colours().at(node.shown_status));
  }
  for (const auto& [upstream, downstream] : find_campaign_edges(db, campaign))
    out << fmt::format("  \"{}\" -> \"{}\";\n", upstream, downstream);
}

// One node per kind (its tasks counted by status, coloured by the most pressing status present),
// one edge per pair of kinds with the number of task edges between them.
void print_kind_graph(sql::Connection& db, std::int64_t campaign, std::ostream& out) {
  std::map<std::string, std::map<TaskStatus, std::int64_t>> by_kind;
  std::map<std::string, std::int64_t> first_row;  // kinds in graph order: planned upstream first
  for (const KindStatusCount& count : count_campaign_tasks_by_kind(db, campaign)) {
    by_kind[count.kind][task_status_from(count.shown_status)] = count.tasks;
    auto [where, inserted] = first_row.emplace(count.kind, count.first_row);
    if (!inserted) where->second = std::min(where->second, count.first_row);
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
  for (const KindEdge& edge : count_campaign_edges_by_kind(db, campaign)) {
    out << fmt::format("  \"{}\" -> \"{}\" [label=\"{}\"];\n", edge.upstream_kind,
                       edge.downstream_kind, edge.edges);
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
  nlohmann::json tasks = nlohmann::json::array();
  for (TaskResultRow& row : find_task_results(connection, campaign)) {
    tasks.push_back({{"task_key", std::move(row.task_key)},
                     {"kind", std::move(row.kind)},
                     {"status", std::move(row.status)},
                     {"params", std::move(row.params)},
                     {"result", std::move(row.result)}});
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
  std::vector<TaskArtifacts> tasks;
  for (std::string& key : find_done_task_keys(connection, campaign_id(connection, campaign), kind))
    tasks.push_back({std::move(key), {}});
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
  const std::set<std::string> referenced = find_referenced_digests(connection);
  const ArtifactStore artifacts(artifacts_dir(db));
  std::vector<std::string> unreferenced;
  for (const auto& file : artifacts.stored_files()) {
    const std::string name = file.filename().string();
    if (referenced.count(name) > 0) continue;
    unreferenced.push_back(name);
    // By its path: a crash's leftover ".<digest>.tmp..." is not where path_of(its name) is.
    if (!dry_run) artifacts.remove(file);
  }
  return unreferenced;
}

}  // namespace millflow::engine
