#pragma once
// Flow regions of a mill's averaged flow and representative sites for the shear cells, and the
// `sites` task kind.
//
// Regions. Every cell inside the mill whose solid fraction nu reaches `charge_solid_fraction`
// belongs to the charge; the first rule that holds names its region:
//   near_liner   the cell centre lies within `liner_layer_diameters` ball diameters of the shell;
//   cataracting  nu < `flight_solid_fraction`: balls in free flight;
//   toe          within `end_radius_fraction` x R of the toe point;
//   shoulder     within `end_radius_fraction` x R of the shoulder point;
//   cascading    shear rate >= `bulk_max_shear_per_omega` x |omega|: the sheared surface layer;
//   bulk         the rest of the dense charge, moving nearly as a rigid body with the shell.
// The toe and the shoulder are where the bed meets the shell: along the circle just inside the
// liner layer (radius R - max(liner layer, one cell)), the arc where nu >= `bed_solid_fraction`
// that holds the lowest point (else the densest point) ends at the toe going against the
// rotation and at the shoulder going with it (omega > 0: counter-clockwise seen from +z). When
// the bed covers the whole circle (centrifuging) or none of it, there is no toe or shoulder.
//
// Sites. Each region's cells, sorted by shear rate (then index), are split into
// min(per_region, cells) contiguous groups of nearly equal cell counts; each group is a site:
//   position        the centre of the group's cell nearest the group's solid-weighted centroid
//                   (so a site always lies in its region);
//   weight_m3       the group's volume (cell area x slice length x cells): the sites' weights sum
//                   to the volume of the charge in the regions that get sites;
//   dissipation_share  the group's dissipated power over the mill's total;
//   shear rate, normal and shear stress (on the shear plane), pressure, granular temperature: means
//   weighted by solid volume
//                   (what the media there experience); solid fraction, collision frequency and
//                   dissipation density: means over the group's volume.
// Empty regions give no sites.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "engine/campaign.hpp"
#include "engine/task.hpp"
#include "tasks/cross_section_grid.hpp"

namespace millflow::tasks {

// Bump whenever the results change (tests/tasks/golden/sites.json guards it).
inline constexpr const char* kSitesVersion = "2";

// The region names, in rule order.
const std::vector<std::string>& region_names();

struct RegionRules {
  double charge_solid_fraction = 0.02;
  double flight_solid_fraction = 0.2;
  double liner_layer_diameters = 1.5;
  double bed_solid_fraction = 0.3;
  double end_radius_fraction = 0.25;
  double bulk_max_shear_per_omega = 2.0;
};

// The per-cell fields the classification reads (SI units; stresses compressive positive).
struct FlowMap {
  CrossSectionGrid grid;  // half_width: the mill radius
  double slice_length = 0.0;
  double media_diameter = 0.0;
  double angular_velocity = 0.0;  // rad/s, counter-clockwise seen from +z positive
  std::vector<double> solid_fraction, shear_rate, normal_stress, shear_stress, pressure,
      granular_temperature, collision_frequency, dissipation;
};

// From the average task's fields.json (tasks/average.hpp). Throws std::invalid_argument naming a
// missing or mis-sized array.
FlowMap flow_map_from_document(const nlohmann::json& fields);

struct Site {
  std::string site_id;  // "<region>-<k>", k from the lowest shear rate up
  std::string region;
  double x = 0.0, y = 0.0;
  double weight_m3 = 0.0;
  double dissipation_share = 0.0;
  double shear_rate = 0.0, normal_stress = 0.0, shear_stress = 0.0, pressure = 0.0,
         solid_fraction = 0.0;
  double granular_temperature = 0.0, collision_frequency = 0.0, dissipation = 0.0;
};

struct RegionSummary {
  std::string name;
  std::size_t cells = 0;
  double volume_m3 = 0.0;
  double solid_volume_m3 = 0.0;
  double dissipation_w = 0.0;
  double dissipation_share = 0.0;
  double mean_shear_rate = 0.0;  // solid-weighted
  std::size_t sites = 0;
};

struct SiteSelection {
  std::vector<int> region_of_cell;     // index into region_names(), -1 outside the charge
  std::vector<RegionSummary> regions;  // every region, in region_names() order
  std::vector<Site> sites;
  double charge_volume_m3 = 0.0;                            // all classified cells
  double total_dissipation_w = 0.0;                         // over the whole cross-section
  std::optional<double> toe_angle_deg, shoulder_angle_deg;  // atan2(y, x) of the points
};

// Classifies the cells and picks up to `per_region` sites in each region of `site_regions`.
// Throws std::invalid_argument for an unknown region name or per_region < 1.
SiteSelection select_sites(const FlowMap& map, const RegionRules& rules,
                           const std::vector<std::string>& site_regions, int per_region);

// Parameters: {"sites": {"per_region": n, "regions": [...]}}. Input 0: the average task (its
// fields.json). Artifact: regions.vti (region index per cell, with the fields it used). Result:
// the regions with volumes and power shares, the empty regions, the toe and shoulder angles, and
// the sites.
engine::TaskOutcome run_sites(engine::TaskContext& context);

// The SQL view `sites`: one row per (campaign, sites task, site) with the macro run's fill and
// speed fraction.
engine::ViewDefinition sites_view();

}  // namespace millflow::tasks
