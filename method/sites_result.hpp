#pragma once
// A sweep point's flow regions and sites (docs/method.md, step 2): what the `sites` task kind
// stores (tasks/sites.cpp fills it from method::select_sites) and the upscale and report tasks
// read. to_json and read_sites_result below are the one spelling of its keys (the sites SQL view
// in tasks/sites.cpp names the sites' keys too).
//
// Result JSON (versioned by the kind's kSitesVersion, tasks/kinds.hpp), SI units unless the key
// says otherwise, null where a figure is undefined:
//   rules (method::RegionRules), weight_by ("solid_volume" or "volume"),
//   regions [{name, cells, volume_m3, solid_volume_m3, dissipation_w, dissipation_share,
//   mean_shear_rate_per_s, sites}] (every region, in region_names() order), empty_regions [name],
//   charge_volume_m3, charge_solid_volume_m3, sites_volume_m3, sites_solid_volume_m3 (the sums
//   of the sites' weights), total_dissipation_w, toe_angle_deg, shoulder_angle_deg (the macro
//   run's), toe {angle_deg (= toe_angle_deg), position_m [x, y], radius_m, impact_cells,
//   impact_angle_deg} or null, sites [method::Site], fill, speed_fraction, average_task,
//   region_index (region_names(), the index regions.vti's `region` array counts in),
//   rule_sets [{name, rules, regions [{name, volume_m3, solid_volume_m3, dissipation_w,
//   dissipation_share}]}] (the default rules first, then each alternative).
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "method/sites.hpp"

namespace millflow::method {

// One region's dissipation under one rule set.
struct RuleSetRegion {
  std::string name{};
  double volume_m3 = 0.0, solid_volume_m3 = 0.0, dissipation_w = 0.0, dissipation_share = 0.0;
};

// The regions one rule set draws (the default rules or an alternative, docs/regions.md).
struct RuleSet {
  std::string name{};
  RegionRules rules{};
  std::vector<RuleSetRegion> regions{};  // every region, in region_names() order
};

RuleSet rule_set_of(const std::string& name, const RegionRules& rules,
                    const Classification& classification);

struct SitesResult {
  RegionRules rules{};
  WeightBasis weight_by = WeightBasis::solid_volume;
  std::vector<RegionSummary> regions{};  // every region, in region_names() order
  std::vector<std::string> empty_regions{};
  double charge_volume_m3 = 0.0, charge_solid_volume_m3 = 0.0;
  double sites_volume_m3 = 0.0, sites_solid_volume_m3 = 0.0;
  double total_dissipation_w = 0.0;
  std::optional<double> toe_angle_deg{}, shoulder_angle_deg{};
  std::optional<Toe> toe{};
  std::vector<Site> sites{};
  double fill = 0.0, speed_fraction = 0.0;
  std::string average_task{};
  std::vector<std::string> region_index{};
  std::vector<RuleSet> rule_sets{};

  // The macro run's toe and shoulder angles.
  ChargeAngles angles() const {
    return {.toe_deg = toe_angle_deg, .shoulder_deg = shoulder_angle_deg};
  }
};

// The selection's regions, toe and sites under `rules`, with the empty regions, the sums of the
// sites' weights and region_index filled in; the caller adds fill, speed_fraction, average_task
// and rule_sets.
SitesResult sites_result_of(const SiteSelection& selection, const RegionRules& rules);

void to_json(nlohmann::json& out, const SitesResult& result);

// The JSON of site `site_id` in a sites result's JSON, as stored (a shear cell keeps it in its
// result as it is), none when there is none. Reads only the sites' site_id, so that the one-site
// result of a `millflow cell` spec (sites_json_of) is read the same way.
std::optional<nlohmann::json> find_site_json(const nlohmann::json& sites_result,
                                             const std::string& site_id);
// A sites result's JSON holding these sites only.
nlohmann::json sites_json_of(const std::vector<nlohmann::json>& sites);

// Reads and checks a result: a missing or ill-typed field throws std::invalid_argument
// "<owner>: field <JSON pointer> <problem>; <fix>" (util/json_fields.hpp), e.g. owner "sites
// task <key>".
SitesResult read_sites_result(const nlohmann::json& in, const std::string& owner,
                              const std::string& fix = "re-run that task with a matching version");
void from_json(const nlohmann::json& in, SitesResult& result);  // owner "sites result"

}  // namespace millflow::method
