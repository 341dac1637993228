#pragma once
// One shear cell outside a campaign (`millflow cell SPEC.json`): for calibrating rheology and for
// comparing a cell with other DEM codes.
//
// The spec file holds a campaign's /materials, /interactions, /media, /shear_cell and (optional)
// /dem blocks, checked by the same field table and cross-field checks as a campaign, plus
//   /shear_rate      the cell's target shear rate, 1/s (0.01 to 1e4)
//   /normal_stress   the normal stress it imposes, Pa (1 to 1e8)
// The cell runs as a shear_cell task of site "cell-0" would (tasks/shear_cell.hpp), its seed
// from /dem/seed and the key "cell"; its result is that task's result JSON.
#include <filesystem>
#include <functional>
#include <optional>
#include <stop_token>
#include <string_view>

#include <nlohmann/json.hpp>

#include "engine/json_validator.hpp"
#include "tasks/cost_model.hpp"

namespace millflow::tasks {

// The fields of a cell spec.
const engine::FieldTable& cell_spec_table();

// Reads and validates a spec file; throws engine::InvalidInput with every error.
nlohmann::json load_cell_spec(const std::filesystem::path& file);
nlohmann::json parse_cell_spec(std::string_view text);

// What a running cell tells its caller, and when it should stop.
struct CellRunHooks {
  std::function<void(std::string_view line)> log;
  // The fraction done (dem::ShearCellRun::progress: compaction against its expected steps, the
  // rest against the strain caps) and what it does.
  std::function<void(double fraction, std::string_view phase)> progress;
  std::stop_token stop;
};

// Runs the validated spec's cell in out_dir (created; it keeps cell.vtp and result.json, and the
// checkpoint while it runs, so an interrupted command continues where it stopped). Returns the
// result JSON, or none when a stop was requested: the cell saved its checkpoint and stopped.
// The cell runs on the threads of the calling task arena.
std::optional<nlohmann::json> run_cell_spec(const nlohmann::json& spec,
                                            const std::filesystem::path& out_dir,
                                            const CellRunHooks& hooks);

// The validated spec's cell as the cost model prices it (tasks/cost_model.hpp).
TaskCost cell_spec_cost(const nlohmann::json& spec);

}  // namespace millflow::tasks
