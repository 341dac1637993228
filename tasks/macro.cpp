#include "tasks/macro.hpp"

#include <chrono>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "method/macro_run.hpp"
#include "tasks/checkpoint_cadence.hpp"
#include "tasks/kinds.hpp"
#include "tasks/macro_setup.hpp"

namespace millflow::tasks {
namespace {

namespace fs = std::filesystem;

// Steps between polls of the stop token and the checkpoint cadence.
constexpr std::uint64_t kStepsBetweenPolls = 64;

// The run an earlier attempt saved, or a fresh one when there is none or it cannot be used.
method::MacroRun resume_or_start(const method::MacroSettings& settings,
                                 engine::TaskContext& context) {
  const method::MacroRun::Log log = [&context](const std::string& line) { context.log(line); };
  if (method::MacroRun::saved_in(context.work_dir)) {
    try {
      return method::MacroRun::resume(settings, context.work_dir, log);
    } catch (const dem::CorruptData& error) {
      // A damaged checkpoint (flipped, truncated, deleted) must not fail every resume the same
      // way: its work is lost, the run starts again and gives the same result.
      context.log(fmt::format(
          "{}macro: the checkpoint in {} cannot be used ({}); starting again from scratch",
          engine::kTaskWarning, context.work_dir.string(), error.what()));
      fs::remove_all(context.work_dir);
    }
  }
  fs::create_directories(context.work_dir);
  return method::MacroRun(settings, context.work_dir, log);
}

std::string result_field(const char* name, const char* path) {
  return fmt::format("json_extract(r.result, '{}') AS {}", path, name);
}

std::string param_field(const char* name, const char* path) {
  return fmt::format("json_extract(t.params, '{}') AS {}", path, name);
}

}  // namespace

engine::TaskOutcome run_macro(engine::TaskContext& context) {
  using Clock = std::chrono::steady_clock;
  const method::MacroSettings settings = macro_settings(context.params, context.key);
  method::MacroRun run = resume_or_start(settings, context);
  CheckpointCadence cadence(settings.checkpoint_interval_s);
  const auto wall_start = Clock::now();
  const std::uint64_t first_step = run.system().step_count();
  while (!run.done()) {
    if (context.stop.stop_requested()) {
      run.save();
      context.log(fmt::format("macro: stopped at step {} (t = {:.4g} s); checkpoint saved",
                              run.system().step_count(), run.system().time()));
      return engine::TaskOutcome::stopped();
    }
    if (cadence.due()) {
      run.save();
      cadence.saved();
    }
    run.advance(kStepsBetweenPolls);
    if (context.progress) context.progress(run.progress(), run.phase_name());
  }
  const std::uint64_t steps = run.system().step_count() - first_step;
  const double seconds = std::chrono::duration<double>(Clock::now() - wall_start).count();
  if (steps > 0 && seconds > 0.0) {
    context.log(fmt::format(
        "macro: {} steps of {} balls in {:.3g} s wall: {:.4g} particle-steps/s on {} threads",
        steps, run.system().size(), seconds,
        static_cast<double>(steps * run.system().size()) / seconds, context.threads));
  }
  method::MacroOutcome finished = run.finish();
  engine::TaskOutcome outcome = engine::TaskOutcome::with_result(finished.result);
  for (const std::string& name : finished.artifacts)
    outcome.artifacts.push_back({name, context.work_dir / name});
  return outcome;
}

method::MacroResult macro_result_of(const engine::TaskInput& macro) {
  return method::read_macro_result(macro.result, fmt::format("macro task {}", macro.key));
}

engine::ViewDefinition macro_lineage_view() {
  // Every task reaches its sweep point's macro run along first-upstream edges
  // (shear_cell -> shear_cells -> sites -> average -> macro).
  return {"macro_lineage", R"sql(
WITH RECURSIVE up(task_key, ancestor) AS (
  SELECT key, key FROM tasks
  UNION
  SELECT up.task_key, e.upstream FROM up JOIN edges e ON e.downstream = up.ancestor AND e.position = 0
)
SELECT up.task_key AS task_key,
       m.key AS macro_key,
       json_extract(m.params, '$.macro.fill') AS fill,
       json_extract(m.params, '$.macro.speed_fraction') AS speed_fraction
FROM up JOIN tasks m ON m.key = up.ancestor AND m.kind = 'macro'
)sql"};
}

engine::ViewDefinition macro_results_view() {
  const std::vector<std::string> columns = {
      "c.name AS campaign",
      "t.key AS task_key",
      param_field("fill", "$.macro.fill"),
      param_field("speed_fraction", "$.macro.speed_fraction"),
      result_field("power_kw", "$.power.mean_kw"),
      result_field("power_kw_per_m", "$.power.kw_per_m"),
      result_field("power_kw_per_t_balls", "$.power.kw_per_t_balls"),
      result_field("power_std_kw", "$.power.std_kw"),
      result_field("torque_arm_power_kw", "$.power.torque_arm_kw"),
      result_field("liner_torque_n_m", "$.frame_means.drive_torque_n_m.liner"),
      result_field("lifter_torque_n_m", "$.frame_means.drive_torque_n_m.lifters"),
      result_field("kinetic_energy_translational_j",
                   "$.frame_means.kinetic_energy_j.translational"),
      result_field("kinetic_energy_rotational_j", "$.frame_means.kinetic_energy_j.rotational"),
      result_field("centre_of_mass_x_m", "$.frame_means.centre_of_mass_m.x"),
      result_field("centre_of_mass_y_m", "$.frame_means.centre_of_mass_m.y"),
      result_field("toe_angle_deg", "$.charge.toe_angle_deg"),
      result_field("shoulder_angle_deg", "$.charge.shoulder_angle_deg"),
      result_field("n_balls", "$.n_balls"),
      result_field("ball_mass_kg", "$.ball_mass_kg"),
      param_field("mill_diameter_m", "$.mill.diameter"),
      result_field("dt_s", "$.dt_s"),
      "t.status AS status",
  };
  return {
      "macro_results",
      fmt::format("SELECT {} FROM campaign_tasks ct JOIN campaigns c ON c.id = ct.campaign_id "
                  "JOIN tasks t ON t.key = ct.task_key LEFT JOIN results r ON r.task_key = t.key "
                  "WHERE t.kind = 'macro'",
                  fmt::join(columns, ", "))};
}

void register_macro(engine::Registry& registry) {
  registry.kinds.add(engine::TaskKind{.name = "macro", .version = kMacroVersion, .run = run_macro});
  registry.views.push_back(macro_lineage_view());
  registry.views.push_back(macro_results_view());
}

}  // namespace millflow::tasks
