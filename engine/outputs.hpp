#pragma once
// A campaign's outputs outside the store: each task's sweep point, and its artifacts written
// under their own names (`millflow files`), where ParaView and scripts can open them.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/sqlite.hpp"

namespace millflow::engine {

// The view a campaign format may install to say where in its sweep each task sits: a column
// task_key plus one column per sweep coordinate (NULL where a coordinate does not apply to the
// task). Exports put these columns first; `millflow files` names folders after them.
inline constexpr const char* kSweepPointsView = "sweep_points";

// Coordinate name and value (SQLite's text of it) of the non-NULL coordinates, in the view's
// column order; none when the store has no such view or the task no row in it.
using TaskCoordinates = std::vector<std::pair<std::string, std::string>>;
struct SweepPoints {
  std::vector<std::string> columns;  // the view's coordinates (without task_key)
  std::map<std::string, TaskCoordinates> by_task;
};
SweepPoints read_sweep_points(sql::Connection& db, std::int64_t campaign_id);

// `text` as one CSV field: quoted (quotes doubled) when it holds a comma, quote or line break.
std::string csv_field(const std::string& text);

// The scalar leaves of a JSON value as CSV cells, by path ("/power/mean_kw"; "/" for a scalar
// value itself): strings as their plain text (no JSON quotes), numbers and booleans as JSON
// writes them, null as an empty cell, and an array or empty object as its compact JSON text
// (one cell). Objects are walked into, so each scalar gets its own column.
std::map<std::string, std::string> csv_columns(const nlohmann::json& value);

// Writes the artifacts of `task_or_campaign` under `out_dir`, each verified (size and SHA-256)
// before it is copied, under its own name and folders (vtk/particles.pvd beside the
// vtk/particles_NNNN.vtp it lists):
//   a task (key or unique prefix):  <out_dir>/<artifact name>
//   a campaign (its name):          <out_dir>/<kind>/<label>/<artifact name> for every finished
//     task with artifacts, label = its sweep point ("fill0.3_speed_fraction0.75") and the first
//     8 characters of its key, plus <out_dir>/tasks.csv (kind, task_key, folder, coordinates).
// Returns the written files. Throws InvalidInput for an unknown name and std::runtime_error for
// a missing or corrupt artifact.
std::vector<std::filesystem::path> export_files(const std::filesystem::path& db,
                                                const std::string& task_or_campaign,
                                                const std::filesystem::path& out_dir);

// The log lines of one task (key or unique prefix), oldest first: "<ISO time> <level> <message>".
std::vector<std::string> task_log(const std::filesystem::path& db, const std::string& task);

}  // namespace millflow::engine
