#include "engine/outputs.hpp"

#include <fmt/format.h>

#include <optional>

#include "engine/artifacts.hpp"
#include "engine/clock.hpp"
#include "engine/inspect.hpp"
#include "engine/store.hpp"
#include "engine/validation.hpp"
#include "util/durable_file.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

// A folder name from a sweep point: "fill0.3_speed_fraction0.75_<key8>", characters that do not
// belong in a file name replaced by '-'.
std::string folder_label(const TaskCoordinates& point, const std::string& key) {
  std::string label;
  for (const auto& [name, value] : point) label += fmt::format("{}{}_", name, value);
  label += key.substr(0, 8);
  for (char& c : label) {
    const bool plain =
        std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
    if (!plain) c = '-';
  }
  return label;
}

void add_csv_columns(const nlohmann::json& value, const std::string& path,
                     std::map<std::string, std::string>& columns) {
  if (value.is_object() && !value.empty()) {
    for (const auto& [key, member] : value.items())
      add_csv_columns(member, fmt::format("{}/{}", path, key), columns);
    return;
  }
  const std::string name = path.empty() ? "/" : path;
  if (value.is_string())
    columns[name] = value.get<std::string>();
  else if (value.is_null())
    columns[name] = "";
  else
    columns[name] = value.dump();
}

}  // namespace

std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::map<std::string, std::string> csv_columns(const nlohmann::json& value) {
  std::map<std::string, std::string> columns;
  add_csv_columns(value, "", columns);
  return columns;
}

SweepPoints read_sweep_points(sql::Connection& db, std::int64_t campaign_id) {
  SweepPoints points;
  const auto view = find_campaign_view_rows(db, kSweepPointsView, campaign_id);
  if (!view) return points;
  int key_column = -1;
  for (int column = 0; column < static_cast<int>(view->columns.size()); ++column) {
    if (view->columns[column] == "task_key")
      key_column = column;
    else
      points.columns.push_back(view->columns[column]);
  }
  if (key_column < 0) throw std::logic_error("the sweep_points view has no task_key column");
  for (const auto& row : view->rows) {
    TaskCoordinates point;
    for (int column = 0; column < static_cast<int>(row.size()); ++column) {
      if (column == key_column || !row[column]) continue;
      point.emplace_back(view->columns[column], *row[column]);
    }
    points.by_task[row[key_column].value_or("")] = std::move(point);
  }
  return points;
}

std::vector<fs::path> export_files(const fs::path& db, const std::string& task_or_campaign,
                                   const fs::path& out_dir) {
  auto connection = open_read_only(db);
  const auto campaign = find_campaign_id(connection, task_or_campaign);
  if (!campaign) {
    const std::string key = resolve_task(connection, task_or_campaign);
    return copy_artifacts(db, find_artifacts(connection, key), out_dir);
  }
  const SweepPoints points = read_sweep_points(connection, *campaign);
  std::vector<fs::path> written;
  std::string index = "kind,task_key,folder";
  for (const auto& column : points.columns) index += fmt::format(",{}", csv_field(column));
  index += '\n';
  for (const auto& [kind, key] : find_done_tasks_with_artifacts(connection, *campaign)) {
    const auto found = points.by_task.find(key);
    const TaskCoordinates point = found == points.by_task.end() ? TaskCoordinates{} : found->second;
    const fs::path folder = fs::path(kind) / folder_label(point, key);
    const auto files = copy_artifacts(db, find_artifacts(connection, key), out_dir / folder);
    written.insert(written.end(), files.begin(), files.end());
    index += fmt::format("{},{},{}", kind, key, folder.string());
    for (const auto& column : points.columns) {
      std::string value;
      for (const auto& [name, text] : point) value = name == column ? text : value;
      index += fmt::format(",{}", csv_field(value));
    }
    index += '\n';
  }
  fs::create_directories(out_dir);
  written.push_back(out_dir / "tasks.csv");
  util::write_file_durably(written.back(), index);
  return written;
}

std::vector<std::string> task_log(const fs::path& db, const std::string& task) {
  auto connection = open_read_only(db);
  const std::string key = resolve_task(connection, task);
  std::vector<std::string> lines;
  for (const LogLine& line : find_log_lines(connection, key))
    lines.push_back(fmt::format("{} {} {}", iso8601_utc(line.at), line.level, line.message));
  return lines;
}

}  // namespace millflow::engine
