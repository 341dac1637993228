#include <fmt/format.h>

#include "method/sites.hpp"
#include "method/sites_result.hpp"
#include "tasks/kinds.hpp"
#include "tasks/shear_cell.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

}  // namespace

std::string slot_site_id(const json& slot) {
  return fmt::format("{}-{}", slot.at("region").get<std::string>(), slot.at("index").get<int>());
}

SlotSite find_slot_site(const json& sites_result, const json& slot) {
  const std::string id = slot_site_id(slot);
  if (const std::optional<json> site = method::find_site_json(sites_result, id))
    return {*site, method::unusable_reason(site->get<method::CellDrive>())};
  return {json(), fmt::format("the sites task chose no site {} (region {} has fewer cells or none)",
                              id, slot.at("region").get<std::string>())};
}

// One row per shear cell that ran, with the sweep point it belongs to (view macro_lineage);
// stiffness_factor tells the stiff cells of /shear_cell/stiffness/sensitivity (1: a default cell).
engine::ViewDefinition micro_results_view() {
  return {"micro_results", R"sql(
SELECT c.name AS campaign,
       lineage.fill AS fill,
       lineage.speed_fraction AS speed_fraction,
       cell.key AS task_key,
       json_extract(r.result, '$.site.site_id') AS site_id,
       json_extract(r.result, '$.site.region') AS region,
       json_extract(r.result, '$.site.weight_m3') AS weight_m3,
       json_extract(r.result, '$.powder_load') AS powder_load,
       coalesce(json_extract(r.result, '$.stiffness_factor'), 1.0) AS stiffness_factor,
       json_extract(r.result, '$.site.shear_rate_per_s') AS shear_rate_per_s,
       json_extract(r.result, '$.site.normal_stress_pa') AS normal_stress_pa,
       json_extract(r.result, '$.site.shear_stress_pa') AS macro_shear_stress_pa,
       json_extract(r.result, '$.bulk_shear_rate_per_s') AS bulk_shear_rate_per_s,
       json_extract(r.result, '$.shear_stress_pa') AS shear_stress_pa,
       json_extract(r.result, '$.normal_stress_pa') AS measured_normal_stress_pa,
       json_extract(r.result, '$.friction') AS friction,
       json_extract(r.result, '$.inertial_number') AS inertial_number,
       json_extract(r.result, '$.solid_fraction') AS solid_fraction,
       json_extract(r.result, '$.power_density_w_m3') AS power_density_w_m3,
       json_extract(r.result, '$.powder_dissipation_w_m3') AS powder_dissipation_w_m3,
       json_extract(r.result, '$.dissipation_w_m3."media-media"') AS media_media_dissipation_w_m3,
       json_extract(r.result, '$.energy.balance_error') AS energy_balance_error,
       json_extract(r.result, '$.steady') AS steady,
       json_extract(r.result, '$.stationary_strain') AS stationary_strain,
       json_extract(r.result, '$.converged') AS converged,
       json_extract(r.result, '$.friction_mean_pressure') AS friction_mean_pressure,
       json_extract(r.result, '$.stresses.mean_pressure_pa') AS mean_pressure_pa,
       json_extract(r.result, '$.standard_errors.friction') AS friction_se,
       json_extract(r.result, '$.standard_errors.powder_dissipation_w_m3')
         AS powder_dissipation_se_w_m3,
       json_extract(r.result, '$.overlap_mean_fraction') AS overlap_mean_fraction,
       json_extract(r.result, '$.overlap_p95_fraction') AS overlap_p95_fraction,
       json_extract(r.result, '$.overlap_max_fraction') AS overlap_max_fraction,
       json_extract(r.result, '$.overlap_ok') AS overlap_ok
FROM campaign_tasks ct
JOIN campaigns c ON c.id = ct.campaign_id
JOIN tasks cell ON cell.key = ct.task_key AND cell.kind = 'shear_cell' AND cell.status = 'done'
JOIN results r ON r.task_key = cell.key AND json_extract(r.result, '$.skipped') IS NULL
JOIN macro_lineage lineage ON lineage.task_key = cell.key
)sql"};
}

void register_shear_cells(engine::Registry& registry) {
  registry.kinds.add(
      engine::TaskKind{.name = "shear_cell", .version = kShearCellVersion, .run = run_shear_cell});
  registry.views.push_back(micro_results_view());
}

}  // namespace millflow::tasks
