#include "tasks/sites.hpp"
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <stdexcept>

#include "tasks/kinds.hpp"
#include "tasks/vtk_image.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

enum Region : int { kNearLiner, kCataracting, kToe, kShoulder, kCascading, kBulk };

std::vector<double> scalar_array(const json& fields, const std::string& name, std::size_t cells) {
  const json& arrays = fields.at("arrays");
  if (!arrays.contains(name))
    throw std::invalid_argument("fields.json has no array '" + name + "': re-run average");
  auto values = arrays.at(name).at("values").get<std::vector<double>>();
  if (values.size() != cells) {
    throw std::invalid_argument(
        fmt::format("fields.json array '{}' holds {} values for {} cells: re-run average", name,
                    values.size(), cells));
  }
  return values;
}

// Where the bed meets the shell, as angles atan2(y, x) (header: the toe and the shoulder).
struct BedEnds {
  double toe = 0.0, shoulder = 0.0, radius = 0.0;
};

std::optional<BedEnds> bed_ends(const FlowMap& map, const RegionRules& rules) {
  constexpr int kSamples = 360;
  const CrossSectionGrid& g = map.grid;
  const double radius = g.half_width - std::max(rules.liner_layer_diameters * map.media_diameter,
                                                std::max(g.dx(), g.dy()));
  auto angle = [](int k) { return 2.0 * std::numbers::pi * k / kSamples - std::numbers::pi; };
  std::vector<double> nu(kSamples);
  for (int k = 0; k < kSamples; ++k) {
    const int i = std::clamp(
        static_cast<int>((radius * std::cos(angle(k)) + g.half_width) / g.dx()), 0, g.nx - 1);
    const int j = std::clamp(
        static_cast<int>((radius * std::sin(angle(k)) + g.half_width) / g.dy()), 0, g.ny - 1);
    nu[static_cast<std::size_t>(k)] = map.solid_fraction[g.index(i, j)];
  }
  auto bed = [&](int k) {
    return nu[static_cast<std::size_t>(((k % kSamples) + kSamples) % kSamples)] >=
           rules.bed_solid_fraction;
  };
  const int bottom = kSamples / 4;  // -90 degrees
  const int anchor =
      bed(bottom) ? bottom : static_cast<int>(std::max_element(nu.begin(), nu.end()) - nu.begin());
  if (!bed(anchor)) return std::nullopt;
  const int with_rotation = map.angular_velocity < 0.0 ? -1 : 1;
  int toe = anchor, shoulder = anchor, covered = 1;
  while (covered < kSamples && bed(toe - with_rotation)) toe -= with_rotation, ++covered;
  while (covered < kSamples && bed(shoulder + with_rotation)) shoulder += with_rotation, ++covered;
  if (covered == kSamples) return std::nullopt;
  return BedEnds{.toe = angle(toe), .shoulder = angle(shoulder), .radius = radius};
}

std::vector<int> classify(const FlowMap& map, const RegionRules& rules,
                          const std::optional<BedEnds>& ends) {
  const CrossSectionGrid& g = map.grid;
  const double liner_layer = rules.liner_layer_diameters * map.media_diameter;
  const double end_radius = rules.end_radius_fraction * g.half_width;
  const double bulk_shear = rules.bulk_max_shear_per_omega * std::abs(map.angular_velocity);
  auto near = [&](double x, double y, double angle) {
    return std::hypot(x - ends->radius * std::cos(angle), y - ends->radius * std::sin(angle)) <=
           end_radius;
  };
  std::vector<int> region(g.size(), -1);
  for (std::size_t c = 0; c < g.size(); ++c) {
    const double x = g.x_of(c), y = g.y_of(c), nu = map.solid_fraction[c];
    if (!g.inside_mill(c) || nu < rules.charge_solid_fraction) continue;
    if (g.half_width - std::hypot(x, y) < liner_layer)
      region[c] = kNearLiner;
    else if (nu < rules.flight_solid_fraction)
      region[c] = kCataracting;
    else if (ends && near(x, y, ends->toe))
      region[c] = kToe;
    else if (ends && near(x, y, ends->shoulder))
      region[c] = kShoulder;
    else if (map.shear_rate[c] >= bulk_shear)
      region[c] = kCascading;
    else
      region[c] = kBulk;
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

std::vector<Site> sites_of_region(const FlowMap& map, std::vector<std::size_t> cells,
                                  const std::string& name, int per_region,
                                  double total_dissipation) {
  std::stable_sort(cells.begin(), cells.end(), [&](std::size_t a, std::size_t b) {
    return map.shear_rate[a] < map.shear_rate[b];
  });
  const std::size_t groups = std::min(cells.size(), static_cast<std::size_t>(per_region));
  std::vector<Site> sites;
  for (std::size_t k = 0; k < groups; ++k) {
    const std::vector<std::size_t> group(
        cells.begin() + static_cast<std::ptrdiff_t>(k * cells.size() / groups),
        cells.begin() + static_cast<std::ptrdiff_t>((k + 1) * cells.size() / groups));
    Site site = site_of(map, group, total_dissipation);
    site.site_id = fmt::format("{}-{}", name, k);
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

json selection_json(const SiteSelection& selection) {
  json regions = json::array(), empty = json::array(), sites = json::array();
  for (const RegionSummary& r : selection.regions) {
    if (r.cells == 0) empty.push_back(r.name);
    regions.push_back({{"name", r.name},
                       {"cells", r.cells},
                       {"volume_m3", r.volume_m3},
                       {"solid_volume_m3", r.solid_volume_m3},
                       {"dissipation_w", r.dissipation_w},
                       {"dissipation_share", r.dissipation_share},
                       {"mean_shear_rate_per_s", r.mean_shear_rate},
                       {"sites", r.sites}});
  }
  double weights = 0.0;
  for (const Site& s : selection.sites) {
    sites.push_back(site_json(s));
    weights += s.weight_m3;
  }
  auto angle = [](const std::optional<double>& a) { return a ? json(*a) : json(nullptr); };
  return {{"regions", regions},
          {"empty_regions", empty},
          {"charge_volume_m3", selection.charge_volume_m3},
          {"sites_volume_m3", weights},
          {"total_dissipation_w", selection.total_dissipation_w},
          {"toe_angle_deg", angle(selection.toe_angle_deg)},
          {"shoulder_angle_deg", angle(selection.shoulder_angle_deg)},
          {"sites", sites}};
}

}  // namespace

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
  return map;
}

SiteSelection select_sites(const FlowMap& map, const RegionRules& rules,
                           const std::vector<std::string>& site_regions, int per_region) {
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
  const auto ends = bed_ends(map, rules);
  if (ends) {
    selection.toe_angle_deg = ends->toe * 180.0 / std::numbers::pi;
    selection.shoulder_angle_deg = ends->shoulder * 180.0 / std::numbers::pi;
  }
  selection.region_of_cell = classify(map, rules, ends);
  const double cell_volume = map.grid.cell_area() * map.slice_length;
  std::vector<std::vector<std::size_t>> cells(names.size());
  for (std::size_t c = 0; c < map.grid.size(); ++c) {
    selection.total_dissipation_w += map.dissipation[c] * cell_volume;
    if (selection.region_of_cell[c] >= 0)
      cells[static_cast<std::size_t>(selection.region_of_cell[c])].push_back(c);
  }
  for (std::size_t r = 0; r < names.size(); ++r) {
    selection.regions.push_back(summarise(map, cells[r], names[r], selection.total_dissipation_w));
    selection.charge_volume_m3 += selection.regions.back().volume_m3;
  }
  for (const std::string& name : site_regions) {
    const std::size_t r =
        static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
    auto sites = sites_of_region(map, cells[r], name, per_region, selection.total_dissipation_w);
    selection.regions[r].sites = sites.size();
    selection.sites.insert(selection.sites.end(), sites.begin(), sites.end());
  }
  return selection;
}

engine::TaskOutcome run_sites(engine::TaskContext& context) {
  const engine::TaskInput& average = context.inputs.at(0);
  std::ifstream file(average.artifacts.at("fields.json"));
  const json fields = json::parse(file);
  const FlowMap map = flow_map_from_document(fields);
  const json& params = context.params.at("sites");
  const SiteSelection selection =
      select_sites(map, RegionRules{}, params.at("regions").get<std::vector<std::string>>(),
                   params.at("per_region").get<int>());

  std::vector<double> region_index(selection.region_of_cell.begin(),
                                   selection.region_of_cell.end());
  const std::vector<CellArray> arrays = {{"region", 1, std::move(region_index)},
                                         {"solid_fraction", 1, map.solid_fraction},
                                         {"shear_rate_per_s", 1, map.shear_rate},
                                         {"dissipation_w_m3", 1, map.dissipation}};
  std::filesystem::create_directories(
      context.work_dir);  // the engine leaves its creation to the task
  const auto vti = context.work_dir / "regions.vti";
  write_vtk_image(vti, map.grid, arrays);

  json result = selection_json(selection);
  result["region_index"] = region_names();
  engine::TaskOutcome outcome = engine::TaskOutcome::with_result(std::move(result));
  outcome.artifacts = {{"regions.vti", vti}};
  context.log(fmt::format("{} sites over a charge of {:.4g} m^3", selection.sites.size(),
                          selection.charge_volume_m3));
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
