#pragma once
// Read-only views of a store for the command line: status, query, show, explain, dag, export,
// and artifact garbage collection. All of them use read-only connections and work while a
// coordinator is running.
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "engine/artifacts.hpp"
#include "engine/files.hpp"
#include "engine/sqlite.hpp"

namespace millflow::engine {

enum class TableFormat { table, csv, json };

// Campaign list (campaign empty) or one campaign's counts by kind and status, plus the
// coordinator holding the database if any.
void print_status(const std::filesystem::path& db, const std::string& campaign, std::ostream& out);

// Runs one read-only SQL statement; a writing statement is refused with InvalidInput.
void run_query(const std::filesystem::path& db, const std::string& sql, TableFormat format,
               std::ostream& out);

// The full key of the one task whose key starts with `prefix` (InvalidInput otherwise).
std::string resolve_task(sql::Connection& db, const std::string& prefix);

void print_show(const std::filesystem::path& db, const std::string& task, std::ostream& out);
void print_explain(const std::filesystem::path& db, const std::string& task, std::ostream& out);
// Graphviz dot: one node per task kind (tasks counted by status) and edges between kinds labelled
// with the number of task edges; with every_task, one node per task and every edge.
void print_dag_dot(const std::filesystem::path& db, const std::string& campaign, bool every_task,
                   std::ostream& out);

// Writes <out>/<kind>.csv per task kind (params.* and result.* columns) or <out>/<campaign>.json.
std::vector<std::filesystem::path> export_campaign(const std::filesystem::path& db,
                                                   const std::string& campaign, TableFormat format,
                                                   const std::filesystem::path& out_dir);

// The finished (done) tasks of one kind in a campaign, by key, each with its stored artifacts
// (possibly none). Throws InvalidInput for an unknown campaign.
struct TaskArtifacts {
  std::string task_key;
  std::vector<StoredArtifact> artifacts;
};
std::vector<TaskArtifacts> finished_task_artifacts(const std::filesystem::path& db,
                                                   const std::string& campaign,
                                                   const std::string& kind);

// Copies stored artifacts out of the store as <out_dir>/<name>, each verified (size and SHA-256)
// first; returns the written paths. Throws std::runtime_error for a missing or corrupt artifact.
std::vector<std::filesystem::path> copy_artifacts(const std::filesystem::path& db,
                                                  const std::vector<StoredArtifact>& artifacts,
                                                  const std::filesystem::path& out_dir,
                                                  const FileSystem& files = local_file_system());

// Artifact files no task references (and temporary files left by crashes); removed unless
// dry_run. Takes the coordinator lock: never collects while a campaign runs.
std::vector<std::string> collect_garbage(const std::filesystem::path& db, bool dry_run);

}  // namespace millflow::engine
