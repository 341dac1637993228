#include "tasks/sites.hpp"

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <utility>

#include "method/fields_file.hpp"
#include "method/sites_result.hpp"
#include "method/vtk_image.hpp"
#include "tasks/kinds.hpp"
#include "tasks/macro.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

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

  method::SitesResult result = method::sites_result_of(selection, rules);
  result.fill = macro.fill;
  result.speed_fraction = macro.speed_fraction;
  result.average_task = input_of_kind(context, "average").key;
  result.rule_sets.push_back(method::rule_set_of("default", rules, selection));
  for (const json& alternative : params.at("alternatives")) {
    const method::RegionRules alternative_rules =
        region_rules_from_json(params.at("rules"), alternative.value("rules", json::object()));
    result.rule_sets.push_back(
        method::rule_set_of(alternative.at("name").get<std::string>(), alternative_rules,
                            method::classify_regions(map, alternative_rules, angles)));
  }
  engine::TaskOutcome outcome = engine::TaskOutcome::with_result(result);
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
