#include "method/fields_file.hpp"

#include <fmt/format.h>

#include <stdexcept>

namespace millflow::method {
namespace {

using nlohmann::json;

std::vector<double> cell_array(const json& fields, const std::string& name, std::size_t cells,
                               std::size_t components) {
  const json& arrays = fields.at("arrays");
  if (!arrays.contains(name))
    throw std::invalid_argument("fields.json has no array '" + name + "': re-run average");
  auto values = arrays.at(name).at("values").get<std::vector<double>>();
  if (values.size() != cells * components) {
    throw std::invalid_argument(
        fmt::format("fields.json array '{}' holds {} values for {} cells: re-run average", name,
                    values.size(), cells));
  }
  return values;
}

std::vector<double> scalar_array(const json& fields, const std::string& name, std::size_t cells) {
  return cell_array(fields, name, cells, 1);
}

std::vector<double> vector_array(const json& fields, const std::string& name, std::size_t cells) {
  return cell_array(fields, name, cells, 3);
}

}  // namespace

json fields_document(const CoarseFields& fields, const json& mill) {
  json arrays = json::object();
  for (CellArray& array : cell_arrays(fields)) {
    arrays[array.name] = {{"components", array.components}, {"values", std::move(array.values)}};
  }
  json document = mill;
  document["grid"] = {
      {"nx", fields.grid.nx}, {"ny", fields.grid.ny}, {"half_width_m", fields.grid.half_width}};
  document["slice_length_m"] = fields.slice_length;
  document["arrays"] = std::move(arrays);
  return document;
}

FlowMap flow_map_from_document(const json& fields) {
  FlowMap map;
  const json& grid = fields.at("grid");
  map.grid = CrossSectionGrid{.nx = grid.at("nx").get<int>(),
                              .ny = grid.at("ny").get<int>(),
                              .half_width = grid.at("half_width_m").get<double>()};
  map.slice_length = fields.at("slice_length_m").get<double>();
  map.media_diameter = fields.at("media_diameter_m").get<double>();
  map.angular_velocity = fields.at("angular_velocity_rad_s").get<double>();
  const std::size_t cells = map.grid.size();
  map.solid_fraction = scalar_array(fields, "solid_fraction", cells);
  map.shear_rate = scalar_array(fields, "shear_rate_per_s", cells);
  map.normal_stress = scalar_array(fields, "normal_stress_pa", cells);
  map.shear_stress = scalar_array(fields, "shear_stress_pa", cells);
  map.pressure = scalar_array(fields, "pressure_pa", cells);
  map.granular_temperature = scalar_array(fields, "granular_temperature_m2_s2", cells);
  map.collision_frequency = scalar_array(fields, "collision_frequency_per_m3_s", cells);
  map.dissipation = scalar_array(fields, "dissipation_w_m3", cells);
  const std::vector<double> velocity = vector_array(fields, "velocity_m_s", cells);
  map.velocity_x.resize(cells);
  map.velocity_y.resize(cells);
  for (std::size_t c = 0; c < cells; ++c) {
    map.velocity_x[c] = velocity[3 * c];
    map.velocity_y[c] = velocity[3 * c + 1];
  }
  return map;
}

}  // namespace millflow::method
