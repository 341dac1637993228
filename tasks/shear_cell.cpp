#include "tasks/shear_cell.hpp"

#include <cmath>
#include <filesystem>
#include <numbers>

#include <fmt/format.h>

#include "dem/material.hpp"
#include "dem/stiffness_policy.hpp"
#include "dem/vtk.hpp"
#include "engine/validation.hpp"
#include "method/macro_measure.hpp"
#include "tasks/checkpoint_cadence.hpp"
#include "tasks/macro_setup.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

const json& at(const json& params, const std::string& path) {
  return params.at(json::json_pointer(path));
}

double sphere_mass(double density, double diameter) {
  return density * std::numbers::pi * diameter * diameter * diameter / 6.0;
}

dem::ShearCellSetup::Boundary boundary(const std::string& name) {
  if (name == "walls") return dem::ShearCellSetup::Boundary::RoughWalls;
  if (name == "lees_edwards") return dem::ShearCellSetup::Boundary::LeesEdwards;
  throw engine::InvalidInput(
      {{"/shear_cell/boundary", "is \"" + name + "\"", "write \"walls\" or \"lees_edwards\""}});
}

bool involves_powder(dem::ContactType type) {
  return type == dem::ContactType::MediaPowder || type == dem::ContactType::PowderPowder ||
         type == dem::ContactType::WallPowder;
}

json collisions_json(const dem::CollisionStats& stats) {
  return {{"count", stats.count}, {"rate_per_m3_s", stats.rate_per_volume}};
}

json spectra_json(const dem::ShearCellMeasurements& m) {
  const dem::LogHistogram& grid = m.media_collisions.dissipated_energy;
  std::vector<double> edges;
  for (std::size_t k = 0; k < grid.bin_count(); ++k) edges.push_back(grid.bin_lower(k));
  if (grid.bin_count() > 0) edges.push_back(grid.bin_upper(grid.bin_count() - 1));
  return {{"bin_edges_j", edges},
          {"media", method::histogram_json(m.media_collisions.dissipated_energy)},
          {"powder", method::histogram_json(m.powder_collisions.dissipated_energy)}};
}

}  // namespace

std::string stiffness_log(const std::vector<dem::PairStiffness>& pairs,
                          const dem::ShearCellSetup& setup) {
  std::string text = fmt::format(
      "shear cell stiffness at sigma_n {:.4g} Pa, shear rate {:.4g} 1/s (mean overlap <= {:.3g} "
      "of d_small):",
      setup.normal_stress, setup.shear_rate, setup.overlap_bound.mean_fraction);
  for (const dem::PairStiffness& p : pairs) {
    text += fmt::format(
        " {}: k_n {:.4g} N/m (given {:.4g}, static bound {:.4g}, impact bound {:.4g}), kappa "
        "{:.4g};",
        p.pair, p.chosen, p.given, p.static_bound, p.impact_bound, p.kappa);
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

  const double media_mass = sphere_mass(setup.media.density, setup.media_diameter);
  const double powder_mass =
      sphere_mass(setup.powder.density, setup.powder_diameter_ratio * setup.media_diameter);
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
  setup.shear_rate = site.at("shear_rate_per_s").get<double>();
  setup.normal_stress = site.at("normal_stress_pa").get<double>();
  setup.gravity = cell.at("gravity").get<bool>();
  setup.servo_gain = at(cell, "/stress_control/gain").get<double>();
  setup.seed = macro_seed(at(params, "/dem/seed").get<std::uint64_t>(), task_key);
  setup.neighbor_skin_fraction = at(params, "/dem/neighbor_skin_fraction").get<double>();
  setup.steps_per_collision = cell.at("steps_per_collision").get<int>();
  setup.overlap_bound = {
      .mean_fraction = at(cell, "/stiffness/mean_overlap_fraction").get<double>(),
      .p95_fraction = at(cell, "/stiffness/p95_overlap_fraction").get<double>()};
  return setup;
}

std::vector<dem::PairStiffness> apply_stiffness_policy(const json& params,
                                                       dem::ShearCellSetup& setup) {
  if (at(params, "/shear_cell/stiffness/policy").get<std::string>() == "campaign")
    return dem::describe_stiffness(setup);
  return dem::apply_overlap_bound(setup);
}

json stiffness_json(const std::vector<dem::PairStiffness>& pairs) {
  json out = json::object();
  for (const dem::PairStiffness& p : pairs) {
    out[p.pair] = {{"k_n_n_m", p.chosen},
                   {"kappa", p.kappa},
                   {"given_n_m", p.given},
                   {"static_bound_n_m", p.static_bound},
                   {"impact_bound_n_m", p.impact_bound}};
  }
  return out;
}

json measurements_json(const dem::ShearCellMeasurements& m) {
  json dissipation = json::object(), collisions = json::object(), overlap = json::object();
  json dissipation_errors = json::object();
  double powder_dissipation = 0.0;
  const dem::OverlapStats* worst = nullptr;
  for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) {
    const auto type = static_cast<dem::ContactType>(t);
    dissipation[dem::contact_type_name(type)] = m.dissipation_density[t];
    dissipation_errors[dem::contact_type_name(type)] = m.dissipation_standard_error[t];
    collisions[dem::contact_type_name(type)] = collisions_json(m.collisions[t]);
    if (involves_powder(type)) powder_dissipation += m.dissipation_density[t];
    const dem::OverlapStats& o = m.overlaps[t];
    if (o.contacts == 0.0) continue;
    overlap[dem::contact_type_name(type)] = {{"mean_fraction", o.mean_fraction},
                                             {"p95_fraction", o.p95_fraction},
                                             {"max_fraction", o.max_fraction},
                                             {"contact_samples", o.contacts}};
    if (worst == nullptr || o.p95_fraction > worst->p95_fraction) worst = &o;
  }
  dissipation["total"] = m.dissipation_density_total;
  dissipation_errors["total"] = m.dissipation_total_error.standard_error;
  const dem::OverlapStats none;
  if (worst == nullptr) worst = &none;
  const auto& s = m.stress_tensor;
  collisions["media"] = collisions_json(m.media_collisions);
  collisions["powder"] = collisions_json(m.powder_collisions);
  return {
      {"strain", m.strain},
      {"duration_s", m.duration},
      {"steps", m.steps},
      {"target_shear_rate_per_s", m.target_shear_rate},
      {"bulk_shear_rate_per_s", m.bulk_shear_rate},
      {"nominal_shear_rate_per_s", m.nominal_shear_rate},
      {"wall_speed_m_s", m.wall_speed},
      {"wall_slip_m_s", m.wall_slip},
      {"gap_m", m.gap},
      {"volume_m3", m.volume},
      {"shear_stress_pa", m.shear_stress},
      {"normal_stress_pa", m.normal_stress},
      {"friction", m.friction},
      {"friction_mean_pressure", m.friction_mean_pressure},
      {"stresses",
       {{"xx", s[0]},
        {"yy", s[1]},
        {"zz", s[2]},
        {"xy", s[3]},
        {"xz", s[4]},
        {"yz", s[5]},
        {"mean_pressure_pa", m.mean_pressure},
        {"p_yy_pa", m.normal_stress}}},
      {"inertial_number", m.inertial_number},
      {"inertial_number_measured_rate", m.inertial_number_measured_rate},
      {"media_solid_fraction", m.media_solid_fraction},
      {"powder_solid_fraction", m.powder_solid_fraction},
      {"solid_fraction", m.media_solid_fraction + m.powder_solid_fraction},
      {"power_density_w_m3", m.power_density},
      {"dissipation_w_m3", dissipation},
      {"powder_dissipation_w_m3", powder_dissipation},
      {"collisions", collisions},
      {"spectra", spectra_json(m)},
      {"energy",
       {{"work_in_j", m.work_in},
        {"kinetic_change_j", m.kinetic_change},
        {"elastic_change_j", m.elastic_change},
        {"dissipated_j", m.dissipated},
        {"stress_control_work_j", m.stress_control_work},
        {"balance_error", m.energy_balance_error}}},
      {"steady_state",
       {{"shear_stress_first_half_pa", m.shear_stress_first_half},
        {"shear_stress_second_half_pa", m.shear_stress_second_half},
        {"deviation", m.steady_state_deviation},
        {"steady", m.steady}}},
      {"steady", m.steady},
      {"stationary_strain", m.stationary ? json(m.stationary_strain) : json()},
      {"converged", m.converged},
      {"standard_errors",
       {{"friction", m.friction_error.standard_error},
        {"friction_mean_pressure", m.friction_mean_pressure_error.standard_error},
        {"shear_stress_pa", m.shear_stress_error.standard_error},
        {"normal_stress_pa", m.normal_stress_error.standard_error},
        {"power_density_w_m3", m.power_density_error.standard_error},
        {"powder_dissipation_w_m3", m.powder_dissipation_error.standard_error},
        {"dissipation_w_m3", dissipation_errors},
        {"blocks", m.blocks},
        {"batch_blocks", m.batch_blocks}}},
      {"overlap", overlap},
      {"overlap_mean_fraction", worst->mean_fraction},
      {"overlap_p95_fraction", worst->p95_fraction},
      {"overlap_max_fraction", worst->max_fraction},
      {"overlap_ok", m.overlap_ok},
  };
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

}  // namespace

dem::ShearCellProtocol shear_cell_protocol(const json& params) {
  const json& cell = params.at("shear_cell");
  return {
      .warmup_strain = cell.at("warmup_strain").get<double>(),
      .warmup_windows = kWarmupWindows,
      .max_warmup_strain = cell.at("max_warmup_strain").get<double>(),
      .measure_strain = cell.at("measure_strain").get<double>(),
      .measure = {.standard_error_target = at(cell, "/convergence/standard_error").get<double>(),
                  .max_strain = at(cell, "/convergence/max_strain").get<double>()}};
}

engine::TaskOutcome run_shear_cell(engine::TaskContext& context) {
  const json& cell_params = context.params.at("shear_cell");
  const json& slot = context.params.at("slot");
  const json powder_load = at(cell_params, "/powder/load");
  const SlotSite found = find_slot_site(context.inputs.at(0).result, slot);
  if (!found.skipped.empty()) {
    context.log(fmt::format("shear cell {} skipped: {}", slot_site_id(slot), found.skipped));
    return engine::TaskOutcome::with_result(
        {{"skipped", found.skipped}, {"slot", slot}, {"powder_load", powder_load}});
  }
  std::filesystem::create_directories(
      context.work_dir);  // the engine leaves its creation to the task
  const auto checkpoint = context.work_dir / kCheckpointFile;
  dem::ShearCellSetup setup = shear_cell_setup(context.params, found.site, context.key);
  const std::vector<dem::PairStiffness> stiffness = apply_stiffness_policy(context.params, setup);
  dem::ShearCellRun run =
      resume_or_start(setup, shear_cell_protocol(context.params), checkpoint, context);
  context.log(stiffness_log(stiffness, setup));
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
    run.advance(kStepsBetweenPolls);
    context.progress(run.progress(), run.phase_name());
  }
  const dem::ShearCell& cell = run.cell();
  const dem::ShearCellMeasurements& m = run.measurements();

  json result = measurements_json(m);
  result["site"] = found.site;
  result["slot"] = slot;
  result["powder_load"] = powder_load;
  result["media_count"] = cell.media_count();
  result["powder_count"] = cell.powder_count();
  result["wall_ball_count"] = cell.wall_ball_count();
  result["stiffness"] = stiffness_json(stiffness);
  // Timings go to the log, not the result: a result must not depend on the machine's load.
  context.log(
      fmt::format("shear cell {}: tau {:.4g} Pa, p {:.4g} Pa, mu {:.3g} +- {:.2g}, I {:.3g}, "
                  "{:.4g} W/m^3{}{}{}; overlap p95 {:.3g} of d_small; measured {:.3g} strain in "
                  "{:.3g} s wall, {:.3g} particle-steps/s",
                  slot_site_id(slot), m.shear_stress, m.normal_stress, m.friction,
                  m.friction_error.standard_error, m.inertial_number, m.power_density,
                  m.steady ? "" : " (not steady)", m.converged ? "" : " (not converged)",
                  m.overlap_ok ? "" : " (overlap above its bound)",
                  measurements_json(m).at("overlap_p95_fraction").get<double>(), m.strain,
                  m.wall_seconds, m.particle_steps_per_second));
  const auto snapshot = context.work_dir / "cell.vtp";
  dem::write_particles_vtp(cell.system(), snapshot);
  std::filesystem::remove(checkpoint);
  auto outcome = engine::TaskOutcome::with_result(std::move(result));
  outcome.artifacts.push_back({"cell.vtp", snapshot});
  return outcome;
}

}  // namespace millflow::tasks
