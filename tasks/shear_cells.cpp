#include <cmath>

#include <fmt/format.h>

#include "tasks/kinds.hpp"
#include "tasks/shear_cell.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

// Why a site cannot drive a shear cell, or nothing when it can.
std::string unusable_reason(const json& site) {
  for (const char* key : {"shear_rate_per_s", "normal_stress_pa"}) {
    const double value = site.at(key).get<double>();
    if (!(value > 0.0 && std::isfinite(value))) return fmt::format("{} = {} is not positive", key, value);
  }
  return {};
}

json site_params(const json& site) {
  json picked = json::object();
  for (const char* key :
       {"site_id", "region", "shear_rate_per_s", "normal_stress_pa", "weight_m3", "dissipation_share"}) {
    picked[key] = site.at(key);
  }
  return picked;
}

}  // namespace

engine::TaskOutcome run_shear_cells(engine::TaskContext& context) {
  engine::TaskOutcome outcome;
  json skipped = json::array();
  for (const json& site : context.inputs.at(0).result.at("sites")) {
    if (const std::string reason = unusable_reason(site); !reason.empty()) {
      skipped.push_back({{"site_id", site.at("site_id")}, {"reason", reason}});
      continue;
    }
    json params = context.params;
    params["site"] = site_params(site);
    outcome.children.push_back(engine::ChildTask{.kind = "shear_cell", .params = std::move(params), .extra_upstream = {}});
  }
  outcome.result = {{"children", outcome.children.size()}, {"skipped", skipped}};
  context.log(fmt::format("{} shear cells, {} sites skipped", outcome.children.size(), skipped.size()));
  return outcome;
}

// One row per finished shear cell, with the sweep point it belongs to (view macro_lineage).
engine::ViewDefinition micro_results_view() {
  return {"micro_results", R"sql(
SELECT c.name AS campaign,
       lineage.fill AS fill,
       lineage.speed_fraction AS speed_fraction,
       cell.key AS task_key,
       json_extract(cell.params, '$.site.site_id') AS site_id,
       json_extract(cell.params, '$.site.region') AS region,
       json_extract(cell.params, '$.site.weight_m3') AS weight_m3,
       json_extract(cell.params, '$.shear_cell.powder.load') AS powder_load,
       json_extract(cell.params, '$.site.shear_rate_per_s') AS shear_rate_per_s,
       json_extract(cell.params, '$.site.normal_stress_pa') AS normal_stress_pa,
       json_extract(r.result, '$.bulk_shear_rate_per_s') AS bulk_shear_rate_per_s,
       json_extract(r.result, '$.shear_stress_pa') AS shear_stress_pa,
       json_extract(r.result, '$.normal_stress_pa') AS measured_normal_stress_pa,
       json_extract(r.result, '$.friction') AS friction,
       json_extract(r.result, '$.inertial_number') AS inertial_number,
       json_extract(r.result, '$.solid_fraction') AS solid_fraction,
       json_extract(r.result, '$.power_density_w_m3') AS power_density_w_m3,
       json_extract(r.result, '$.powder_dissipation_w_m3') AS powder_dissipation_w_m3,
       json_extract(r.result, '$.energy.balance_error') AS energy_balance_error,
       json_extract(r.result, '$.steady_state.steady') AS steady
FROM campaign_tasks ct
JOIN campaigns c ON c.id = ct.campaign_id
JOIN tasks cell ON cell.key = ct.task_key AND cell.kind = 'shear_cell' AND cell.status = 'done'
JOIN results r ON r.task_key = cell.key
JOIN macro_lineage lineage ON lineage.task_key = cell.key
)sql"};
}

void register_shear_cells(engine::Registry& registry) {
  registry.kinds.add(engine::TaskKind{
      .name = "shear_cells", .version = kShearCellsVersion, .run = run_shear_cells, .may_expand = true});
  registry.kinds.add(engine::TaskKind{.name = "shear_cell", .version = kShearCellVersion, .run = run_shear_cell});
  registry.views.push_back(micro_results_view());
}

}  // namespace millflow::tasks
