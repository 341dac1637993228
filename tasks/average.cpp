#include "tasks/average.hpp"
#include <filesystem>

#include <fmt/format.h>

#include <atomic>
#include <cmath>
#include <fstream>
#include <numbers>

#include "engine/campaign.hpp"
#include "engine/validation.hpp"
#include "method/fields_file.hpp"
#include "method/vtk_image.hpp"
#include "tasks/kinds.hpp"
#include "tasks/macro.hpp"
#include "util/durable_file.hpp"
#include "util/sphere.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

std::vector<std::filesystem::path> flow_segments(const engine::TaskInput& macro) {
  std::vector<std::filesystem::path> segments;
  for (const auto& [name, path] : macro.artifacts) {  // a map: sorted by name
    if (name.starts_with("flow/segment_")) segments.push_back(path);
  }
  if (segments.empty()) {
    throw engine::InvalidInput(
        {{"/inputs/0/artifacts", "the macro task left no flow/segment_*.mfs artifacts",
          "re-run the macro task with flow sampling"}});
  }
  return segments;
}

// The balls' density from their total mass and their volume in the first frame.
double media_density(const method::MacroResult& macro, const std::filesystem::path& first_segment) {
  const auto frames = dem::read_flow_segment(first_segment);
  if (frames.empty()) throw std::invalid_argument("the first flow segment holds no frames");
  double volume = 0.0;
  for (float r : frames.front().radius) volume += util::sphere_volume_of_radius(r);
  return macro.ball_mass_kg / volume;
}

method::CoarseGrainSettings settings_for(const json& params, const method::MacroResult& macro,
                                         double density) {
  const json& average = params.at("average");
  const double diameter = macro.media_diameter_m;
  method::CoarseGrainSettings s;
  s.grid = method::CrossSectionGrid{.nx = average.at("grid_cells").at(0).get<int>(),
                                    .ny = average.at("grid_cells").at(1).get<int>(),
                                    .half_width = macro.mill.radius_m};
  s.slice_length = macro.mill.length_m;
  s.kernel_width = average.at("kernel_width_diameters").get<double>() * diameter;
  s.media_density = density;
  s.event_window = static_cast<double>(macro.frame_count) * macro.sample_interval_s;
  s.categories = macro.categories;
  return s;
}

// Maximum, and mean over the cells holding charge (solid fraction at or above `charge`).
json scalar_summaries(const method::CoarseFields& fields, double charge) {
  json out = json::object();
  for (const method::CellArray& array : method::cell_arrays(fields)) {
    if (array.components != 1) continue;
    double max = 0.0, sum = 0.0;
    int count = 0;
    for (std::size_t c = 0; c < array.values.size(); ++c) {
      max = std::max(max, array.values[c]);
      if (fields.solid_fraction[c] >= charge) {
        sum += array.values[c];
        ++count;
      }
    }
    out[array.name] = {{"max", max}, {"mean_over_charge", count > 0 ? sum / count : 0.0}};
  }
  return out;
}

json mill_wide_rates(const method::CoarseFields& fields) {
  json out = json::object();
  for (std::size_t k = 0; k < fields.categories.size(); ++k) {
    out[fields.categories[k]] = {
        {"collisions_per_s", fields.integral(fields.collision_frequency_by_category[k])},
        {"dissipation_w", fields.integral(fields.dissipation_by_category[k])}};
  }
  out["total"] = {{"collisions_per_s", fields.integral(fields.collision_frequency)},
                  {"dissipation_w", fields.integral(fields.dissipation)}};
  return out;
}

void write_json(const std::filesystem::path& file, const json& document) {
  util::write_file_durably(file, document.dump());
}

}  // namespace

engine::TaskOutcome run_average(engine::TaskContext& context) {
  const engine::TaskInput& macro = context.inputs.at(0);
  const auto segments = flow_segments(macro);
  const method::MacroResult macro_result = macro_result_of(macro);
  const method::CoarseGrainSettings settings =
      settings_for(context.params, macro_result, media_density(macro_result, segments.front()));

  std::atomic<std::size_t> loaded{0};
  const auto load = [&](std::size_t index) {
    auto frames = dem::read_flow_segment(segments.at(index));
    const std::size_t done = ++loaded;
    context.progress(static_cast<double>(done) / (2.0 * static_cast<double>(segments.size())),
                     "averaging flow segments");
    return frames;
  };
  const method::CoarseFields fields = method::coarse_grain(settings, segments.size(), load);

  const json mill = {{"mill_radius_m", settings.grid.half_width},
                     {"media_diameter_m", macro_result.media_diameter_m},
                     {"angular_velocity_rad_s", macro_result.angular_velocity_rad_s},
                     {"kernel_width_m", settings.kernel_width}};
  std::filesystem::create_directories(
      context.work_dir);  // the engine leaves its creation to the task
  const auto vti = context.work_dir / "fields.vti";
  const auto arrays = method::cell_arrays(fields);
  method::write_vtk_image(vti, fields.grid, arrays);
  const auto fields_json = context.work_dir / "fields.json";
  write_json(fields_json, method::fields_document(fields, mill));

  const double integrated = fields.solid_volume();
  json result = {
      {"grid",
       {{"nx", settings.grid.nx}, {"ny", settings.grid.ny}, {"cell_size_m", settings.grid.dx()}}},
      {"kernel_width_m", settings.kernel_width},
      {"kernel_width_diameters", context.params.at("average").at("kernel_width_diameters")},
      {"media_density_kg_m3", settings.media_density},
      {"frame_count", fields.frame_count},
      {"segment_count", segments.size()},
      {"event_window_s", settings.event_window},
      {"mass_conservation",
       {{"media_volume_m3", fields.media_volume},
        {"integrated_volume_m3", integrated},
        {"relative_error", (integrated - fields.media_volume) / fields.media_volume}}},
      {"fields", scalar_summaries(fields, settings.min_solid_fraction_for_velocity)},
      {"mill_wide", mill_wide_rates(fields)},
  };
  result.update(mill);
  engine::TaskOutcome outcome = engine::TaskOutcome::with_result(std::move(result));
  outcome.artifacts = {{"fields.vti", vti}, {"fields.json", fields_json}};
  context.log(fmt::format(
      "averaged {} frames onto {} x {} cells; solid volume {:.6g} m^3 vs media {:.6g} m^3",
      fields.frame_count, settings.grid.nx, settings.grid.ny, integrated, fields.media_volume));
  return outcome;
}

void register_average(engine::Registry& registry) {
  registry.kinds.add(
      engine::TaskKind{.name = "average", .version = kAverageVersion, .run = run_average});
}

}  // namespace millflow::tasks
