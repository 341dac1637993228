#pragma once
// Read-only views of a store for the command line: status, query, show, explain, dag, export,
// and artifact garbage collection. All of them use read-only connections and work while a
// coordinator is running.
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "engine/sqlite.hpp"

namespace millflow::engine {

enum class TableFormat { table, csv, json };

// Campaign list (campaign empty) or one campaign's counts by kind and status, plus the
// coordinator holding the database if any.
void print_status(const std::filesystem::path& db, const std::string& campaign, std::ostream& out);

// Runs one read-only SQL statement; a writing statement is refused with InvalidInput.
void run_query(const std::filesystem::path& db, const std::string& sql, TableFormat format, std::ostream& out);

// The full key of the one task whose key starts with `prefix` (InvalidInput otherwise).
std::string resolve_task(sql::Connection& db, const std::string& prefix);

void print_show(const std::filesystem::path& db, const std::string& task, std::ostream& out);
void print_explain(const std::filesystem::path& db, const std::string& task, std::ostream& out);
void print_dag_dot(const std::filesystem::path& db, const std::string& campaign, std::ostream& out);

// Writes <out>/<kind>.csv per task kind (params.* and result.* columns) or <out>/<campaign>.json.
std::vector<std::filesystem::path> export_campaign(const std::filesystem::path& db, const std::string& campaign,
                                                   TableFormat format, const std::filesystem::path& out_dir);

// Copies the artifacts of the campaign's finished tasks of `kind` into out_dir under their names
// (each verified against its digest first), e.g. a report. Throws InvalidInput when there are
// none, or when a stored file is damaged.
std::vector<std::filesystem::path> copy_kind_artifacts(const std::filesystem::path& db, const std::string& campaign,
                                                       const std::string& kind, const std::filesystem::path& out_dir);

// Artifact files no task references (and temporary files left by crashes); removed unless
// dry_run. Takes the coordinator lock: never collects while a campaign runs.
std::vector<std::string> collect_garbage(const std::filesystem::path& db, bool dry_run);

}  // namespace millflow::engine
