#include "tasks/millflow.hpp"

#include <algorithm>
#include <set>

#include "engine/outputs.hpp"
#include "tasks/campaign.hpp"
#include "tasks/cost_model.hpp"
#include "tasks/kinds.hpp"

namespace millflow::tasks {
namespace {

// The interactions whose two materials are both in `names`.
nlohmann::json interactions_among(const nlohmann::json& interactions,
                                  const std::set<std::string>& names) {
  nlohmann::json kept = nlohmann::json::array();
  for (const auto& interaction : interactions) {
    const auto& pair = interaction.at("materials");
    if (names.count(pair.at(0).get<std::string>()) && names.count(pair.at(1).get<std::string>())) {
      kept.push_back(interaction);
    }
  }
  return kept;
}

}  // namespace

nlohmann::json macro_params(const nlohmann::json& point) {
  const std::set<std::string> names{point.at("media").at("material").get<std::string>(),
                                    point.at("mill").at("liner_material").get<std::string>()};
  nlohmann::json materials = nlohmann::json::object();
  for (const auto& name : names) materials[name] = point.at("materials").at(name);
  return {{"materials", materials},
          {"interactions", interactions_among(point.at("interactions"), names)},
          {"dem", point.at("dem")},
          {"mill", point.at("mill")},
          {"media", point.at("media")},
          {"macro", point.at("macro")}};
}

nlohmann::json shear_cells_params(const nlohmann::json& point) {
  const std::set<std::string> names{
      point.at("media").at("material").get<std::string>(),
      point.at("shear_cell").at("powder").at("material").get<std::string>()};
  nlohmann::json materials = nlohmann::json::object();
  for (const auto& name : names) materials[name] = point.at("materials").at(name);
  // The cells' time step is /shear_cell's; the seed and the skin are the campaign's.
  const nlohmann::json& dem = point.at("dem");
  // The stiffness sensitivity says which cells to plan, not how a cell runs: without it in their
  // parameters the default cells keep their keys whether a campaign asks for it or not.
  nlohmann::json cell = point.at("shear_cell");
  if (cell.contains("stiffness")) cell["stiffness"].erase("sensitivity");
  return {
      {"shear_cell", std::move(cell)},
      {"materials", materials},
      {"interactions", interactions_among(point.at("interactions"), names)},
      {"media", point.at("media")},
      {"dem",
       {{"seed", dem.at("seed")}, {"neighbor_skin_fraction", dem.at("neighbor_skin_fraction")}}}};
}

nlohmann::json average_params(const nlohmann::json& point) {
  return {{"average", point.at("average")}};
}

nlohmann::json sites_params(const nlohmann::json& point) {
  return {{"sites", point.at("sites")}};
}

nlohmann::json upscale_params(const nlohmann::json& point) {
  const nlohmann::json& materials = point.at("materials");
  const nlohmann::json& powder = point.at("shear_cell").at("powder");
  return {{"powder_load", powder.at("load")},
          {"upscale", point.at("upscale")},
          {"media_density_kg_m3",
           materials.at(point.at("media").at("material").get<std::string>()).at("density")},
          {"powder_density_kg_m3",
           materials.at(powder.at("material").get<std::string>()).at("density")}};
}

namespace {

// One cell per slot: each of `regions` x the indices below `per_region`.
std::vector<std::string> plan_slots(engine::Plan& plan, const nlohmann::json& base,
                                    const nlohmann::json& regions, int per_region,
                                    const std::string& sites) {
  std::vector<std::string> cells;
  for (const auto& region : regions) {
    for (int index = 0; index < per_region; ++index) {
      nlohmann::json params = base;
      params["slot"] = {{"region", region}, {"index", index}};
      cells.push_back(plan.add("shear_cell", std::move(params), {sites}));
    }
  }
  return cells;
}

}  // namespace

std::vector<std::string> plan_shear_cells(engine::Plan& plan, const nlohmann::json& point,
                                          const std::string& sites) {
  const nlohmann::json& chosen = point.at("sites");
  return plan_slots(plan, shear_cells_params(point), chosen.at("regions"),
                    chosen.at("per_region").get<int>(), sites);
}

std::vector<std::string> plan_stiff_cells(engine::Plan& plan, const nlohmann::json& point,
                                          const std::string& sites) {
  const auto sensitivity = nlohmann::json::json_pointer("/shear_cell/stiffness/sensitivity");
  if (!point.contains(sensitivity)) return {};
  const nlohmann::json& asked = point.at(sensitivity);
  nlohmann::json base = shear_cells_params(point);
  base["stiffness_factor"] = asked.at("factor");
  return plan_slots(plan, base, asked.value("regions", point.at("sites").at("regions")),
                    asked.at("sites_per_region").get<int>(), sites);
}

namespace {

// The point with no powder: its cells are the reference of cushioning and of the coupling check.
nlohmann::json without_powder(nlohmann::json point) {
  point["shear_cell"]["powder"]["load"] = 0.0;
  return point;
}

}  // namespace

// Per point: macro -> average -> sites, and with shear cells on: its cells (and those without
// powder, and the stiff ones of /shear_cell/stiffness/sensitivity) -> upscale; one report over
// every upscale and the macro, average and sites tasks its figures are drawn from.
void plan_millflow(const nlohmann::json& campaign, engine::Plan& plan) {
  std::vector<std::string> report_inputs;
  for (const CampaignPoint& point : expand(campaign)) {
    const nlohmann::json& document = point.document;
    const std::string macro = plan.add("macro", macro_params(document));
    const std::string average = plan.add("average", average_params(document), {macro});
    const std::string sites = plan.add("sites", sites_params(document), {average, macro});
    if (!document.at("shear_cell").at("enabled").get<bool>()) continue;
    const double load = document.at("shear_cell").at("powder").at("load").get<double>();
    std::vector<std::string> upstream = {macro, average, sites};
    for (const auto& cell : plan_shear_cells(plan, document, sites)) upstream.push_back(cell);
    if (load != 0.0) {
      for (const auto& cell : plan_shear_cells(plan, without_powder(document), sites))
        upstream.push_back(cell);
      // Without powder the stiff cells would be the default ones: those are their reference.
      for (const auto& cell : plan_stiff_cells(plan, document, sites)) upstream.push_back(cell);
    }
    report_inputs.push_back(plan.add("upscale", upscale_params(document), std::move(upstream)));
    // The loads of a fill and speed share one macro, average and sites task: the report needs each
    // once.
    for (const std::string& shared : {macro, average, sites}) {
      if (std::find(report_inputs.begin(), report_inputs.end(), shared) == report_inputs.end())
        report_inputs.push_back(shared);
    }
  }
  if (!report_inputs.empty())
    plan.add("report", {{"campaign", campaign.at("name")}}, std::move(report_inputs));
}

// Each task's place in the sweep (engine/outputs.hpp): fill and speed from its macro run
// (view macro_lineage), the powder load of a cell or an upscale, a cell's site and region.
engine::ViewDefinition sweep_points_view() {
  return {engine::kSweepPointsView, R"sql(
SELECT t.key AS task_key,
       lineage.fill AS fill,
       lineage.speed_fraction AS speed_fraction,
       CASE t.kind WHEN 'shear_cell' THEN json_extract(t.params, '$.shear_cell.powder.load')
                   WHEN 'upscale' THEN json_extract(t.params, '$.powder_load') END AS powder_load,
       CASE t.kind WHEN 'shear_cell' THEN json_extract(t.params, '$.slot.region') || '-' ||
                                          json_extract(t.params, '$.slot.index') END AS site_id,
       CASE t.kind WHEN 'shear_cell' THEN json_extract(t.params, '$.slot.region') END AS region
FROM tasks t LEFT JOIN macro_lineage lineage ON lineage.task_key = t.key
)sql"};
}

void register_millflow(engine::Registry& registry) {
  registry.add_format(engine::CampaignFormat{
      .name = "millflow_campaign", .load = load_campaign, .plan = plan_millflow});
  register_macro(registry);
  register_average(registry);
  register_sites(registry);
  register_shear_cells(registry);
  register_upscale(registry);
  register_report(registry);
  register_cost_models(registry.kinds);
  registry.views.push_back(sweep_points_view());  // after macro_lineage, which it reads
}

}  // namespace millflow::tasks
