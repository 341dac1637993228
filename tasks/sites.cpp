#include "tasks/sites.hpp"
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "tasks/kinds.hpp"
#include "tasks/vtk_image.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

enum Region : int { kNearLiner, kCataracting, kToe, kShoulder, kCascading, kBulk };

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

double liner_layer(const FlowMap& map, const RegionRules& rules) {
  return rules.liner_layer_diameters * map.media_diameter;
}

// The toe and shoulder points' circle: just inside the liner layer, at least one cell in.
double end_point_radius(const FlowMap& map, const RegionRules& rules) {
  const CrossSectionGrid& g = map.grid;
  return g.half_width - std::max(liner_layer(map, rules), std::max(g.dx(), g.dy()));
}

bool in_charge(const FlowMap& map, const RegionRules& rules, std::size_t c) {
  return map.grid.inside_mill(c) && map.solid_fraction[c] >= rules.charge_solid_fraction;
}

double radians(double degrees) {
  return degrees * std::numbers::pi / 180.0;
}

// The toe disc around the toe point, sized to hold the impact zone (header).
Toe find_toe(const FlowMap& map, const RegionRules& rules, double toe_deg) {
  const CrossSectionGrid& g = map.grid;
  const double r = end_point_radius(map, rules);
  Toe toe;
  toe.x = r * std::cos(radians(toe_deg));
  toe.y = r * std::sin(radians(toe_deg));
  const double search = rules.toe_search_radius_fraction * g.half_width;
  auto distance = [&](std::size_t c) { return std::hypot(g.x_of(c) - toe.x, g.y_of(c) - toe.y); };
  double peak = 0.0;
  for (std::size_t c = 0; c < g.size(); ++c) {
    if (in_charge(map, rules, c) && distance(c) <= search)
      peak = std::max(peak, map.dissipation[c]);
  }
  double farthest = 0.0, weight = 0.0, cx = 0.0, cy = 0.0;
  for (std::size_t c = 0; c < g.size(); ++c) {
    if (peak <= 0.0 || !in_charge(map, rules, c) || distance(c) > search ||
        map.dissipation[c] < rules.impact_dissipation_fraction * peak) {
      continue;
    }
    ++toe.impact_cells;
    farthest = std::max(farthest, distance(c));
    weight += map.dissipation[c];
    cx += map.dissipation[c] * g.x_of(c);
    cy += map.dissipation[c] * g.y_of(c);
  }
  if (weight > 0.0) toe.impact_angle_deg = std::atan2(cy, cx) * 180.0 / std::numbers::pi;
  const double holds_impact = toe.impact_cells ? farthest + 0.5 * std::hypot(g.dx(), g.dy()) : 0.0;
  toe.radius_m = std::clamp(holds_impact, rules.toe_min_radius_fraction * g.half_width, search);
  return toe;
}

// |V - omega x r| over the rigid-body speed |omega| |r| (|r| at least one cell, near the axis).
double slip_from_shell(const FlowMap& map, std::size_t c) {
  const CrossSectionGrid& g = map.grid;
  const double x = g.x_of(c), y = g.y_of(c), omega = map.angular_velocity;
  const double rigid_speed = std::abs(omega) * std::max(std::hypot(x, y), g.dx());
  const double deviation = std::hypot(map.velocity_x[c] + omega * y, map.velocity_y[c] - omega * x);
  return rigid_speed > 0.0 ? deviation / rigid_speed : std::numeric_limits<double>::infinity();
}

std::vector<int> classify(const FlowMap& map, const RegionRules& rules,
                          const std::optional<Toe>& toe,
                          const std::optional<double>& shoulder_deg) {
  const CrossSectionGrid& g = map.grid;
  const double layer = liner_layer(map, rules);
  const double ends = end_point_radius(map, rules);
  const double shoulder_radius = rules.shoulder_radius_fraction * g.half_width;
  auto in_toe = [&](double x, double y) {
    return toe && std::hypot(x - toe->x, y - toe->y) <= toe->radius_m;
  };
  auto in_shoulder = [&](double x, double y) {
    return shoulder_deg &&
           std::hypot(x - ends * std::cos(radians(*shoulder_deg)),
                      y - ends * std::sin(radians(*shoulder_deg))) <= shoulder_radius;
  };
  std::vector<int> region(g.size(), -1);
  for (std::size_t c = 0; c < g.size(); ++c) {
    if (!in_charge(map, rules, c)) continue;
    const double x = g.x_of(c), y = g.y_of(c);
    if (in_toe(x, y))
      region[c] = kToe;
    else if (g.half_width - std::hypot(x, y) < layer)
      region[c] = kNearLiner;
    else if (map.solid_fraction[c] < rules.flight_solid_fraction)
      region[c] = kCataracting;
    else if (in_shoulder(x, y))
      region[c] = kShoulder;
    else if (slip_from_shell(map, c) <= rules.en_masse_max_slip)
      region[c] = kBulk;
    else
      region[c] = kCascading;
  }
  return region;
}

// One site from a group of cells of one region.
Site site_of(const FlowMap& map, const std::vector<std::size_t>& cells, double total_dissipation) {
  const CrossSectionGrid& g = map.grid;
  const double cell_volume = g.cell_area() * map.slice_length;
  Site s;
  double solid = 0.0, cx = 0.0, cy = 0.0, dissipated = 0.0;
  for (std::size_t c : cells) {
    const double nu = map.solid_fraction[c];
    solid += nu;
    cx += nu * g.x_of(c);
    cy += nu * g.y_of(c);
    s.shear_rate += nu * map.shear_rate[c];
    s.normal_stress += nu * map.normal_stress[c];
    s.shear_stress += nu * map.shear_stress[c];
    s.pressure += nu * map.pressure[c];
    s.granular_temperature += nu * map.granular_temperature[c];
    s.collision_frequency += map.collision_frequency[c];
    dissipated += map.dissipation[c];
  }
  const double n = static_cast<double>(cells.size());
  for (double* solid_weighted : {&s.shear_rate, &s.normal_stress, &s.shear_stress, &s.pressure,
                                 &s.granular_temperature, &cx, &cy}) {
    *solid_weighted /= solid;
  }
  s.solid_fraction = solid / n;
  s.collision_frequency /= n;
  s.dissipation = dissipated / n;
  s.weight_m3 = n * cell_volume;
  s.solid_volume_m3 = solid * cell_volume;
  s.dissipation_share =
      total_dissipation > 0.0 ? dissipated * cell_volume / total_dissipation : 0.0;
  const auto nearest =
      std::min_element(cells.begin(), cells.end(), [&](std::size_t a, std::size_t b) {
        return std::hypot(g.x_of(a) - cx, g.y_of(a) - cy) <
               std::hypot(g.x_of(b) - cx, g.y_of(b) - cy);
      });
  s.x = g.x_of(*nearest);
  s.y = g.y_of(*nearest);
  return s;
}

// The region's cells sorted by shear rate, split into up to `per_region` contiguous groups of
// nearly equal weight (cell count, or solid volume: a cell goes to the group its solid midpoint
// falls in, so a group can come out empty and is then dropped).
std::vector<Site> sites_of_region(const FlowMap& map, std::vector<std::size_t> cells,
                                  const std::string& name, int per_region, double total_dissipation,
                                  WeightBasis weight_by) {
  std::stable_sort(cells.begin(), cells.end(), [&](std::size_t a, std::size_t b) {
    return map.shear_rate[a] < map.shear_rate[b];
  });
  const std::size_t groups = std::min(cells.size(), static_cast<std::size_t>(per_region));
  std::vector<std::vector<std::size_t>> members(groups);
  double solid = 0.0;
  for (std::size_t c : cells) solid += map.solid_fraction[c];
  double before = 0.0;
  for (std::size_t k = 0; k < cells.size(); ++k) {
    const double nu = map.solid_fraction[cells[k]];
    const double position =
        weight_by == WeightBasis::solid_volume
            ? (before + 0.5 * nu) / solid
            : (static_cast<double>(k) + 0.5) / static_cast<double>(cells.size());
    before += nu;
    members[std::min(groups - 1, static_cast<std::size_t>(position * static_cast<double>(groups)))]
        .push_back(cells[k]);
  }
  std::vector<Site> sites;
  for (const auto& group : members) {
    if (group.empty()) continue;
    Site site = site_of(map, group, total_dissipation);
    site.site_id = fmt::format("{}-{}", name, sites.size());
    site.region = name;
    sites.push_back(std::move(site));
  }
  return sites;
}

RegionSummary summarise(const FlowMap& map, const std::vector<std::size_t>& cells,
                        const std::string& name, double total_dissipation) {
  const double cell_volume = map.grid.cell_area() * map.slice_length;
  RegionSummary r{.name = name, .cells = cells.size()};
  double solid = 0.0, shear = 0.0;
  for (std::size_t c : cells) {
    solid += map.solid_fraction[c];
    shear += map.solid_fraction[c] * map.shear_rate[c];
    r.dissipation_w += map.dissipation[c] * cell_volume;
  }
  r.volume_m3 = static_cast<double>(cells.size()) * cell_volume;
  r.solid_volume_m3 = solid * cell_volume;
  r.mean_shear_rate = solid > 0.0 ? shear / solid : 0.0;
  r.dissipation_share = total_dissipation > 0.0 ? r.dissipation_w / total_dissipation : 0.0;
  return r;
}

json site_json(const Site& s) {
  return {{"site_id", s.site_id},
          {"region", s.region},
          {"position_m", {s.x, s.y}},
          {"weight_m3", s.weight_m3},
          {"solid_volume_m3", s.solid_volume_m3},
          {"dissipation_share", s.dissipation_share},
          {"shear_rate_per_s", s.shear_rate},
          {"normal_stress_pa", s.normal_stress},
          {"shear_stress_pa", s.shear_stress},
          {"pressure_pa", s.pressure},
          {"solid_fraction", s.solid_fraction},
          {"granular_temperature_m2_s2", s.granular_temperature},
          {"collision_frequency_per_m3_s", s.collision_frequency},
          {"dissipation_w_m3", s.dissipation}};
}

json optional_json(const std::optional<double>& value) {
  return value ? json(*value) : json(nullptr);
}

json regions_json(const std::vector<RegionSummary>& regions) {
  json rows = json::array();
  for (const RegionSummary& r : regions) {
    rows.push_back({{"name", r.name},
                    {"cells", r.cells},
                    {"volume_m3", r.volume_m3},
                    {"solid_volume_m3", r.solid_volume_m3},
                    {"dissipation_w", r.dissipation_w},
                    {"dissipation_share", r.dissipation_share},
                    {"mean_shear_rate_per_s", r.mean_shear_rate},
                    {"sites", r.sites}});
  }
  return rows;
}

json toe_json(const std::optional<Toe>& toe, const std::optional<double>& angle) {
  if (!toe) return nullptr;
  return {{"angle_deg", optional_json(angle)},
          {"position_m", {toe->x, toe->y}},
          {"radius_m", toe->radius_m},
          {"impact_cells", toe->impact_cells},
          {"impact_angle_deg", optional_json(toe->impact_angle_deg)}};
}

json selection_json(const SiteSelection& selection, const RegionRules& rules) {
  json empty = json::array(), sites = json::array();
  for (const RegionSummary& r : selection.regions) {
    if (r.cells == 0) empty.push_back(r.name);
  }
  double weights = 0.0, solid = 0.0;
  for (const Site& s : selection.sites) {
    sites.push_back(site_json(s));
    weights += s.weight_m3;
    solid += s.solid_volume_m3;
  }
  return {
      {"rules", region_rules_json(rules)},
      {"weight_by", selection.weight_by == WeightBasis::solid_volume ? "solid_volume" : "volume"},
      {"regions", regions_json(selection.regions)},
      {"empty_regions", empty},
      {"charge_volume_m3", selection.charge_volume_m3},
      {"charge_solid_volume_m3", selection.charge_solid_volume_m3},
      {"sites_volume_m3", weights},
      {"sites_solid_volume_m3", solid},
      {"total_dissipation_w", selection.total_dissipation_w},
      {"toe_angle_deg", optional_json(selection.toe_angle_deg)},
      {"shoulder_angle_deg", optional_json(selection.shoulder_angle_deg)},
      {"toe", toe_json(selection.toe, selection.toe_angle_deg)},
      {"sites", sites}};
}

json rule_set_json(const std::string& name, const RegionRules& rules,
                   const Classification& classification) {
  json regions = json::array();
  for (const RegionSummary& r : classification.regions) {
    regions.push_back({{"name", r.name},
                       {"volume_m3", r.volume_m3},
                       {"solid_volume_m3", r.solid_volume_m3},
                       {"dissipation_w", r.dissipation_w},
                       {"dissipation_share", r.dissipation_share}});
  }
  return {{"name", name}, {"rules", region_rules_json(rules)}, {"regions", regions}};
}

ChargeAngles charge_angles(const json& macro_result) {
  const json& charge = macro_result.at("charge");
  auto angle = [&](const char* key) {
    return charge.at(key).is_number() ? std::optional(charge.at(key).get<double>()) : std::nullopt;
  };
  return {.toe_deg = angle("toe_angle_deg"), .shoulder_deg = angle("shoulder_angle_deg")};
}

const engine::TaskInput& input_of_kind(const engine::TaskContext& context,
                                       const std::string& kind) {
  for (const auto& input : context.inputs) {
    if (input.kind == kind) return input;
  }
  throw std::invalid_argument(fmt::format("sites {}: no {} input", context.key, kind));
}

}  // namespace

// Each rule's name in /sites/rules.
constexpr std::pair<const char*, double RegionRules::*> kRuleFields[] = {
    {"charge_solid_fraction", &RegionRules::charge_solid_fraction},
    {"flight_solid_fraction", &RegionRules::flight_solid_fraction},
    {"liner_layer_diameters", &RegionRules::liner_layer_diameters},
    {"toe_search_radius_fraction", &RegionRules::toe_search_radius_fraction},
    {"impact_dissipation_fraction", &RegionRules::impact_dissipation_fraction},
    {"toe_min_radius_fraction", &RegionRules::toe_min_radius_fraction},
    {"shoulder_radius_fraction", &RegionRules::shoulder_radius_fraction},
    {"en_masse_max_slip", &RegionRules::en_masse_max_slip}};

json region_rules_json(const RegionRules& rules) {
  json out = json::object();
  for (const auto& [name, field] : kRuleFields) out[name] = rules.*field;
  return out;
}

const std::vector<std::string>& region_names() {
  static const std::vector<std::string> names = {"near_liner", "cataracting", "toe",
                                                 "shoulder",   "cascading",   "bulk"};
  return names;
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

RegionRules region_rules_from_json(const json& rules, const json& overrides) {
  json merged = rules;
  merged.update(overrides);
  RegionRules out;
  for (const auto& [name, field] : kRuleFields) out.*field = merged.at(name).get<double>();
  return out;
}

Classification classify_regions(const FlowMap& map, const RegionRules& rules,
                                const ChargeAngles& angles) {
  Classification result;
  if (angles.toe_deg) result.toe = find_toe(map, rules, *angles.toe_deg);
  result.region_of_cell = classify(map, rules, result.toe, angles.shoulder_deg);
  const auto& names = region_names();
  const double cell_volume = map.grid.cell_area() * map.slice_length;
  std::vector<std::vector<std::size_t>> cells(names.size());
  for (std::size_t c = 0; c < map.grid.size(); ++c) {
    result.total_dissipation_w += map.dissipation[c] * cell_volume;
    if (result.region_of_cell[c] >= 0)
      cells[static_cast<std::size_t>(result.region_of_cell[c])].push_back(c);
  }
  for (std::size_t r = 0; r < names.size(); ++r) {
    result.regions.push_back(summarise(map, cells[r], names[r], result.total_dissipation_w));
    result.charge_volume_m3 += result.regions.back().volume_m3;
    result.charge_solid_volume_m3 += result.regions.back().solid_volume_m3;
  }
  return result;
}

SiteSelection select_sites(const FlowMap& map, const RegionRules& rules, const ChargeAngles& angles,
                           const std::vector<std::string>& site_regions, int per_region,
                           WeightBasis weight_by) {
  if (per_region < 1)
    throw std::invalid_argument(fmt::format("{} sites per region: ask for at least 1", per_region));
  const auto& names = region_names();
  for (const std::string& name : site_regions) {
    if (std::find(names.begin(), names.end(), name) == names.end()) {
      throw std::invalid_argument(
          fmt::format("unknown flow region '{}': use one of {}", name, fmt::join(names, ", ")));
    }
  }
  SiteSelection selection;
  static_cast<Classification&>(selection) = classify_regions(map, rules, angles);
  selection.weight_by = weight_by;
  selection.toe_angle_deg = angles.toe_deg;
  selection.shoulder_angle_deg = angles.shoulder_deg;
  for (const std::string& name : site_regions) {
    const std::size_t r =
        static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
    std::vector<std::size_t> cells;
    for (std::size_t c = 0; c < map.grid.size(); ++c) {
      if (selection.region_of_cell[c] == static_cast<int>(r)) cells.push_back(c);
    }
    auto sites =
        sites_of_region(map, cells, name, per_region, selection.total_dissipation_w, weight_by);
    selection.regions[r].sites = sites.size();
    selection.sites.insert(selection.sites.end(), sites.begin(), sites.end());
  }
  return selection;
}

engine::TaskOutcome run_sites(engine::TaskContext& context) {
  std::ifstream file(input_of_kind(context, "average").artifacts.at("fields.json"));
  const json fields = json::parse(file);
  const FlowMap map = flow_map_from_document(fields);
  const ChargeAngles angles = charge_angles(input_of_kind(context, "macro").result);
  const json& params = context.params.at("sites");
  const RegionRules rules = region_rules_from_json(params.at("rules"));
  const WeightBasis weight_by = params.at("weight_by").get<std::string>() == "volume"
                                    ? WeightBasis::volume
                                    : WeightBasis::solid_volume;
  const SiteSelection selection =
      select_sites(map, rules, angles, params.at("regions").get<std::vector<std::string>>(),
                   params.at("per_region").get<int>(), weight_by);

  std::vector<double> region_index(selection.region_of_cell.begin(),
                                   selection.region_of_cell.end());
  std::filesystem::create_directories(
      context.work_dir);  // the engine leaves its creation to the task
  const std::vector<CellArray> arrays = {{"region", 1, std::move(region_index)},
                                         {"solid_fraction", 1, map.solid_fraction},
                                         {"shear_rate_per_s", 1, map.shear_rate},
                                         {"dissipation_w_m3", 1, map.dissipation}};
  const auto vti = context.work_dir / "regions.vti";
  write_vtk_image(vti, map.grid, arrays);

  json result = selection_json(selection, rules);
  const json& macro = input_of_kind(context, "macro").result;
  result["fill"] = macro.at("fill");
  result["speed_fraction"] = macro.at("speed_fraction");
  result["average_task"] = input_of_kind(context, "average").key;
  result["region_index"] = region_names();
  json rule_sets = json::array({rule_set_json("default", rules, selection)});
  for (const json& alternative : params.at("alternatives")) {
    const RegionRules alternative_rules =
        region_rules_from_json(params.at("rules"), alternative.value("rules", json::object()));
    rule_sets.push_back(rule_set_json(alternative.at("name").get<std::string>(), alternative_rules,
                                      classify_regions(map, alternative_rules, angles)));
  }
  result["rule_sets"] = std::move(rule_sets);
  engine::TaskOutcome outcome = engine::TaskOutcome::with_result(std::move(result));
  outcome.artifacts = {{"regions.vti", vti}};
  context.log(fmt::format("{} sites over a charge of {:.4g} m^3 ({:.4g} m^3 solid)",
                          selection.sites.size(), selection.charge_volume_m3,
                          selection.charge_solid_volume_m3));
  return outcome;
}

engine::ViewDefinition sites_view() {
  return {"sites", R"sql(
SELECT c.name AS campaign,
       lineage.fill AS fill,
       lineage.speed_fraction AS speed_fraction,
       st.key AS sites_task,
       json_extract(site.value, '$.site_id') AS site_id,
       json_extract(site.value, '$.region') AS region,
       json_extract(site.value, '$.weight_m3') AS weight_m3,
       json_extract(site.value, '$.solid_volume_m3') AS solid_volume_m3,
       json_extract(site.value, '$.dissipation_share') AS dissipation_share,
       json_extract(site.value, '$.shear_rate_per_s') AS shear_rate_per_s,
       json_extract(site.value, '$.normal_stress_pa') AS normal_stress_pa,
       json_extract(site.value, '$.shear_stress_pa') AS shear_stress_pa,
       json_extract(site.value, '$.pressure_pa') AS pressure_pa,
       json_extract(site.value, '$.solid_fraction') AS solid_fraction,
       json_extract(site.value, '$.granular_temperature_m2_s2') AS granular_temperature,
       json_extract(site.value, '$.collision_frequency_per_m3_s') AS collision_frequency_per_m3_s,
       json_extract(site.value, '$.position_m[0]') AS x_m,
       json_extract(site.value, '$.position_m[1]') AS y_m
FROM campaign_tasks ct
JOIN campaigns c ON c.id = ct.campaign_id
JOIN tasks st ON st.key = ct.task_key AND st.kind = 'sites' AND st.status = 'done'
JOIN results r ON r.task_key = st.key
JOIN macro_lineage lineage ON lineage.task_key = st.key
JOIN json_each(r.result, '$.sites') site
)sql"};
}

void register_sites(engine::Registry& registry) {
  registry.kinds.add(engine::TaskKind{.name = "sites", .version = kSitesVersion, .run = run_sites});
  registry.views.push_back(sites_view());
}

}  // namespace millflow::tasks
