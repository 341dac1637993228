#include "tasks/sites.hpp"

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <utility>

#include "method/fields_file.hpp"
#include "method/vtk_image.hpp"
#include "tasks/kinds.hpp"
#include "tasks/macro.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

json optional_json(const std::optional<double>& value) {
  return value ? json(*value) : json(nullptr);
}

json regions_json(const std::vector<method::RegionSummary>& regions) {
  json rows = json::array();
  for (const method::RegionSummary& r : regions) {
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

json toe_json(const std::optional<method::Toe>& toe, const std::optional<double>& angle) {
  if (!toe) return nullptr;
  return {{"angle_deg", optional_json(angle)},
          {"position_m", {toe->x, toe->y}},
          {"radius_m", toe->radius_m},
          {"impact_cells", toe->impact_cells},
          {"impact_angle_deg", optional_json(toe->impact_angle_deg)}};
}

json selection_json(const method::SiteSelection& selection, const method::RegionRules& rules) {
  json empty = json::array(), sites = json::array();
  for (const method::RegionSummary& r : selection.regions) {
    if (r.cells == 0) empty.push_back(r.name);
  }
  double weights = 0.0, solid = 0.0;
  for (const method::Site& s : selection.sites) {
    sites.push_back(s);
    weights += s.weight_m3;
    solid += s.solid_volume_m3;
  }
  return {{"rules", json(rules)},
          {"weight_by",
           selection.weight_by == method::WeightBasis::solid_volume ? "solid_volume" : "volume"},
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

json rule_set_json(const std::string& name, const method::RegionRules& rules,
                   const method::Classification& classification) {
  json regions = json::array();
  for (const method::RegionSummary& r : classification.regions) {
    regions.push_back({{"name", r.name},
                       {"volume_m3", r.volume_m3},
                       {"solid_volume_m3", r.solid_volume_m3},
                       {"dissipation_w", r.dissipation_w},
                       {"dissipation_share", r.dissipation_share}});
  }
  return {{"name", name}, {"rules", json(rules)}, {"regions", regions}};
}

const engine::TaskInput& input_of_kind(const engine::TaskContext& context,
                                       const std::string& kind) {
  for (const auto& input : context.inputs) {
    if (input.kind == kind) return input;
  }
  throw std::invalid_argument(fmt::format("sites {}: no {} input", context.key, kind));
}
}  // namespace

method::RegionRules region_rules_from_json(const json& rules, const json& overrides) {
  json merged = rules;
  merged.update(overrides);
  return merged.get<method::RegionRules>();
}

engine::TaskOutcome run_sites(engine::TaskContext& context) {
  std::ifstream file(input_of_kind(context, "average").artifacts.at("fields.json"));
  const json fields = json::parse(file);
  const method::FlowMap map = method::flow_map_from_document(fields);
  const method::MacroResult macro = macro_result_of(input_of_kind(context, "macro"));
  const method::ChargeAngles angles{.toe_deg = macro.charge.toe_angle_deg,
                                    .shoulder_deg = macro.charge.shoulder_angle_deg};
  const json& params = context.params.at("sites");
  const method::RegionRules rules = region_rules_from_json(params.at("rules"));
  const method::WeightBasis weight_by = params.at("weight_by").get<std::string>() == "volume"
                                            ? method::WeightBasis::volume
                                            : method::WeightBasis::solid_volume;
  const method::SiteSelection selection =
      method::select_sites(map, rules, angles, params.at("regions").get<std::vector<std::string>>(),
                           params.at("per_region").get<int>(), weight_by);

  std::vector<double> region_index(selection.region_of_cell.begin(),
                                   selection.region_of_cell.end());
  std::filesystem::create_directories(
      context.work_dir);  // the engine leaves its creation to the task
  const std::vector<method::CellArray> arrays = {{"region", 1, std::move(region_index)},
                                                 {"solid_fraction", 1, map.solid_fraction},
                                                 {"shear_rate_per_s", 1, map.shear_rate},
                                                 {"dissipation_w_m3", 1, map.dissipation}};
  const auto vti = context.work_dir / "regions.vti";
  method::write_vtk_image(vti, map.grid, arrays);

  json result = selection_json(selection, rules);
  result["fill"] = macro.fill;
  result["speed_fraction"] = macro.speed_fraction;
  result["average_task"] = input_of_kind(context, "average").key;
  result["region_index"] = method::region_names();
  json rule_sets = json::array({rule_set_json("default", rules, selection)});
  for (const json& alternative : params.at("alternatives")) {
    const method::RegionRules alternative_rules =
        region_rules_from_json(params.at("rules"), alternative.value("rules", json::object()));
    rule_sets.push_back(rule_set_json(alternative.at("name").get<std::string>(), alternative_rules,
                                      method::classify_regions(map, alternative_rules, angles)));
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
