#include "tasks/macro_setup.hpp"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "engine/validation.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

// The kind whose parameters these are: the shear_cell kind reads its media and interactions
// through the functions below too, and a missing value must be reported as missing from its own.
struct ParamsOwner {
  const char* kind;
  const char* planner;
};

ParamsOwner owner_of(const json& params) {
  if (params.contains("shear_cell")) return {"shear_cell", "tasks::shear_cells_params"};
  return {"macro", "tasks::macro_params"};
}

const json& field(const json& params, const std::string& path) {
  const json::json_pointer pointer(path);
  if (!params.contains(pointer)) {
    const ParamsOwner owner = owner_of(params);
    throw engine::InvalidInput(
        {{path, fmt::format("is missing from the {} task's parameters", owner.kind),
          fmt::format("plan {} tasks from a validated campaign ({})", owner.kind, owner.planner)}});
  }
  return params.at(pointer);
}

double number(const json& params, const std::string& path) {
  const json& value = field(params, path);
  if (!value.is_number()) {
    throw engine::InvalidInput({{path, "must be a number, got " + value.dump(), "write a number"}});
  }
  return value.get<double>();
}

dem::Material material(const json& params, const std::string& name) {
  return dem::Material{name, number(params, "/materials/" + name + "/density")};
}

dem::MillShell shell(const json& params) {
  dem::MillShell shell{
      .radius = 0.5 * number(params, "/mill/diameter"),
      .length = number(params, "/mill/length"),
      .lifter_count = field(params, "/mill/lifters/count").get<int>(),
      .lifter = {},
      .end_walls = field(params, "/mill/axial_ends").get<std::string>() == "walls"};
  if (shell.lifter_count > 0) {
    shell.lifter =
        dem::LifterProfile{.height = number(params, "/mill/lifters/height"),
                           .base_width = number(params, "/mill/lifters/base_width"),
                           .face_angle_deg = number(params, "/mill/lifters/face_angle_deg")};
  }
  return shell;
}

void set_media_sizes(const json& params, dem::MillSetup& mill) {
  const json& media = field(params, "/media");
  if (media.contains("diameter")) {
    mill.ball_diameter = number(params, "/media/diameter");
    return;
  }
  const json& classes = field(params, "/media/size_distribution");
  for (std::size_t i = 0; i < classes.size(); ++i) {
    const std::string path = "/media/size_distribution/" + std::to_string(i);
    mill.size_distribution.push_back(
        {number(params, path + "/diameter"), number(params, path + "/mass_fraction")});
  }
}

}  // namespace

const json& find_interaction(const json& params, const std::string& a, const std::string& b) {
  for (const json& interaction : field(params, "/interactions")) {
    const auto first = interaction.at("materials").at(0).get<std::string>();
    const auto second = interaction.at("materials").at(1).get<std::string>();
    if ((first == a && second == b) || (first == b && second == a)) return interaction;
  }
  throw engine::InvalidInput(
      {{"/interactions", fmt::format("no interaction is given for \"{}\" and \"{}\"", a, b),
        "add {\"materials\": [\"" + a + "\", \"" + b + "\"], ...} to /interactions"}});
}

double media_diameter(const json& params) {
  dem::MillSetup mill;
  set_media_sizes(params, mill);
  return dem::mean_ball_diameter(mill);
}

std::uint64_t macro_seed(std::uint64_t dem_seed, const std::string& task_key) {
  std::uint64_t hash = 0xcbf29ce484222325ULL;  // FNV-1a, 64 bit
  for (const unsigned char c : task_key) hash = (hash ^ c) * 0x100000001b3ULL;
  return hash ^ (dem_seed * 0x9e3779b97f4a7c15ULL);
}

dem::InteractionSpec interaction_spec(const json& interaction, double reference_mass) {
  dem::InteractionSpec spec{
      .restitution = interaction.at("restitution").get<double>(),
      .friction = interaction.at("friction").get<double>(),
      .tangential_stiffness_ratio = interaction.value("tangential_stiffness_ratio", 2.0 / 7.0),
      .tangential_damping_ratio = interaction.value("tangential_damping_ratio", 0.5)};
  const json& stiffness = interaction.at("stiffness");
  if (stiffness.contains("normal")) {
    spec.normal_stiffness = stiffness.at("normal").get<double>();
  } else {
    spec.normal_stiffness = dem::stiffness_for_collision_duration(
        stiffness.at("collision_time").get<double>(), reference_mass,
        dem::damping_ratio_for_restitution(spec.restitution));
  }
  return spec;
}

std::optional<double> neighbor_skin_fraction(const json& params) {
  const std::string path = "/dem/neighbor_skin_fraction";
  if (field(params, path) == "auto") return std::nullopt;
  return number(params, path);
}

method::MacroSettings macro_settings(const json& params, const std::string& task_key) {
  method::MacroSettings settings;
  dem::MillSetup& mill = settings.mill;
  const auto media = field(params, "/media/material").get<std::string>();
  const auto liner = field(params, "/mill/liner_material").get<std::string>();
  mill.shell = shell(params);
  mill.media = material(params, media);
  mill.liner = material(params, liner);
  set_media_sizes(params, mill);
  const double ball_mass = dem::reference_ball_mass(mill);
  mill.ball_ball = interaction_spec(find_interaction(params, media, media),
                                    dem::effective_mass(ball_mass, ball_mass));
  mill.ball_liner =
      interaction_spec(find_interaction(params, media, liner), dem::effective_mass(ball_mass, 0.0));
  mill.fill = number(params, "/macro/fill");
  mill.speed_fraction = number(params, "/macro/speed_fraction");
  mill.seed = macro_seed(field(params, "/dem/seed").get<std::uint64_t>(), task_key);

  settings.steps_per_collision = field(params, "/dem/steps_per_collision").get<int>();
  settings.skin_fraction = neighbor_skin_fraction(params);
  settings.settle_time = number(params, "/macro/settle_time");
  settings.warmup_revolutions = number(params, "/macro/warmup_revolutions");
  settings.measure_revolutions = number(params, "/macro/measure_revolutions");
  settings.sample_interval = number(params, "/macro/sample_interval");
  settings.vtk_interval = number(params, "/macro/vtk_interval");
  settings.checkpoint_interval_s = number(params, "/macro/checkpoint_interval_s");
  return settings;
}

}  // namespace millflow::tasks
