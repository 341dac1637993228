#include "tasks/shear_cell.hpp"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "dem/material.hpp"
#include "dem/stiffness_policy.hpp"
#include "dem/vtk.hpp"
#include "engine/validation.hpp"
#include "method/cell_result.hpp"
#include "method/sites.hpp"
#include "tasks/checkpoint_cadence.hpp"
#include "tasks/macro_setup.hpp"
#include "util/sphere.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

const json& at(const json& params, const std::string& path) {
  return params.at(json::json_pointer(path));
}

dem::ShearCellSetup::Boundary boundary(const std::string& name) {
  if (name == "walls") return dem::ShearCellSetup::Boundary::RoughWalls;
  if (name == "lees_edwards") return dem::ShearCellSetup::Boundary::LeesEdwards;
  throw engine::InvalidInput(
      {{"/shear_cell/boundary", "is \"" + name + "\"", "write \"walls\" or \"lees_edwards\""}});
}

}  // namespace

std::string stiffness_log(const std::vector<dem::PairStiffness>& pairs,
                          const dem::ShearCellSetup& setup, std::optional<double> factor) {
  std::string text = fmt::format(
      "shear cell stiffness at sigma_n {:.4g} Pa, shear rate {:.4g} 1/s (mean overlap <= {:.3g}, "
      "p95 <= {:.3g} of d_small{}):",
      setup.normal_stress, setup.shear_rate, setup.overlap_bound.mean_fraction,
      setup.overlap_bound.p95_fraction,
      setup.overlap_bound.media_rigidity > 0.0
          ? fmt::format(", media k_n / (sigma_n d_m) >= {:.3g}", setup.overlap_bound.media_rigidity)
          : std::string());
  if (factor)
    text +=
        fmt::format(" the powder pairs' k_n {:g} x the policy's (stiffness sensitivity);", *factor);
  for (const dem::PairStiffness& p : pairs) {
    text += fmt::format(
        " {}: k_n {:.4g} N/m ({} governs; given {:.4g}, static bound {:.4g}, impact bound {:.4g}",
        p.pair, p.chosen, p.governing, p.given, p.static_bound, p.impact_bound);
    if (p.rigidity_bound > 0.0) text += fmt::format(", rigidity bound {:.4g}", p.rigidity_bound);
    text += fmt::format("), kappa {:.4g};", p.kappa);
  }
  return text;
}

dem::ShearCellSetup shear_cell_setup(const json& params, const json& site,
                                     const std::string& task_key) {
  dem::ShearCellSetup setup;
  const json& cell = params.at("shear_cell");
  const auto media = at(params, "/media/material").get<std::string>();
  const auto powder = at(cell, "/powder/material").get<std::string>();
  setup.media_diameter = media_diameter(params);
  setup.media = dem::Material{media, at(params, "/materials/" + media + "/density").get<double>()};
  setup.powder =
      dem::Material{powder, at(params, "/materials/" + powder + "/density").get<double>()};
  setup.powder_diameter_ratio = at(cell, "/powder/diameter_ratio").get<double>();
  setup.powder_load = at(cell, "/powder/load").get<double>();

  const double media_mass = util::sphere_mass(setup.media.density, setup.media_diameter);
  const double powder_mass =
      util::sphere_mass(setup.powder.density, setup.powder_diameter_ratio * setup.media_diameter);
  setup.media_media = interaction_spec(find_interaction(params, media, media),
                                       dem::effective_mass(media_mass, media_mass));
  setup.media_powder = interaction_spec(find_interaction(params, media, powder),
                                        dem::effective_mass(media_mass, powder_mass));
  setup.powder_powder = interaction_spec(find_interaction(params, powder, powder),
                                         dem::effective_mass(powder_mass, powder_mass));

  const json& size = cell.at("size_diameters");
  setup.size_diameters =
      dem::Vec3(size.at(0).get<double>(), size.at(1).get<double>(), size.at(2).get<double>());
  setup.boundary = boundary(cell.at("boundary").get<std::string>());
  const auto drive = site.get<method::CellDrive>();
  setup.shear_rate = drive.shear_rate;
  setup.normal_stress = drive.normal_stress;
  setup.gravity = cell.at("gravity").get<bool>();
  setup.servo_gain = at(cell, "/stress_control/gain").get<double>();
  setup.seed = macro_seed(at(params, "/dem/seed").get<std::uint64_t>(), task_key);
  setup.neighbor_skin_fraction = neighbor_skin_fraction(params);
  setup.steps_per_collision = cell.at("steps_per_collision").get<int>();
  setup.overlap_bound = {
      .mean_fraction = at(cell, "/stiffness/mean_overlap_fraction").get<double>(),
      .p95_fraction = at(cell, "/stiffness/p95_overlap_fraction").get<double>(),
      // Optional, with no default in the field table: a campaign without it keeps its tasks'
      // parameters (and cached results) as they were.
      .media_rigidity = cell.value(json::json_pointer("/stiffness/media_rigidity"), 0.0)};
  return setup;
}

namespace {

// A stiff cell's powder pairs (tasks/shear_cell.hpp): k_n x factor after the policy, and what was
// derived for them to match (the bound that governs stays the policy's).
void stiffen_powder_pairs(double factor, dem::ShearCellSetup& setup,
                          std::vector<dem::PairStiffness>& pairs) {
  setup.media_powder.normal_stiffness *= factor;
  setup.powder_powder.normal_stiffness *= factor;
  for (dem::PairStiffness& p : pairs) {
    if (p.pair == "media-media") continue;
    p.chosen *= factor;
    p.kappa *= factor;
  }
}

}  // namespace

std::optional<double> stiffness_factor(const json& params) {
  const auto found = params.find("stiffness_factor");
  return found == params.end() ? std::nullopt : std::optional(found->get<double>());
}

std::vector<dem::PairStiffness> apply_stiffness_policy(const json& params,
                                                       dem::ShearCellSetup& setup) {
  std::vector<dem::PairStiffness> pairs =
      at(params, "/shear_cell/stiffness/policy").get<std::string>() == "campaign"
          ? dem::describe_stiffness(setup)
          : dem::apply_overlap_bound(setup);
  if (const auto factor = stiffness_factor(params)) stiffen_powder_pairs(*factor, setup, pairs);
  return pairs;
}

namespace {

// Where a cell run keeps its checkpoint in the task's work directory.
constexpr const char* kCheckpointFile = "cell.ckpt";

// The run saved by an earlier attempt, or a fresh one when there is none or it cannot be used.
dem::ShearCellRun resume_or_start(const dem::ShearCellSetup& setup,
                                  const dem::ShearCellProtocol& protocol,
                                  const std::filesystem::path& checkpoint,
                                  engine::TaskContext& context) {
  if (std::filesystem::exists(checkpoint)) {
    try {
      dem::ShearCellRun run = dem::ShearCellRun::resume(setup, protocol, checkpoint);
      context.log(
          fmt::format("shear cell: continuing from the checkpoint at step {} ({}, {:.0f}% done)",
                      run.cell().system().step_count(), run.phase_name(), 100.0 * run.progress()));
      return run;
    } catch (const dem::CorruptData& error) {
      context.log(fmt::format(
          "{}shear cell: the checkpoint {} cannot be used ({}); starting again from scratch",
          engine::kTaskWarning, checkpoint.string(), error.what()));
      std::filesystem::remove(checkpoint);
    }
  }
  return dem::ShearCellRun(setup, protocol);
}

// How compaction went: how long it took against what was expected and its cap, and how far it
// closed the cell.
std::string compaction_summary(const dem::ShearCell& cell) {
  const dem::System& system = cell.system();
  const dem::ShearCellSetup& setup = cell.setup();
  const double nominal_gap = setup.size_diameters.y() * setup.media_diameter;
  return fmt::format(
      "{}shear cell: compacted in {} steps ({:.3g} s; expected {}, at most {}), to a gap of {:.3f} "
      "times the nominal{}",
      cell.compacted_under_load() ? "" : engine::kTaskWarning, system.step_count(), system.time(),
      cell.expected_compaction_steps(), cell.compaction_step_cap(), cell.gap() / nominal_gap,
      cell.compacted_under_load()
          ? ""
          : fmt::format(": its time limit, the bed never carried half the normal stress for {} "
                        "control intervals in a row",
                        dem::kCompactedIntervals));
}

}  // namespace

dem::ShearCellProtocol shear_cell_protocol(const json& params) {
  const json& cell = params.at("shear_cell");
  return {
      .warmup_strain = cell.at("warmup_strain").get<double>(),
      .warmup_windows = kWarmupWindows,
      .max_warmup_strain = cell.at("max_warmup_strain").get<double>(),
      .measure_strain = cell.at("measure_strain").get<double>(),
      .measure = {.standard_error_target = at(cell, "/convergence/standard_error").get<double>(),
                  .max_strain = at(cell, "/convergence/max_strain").get<double>()},
      .code_version = kShearCellVersion};
}

engine::TaskOutcome run_shear_cell(engine::TaskContext& context) {
  const json& cell_params = context.params.at("shear_cell");
  const json& slot = context.params.at("slot");
  const std::optional<double> factor = stiffness_factor(context.params);
  const json powder_load = at(cell_params, "/powder/load");
  const SlotSite found = find_slot_site(context.inputs.at(0).result, slot);
  if (!found.skipped.empty()) {
    context.log(fmt::format("shear cell {} skipped: {}", slot_site_id(slot), found.skipped));
    return engine::TaskOutcome::with_result(method::CellResult{.slot = slot,
                                                               .powder_load = powder_load,
                                                               .skipped = found.skipped,
                                                               .stiffness_factor = factor});
  }
  std::filesystem::create_directories(
      context.work_dir);  // the engine leaves its creation to the task
  const auto checkpoint = context.work_dir / kCheckpointFile;
  dem::ShearCellSetup setup = shear_cell_setup(context.params, found.site, context.key);
  const std::vector<dem::PairStiffness> stiffness = apply_stiffness_policy(context.params, setup);
  dem::ShearCellRun run =
      resume_or_start(setup, shear_cell_protocol(context.params), checkpoint, context);
  context.log(stiffness_log(stiffness, setup, factor));
  CheckpointCadence cadence(cell_params.at("checkpoint_interval_s").get<double>());
  while (!run.done()) {
    if (context.stop.stop_requested() || cadence.due()) {
      run.save(checkpoint);
      cadence.saved();
      if (context.stop.stop_requested()) {
        context.log(fmt::format("shear cell: stopped at step {} ({}); checkpoint saved",
                                run.cell().system().step_count(), run.phase_name()));
        return engine::TaskOutcome::stopped();
      }
    }
    const bool compacting = !run.cell().compacted();
    run.advance(kStepsBetweenPolls);
    if (compacting && run.cell().compacted()) context.log(compaction_summary(run.cell()));
    context.progress(run.progress(), run.phase_name());
  }
  const dem::ShearCell& cell = run.cell();
  const dem::ShearCellMeasurements& m = run.measurements();

  method::CellResult result = method::cell_result(m);
  result.site = found.site;
  result.slot = slot;
  result.powder_load = powder_load;
  result.media_count = cell.media_count();
  result.powder_count = cell.powder_count();
  result.wall_ball_count = cell.wall_ball_count();
  result.stiffness = stiffness;
  result.stiffness_factor = factor;
  result.neighbor_skin_fraction = cell.neighbor_skin_fraction();
  // Timings go to the log, not the result: a result must not depend on the machine's load.
  context.log(fmt::format(
      "shear cell {}: tau {:.4g} Pa, p {:.4g} Pa, mu {:.3g} +- {:.2g}, I {:.3g}, "
      "{:.4g} W/m^3{}{}{}; overlap p95 {:.3g} of d_small; measured {:.3g} strain in "
      "{:.3g} s wall, {:.3g} particle-steps/s",
      slot_site_id(slot), m.shear_stress, m.normal_stress, m.friction,
      m.friction_error.standard_error, m.inertial_number, m.power_density,
      m.steady ? "" : " (not steady)", m.converged ? "" : " (not converged)",
      m.overlap_ok ? "" : " (overlap above its bound)", result.worst_overlap().p95_fraction,
      m.strain, m.wall_seconds, m.particle_steps_per_second));
  const auto snapshot = context.work_dir / "cell.vtp";
  dem::write_particles_vtp(cell.system(), snapshot);
  std::filesystem::remove(checkpoint);
  auto outcome = engine::TaskOutcome::with_result(result);
  outcome.artifacts.push_back({"cell.vtp", snapshot});
  return outcome;
}

}  // namespace millflow::tasks
