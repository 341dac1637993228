#pragma once
// fields.json: the coarse-grained fields of one mill run as the average task writes them
// (tasks/average.hpp) and the sites task and the report read them back.
//   {"grid": {nx, ny, half_width_m}, "slice_length_m", "arrays": {name: {components, values}}}
// plus the entries of `mill` (merged at the top level: mill_radius_m, media_diameter_m,
// angular_velocity_rad_s, kernel_width_m). Array names: method/coarse_grain.hpp cell_arrays.
#include <nlohmann/json.hpp>

#include "method/coarse_grain.hpp"
#include "method/sites.hpp"

namespace millflow::method {

nlohmann::json fields_document(const CoarseFields& fields, const nlohmann::json& mill);

// The fields the region rules read. Throws std::invalid_argument naming a missing or mis-sized
// array.
FlowMap flow_map_from_document(const nlohmann::json& fields);

}  // namespace millflow::method
