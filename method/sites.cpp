#include "method/sites.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace millflow::method {
namespace {

enum Region : int { kNearLiner, kCataracting, kToe, kShoulder, kCascading, kBulk };

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

void to_json(nlohmann::json& out, const RegionRules& rules) {
  out = nlohmann::json::object();
  for (const auto& [name, field] : kRuleFields) out[name] = rules.*field;
}

void from_json(const nlohmann::json& in, RegionRules& rules) {
  for (const auto& [name, field] : kRuleFields) rules.*field = in.at(name).get<double>();
}

const std::vector<std::string>& region_names() {
  static const std::vector<std::string> names = {"near_liner", "cataracting", "toe",
                                                 "shoulder",   "cascading",   "bulk"};
  return names;
}

namespace {
constexpr const char* kShearRateKey = "shear_rate_per_s";
constexpr const char* kNormalStressKey = "normal_stress_pa";
constexpr const char* kSiteIdKey = "site_id";
constexpr const char* kRegionKey = "region";
}  // namespace

void to_json(nlohmann::json& out, const CellDrive& drive) {
  out = {{kShearRateKey, drive.shear_rate}, {kNormalStressKey, drive.normal_stress}};
}

void from_json(const nlohmann::json& in, CellDrive& drive) {
  drive.shear_rate = in.at(kShearRateKey).get<double>();
  drive.normal_stress = in.at(kNormalStressKey).get<double>();
}

std::string unusable_reason(const CellDrive& drive) {
  for (const auto& [key, value] : {std::pair{kShearRateKey, drive.shear_rate},
                                   std::pair{kNormalStressKey, drive.normal_stress}}) {
    if (!(value > 0.0 && std::isfinite(value)))
      return fmt::format("{} = {} is not positive", key, value);
  }
  return {};
}

void to_json(nlohmann::json& out, const Site& s) {
  out = {{kSiteIdKey, s.site_id},
         {kRegionKey, s.region},
         {"position_m", {s.x, s.y}},
         {"weight_m3", s.weight_m3},
         {"solid_volume_m3", s.solid_volume_m3},
         {"dissipation_share", s.dissipation_share},
         {"shear_stress_pa", s.shear_stress},
         {"pressure_pa", s.pressure},
         {"solid_fraction", s.solid_fraction},
         {"granular_temperature_m2_s2", s.granular_temperature},
         {"collision_frequency_per_m3_s", s.collision_frequency},
         {"dissipation_w_m3", s.dissipation}};
  out.update(
      nlohmann::json(CellDrive{.shear_rate = s.shear_rate, .normal_stress = s.normal_stress}));
}

std::string site_id_of(const nlohmann::json& site) {
  return site.at(kSiteIdKey).get<std::string>();
}

nlohmann::json drive_site_json(const std::string& site_id, const std::string& region,
                               const CellDrive& drive) {
  nlohmann::json site = drive;
  site.update({{kSiteIdKey, site_id}, {kRegionKey, region}});
  return site;
}

void from_json(const nlohmann::json& in, Site& s) {
  s.site_id = site_id_of(in);
  s.region = in.at(kRegionKey).get<std::string>();
  s.x = in.at("position_m").at(0).get<double>();
  s.y = in.at("position_m").at(1).get<double>();
  s.weight_m3 = in.at("weight_m3").get<double>();
  s.solid_volume_m3 = in.at("solid_volume_m3").get<double>();
  s.dissipation_share = in.at("dissipation_share").get<double>();
  const auto drive = in.get<CellDrive>();
  s.shear_rate = drive.shear_rate;
  s.normal_stress = drive.normal_stress;
  s.shear_stress = in.at("shear_stress_pa").get<double>();
  s.pressure = in.at("pressure_pa").get<double>();
  s.solid_fraction = in.at("solid_fraction").get<double>();
  s.granular_temperature = in.at("granular_temperature_m2_s2").get<double>();
  s.collision_frequency = in.at("collision_frequency_per_m3_s").get<double>();
  s.dissipation = in.at("dissipation_w_m3").get<double>();
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

}  // namespace millflow::method
