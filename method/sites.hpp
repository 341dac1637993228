#pragma once
// Flow regions of a mill's averaged flow and representative sites for the shear cells
// (docs/regions.md gives the rules' reasons and a map; the `sites` task kind is tasks/sites.hpp).
//
// Regions. Every cell inside the mill whose solid fraction nu reaches `charge_solid_fraction`
// belongs to the charge; the first rule that holds, in this order, names its region:
//   toe          within the toe radius of the toe point (below);
//   near_liner   the cell centre lies within `liner_layer_diameters` ball diameters of the shell;
//   cataracting  nu < `flight_solid_fraction`: balls in free flight;
//   shoulder     within `shoulder_radius_fraction` x R of the shoulder point;
//   bulk         en masse: the charge moving with the shell, |V - omega x r| <= `en_masse_max_slip`
//                x |omega| |r| (V the mean velocity, r the position from the axis);
//   cascading    the rest of the dense charge: the sheared free-surface layer, which does not
//                move with the shell.
// bulk and cascading are complementary, so every cell of the charge gets a region.
// The toe and shoulder points lie on the circle just inside the liner layer (radius R - max(liner
// layer, one cell)) at the macro run's toe and shoulder angles (from where the balls touch the
// shell, method/macro_measure.hpp). The toe holds the impact zone, where the cascading stream
// lands on the charge: the charge cells within `toe_search_radius_fraction` x R of the toe point
// whose dissipation density reaches `impact_dissipation_fraction` x the highest there. Its
// radius is the distance from the toe point to the farthest of them plus half a cell diagonal,
// at least `toe_min_radius_fraction` x R and at most the search radius. Without the angles
// (a centrifuging charge) there is no toe or shoulder.
//
// Sites. Each region's cells, sorted by shear rate (then index), are split into
// min(per_region, cells) contiguous groups of nearly equal weight (`weight_by`: solid volume, the
// group of a cell being the one its solid midpoint falls in, empty groups dropped; or cell count);
// each group is a site:
//   position        the centre of the group's cell nearest the group's solid-weighted centroid
//                   (so a site always lies in its region);
//   weight_m3       the group's volume (cell area x slice length x cells), and
//   solid_volume_m3 the balls' volume in it (sum of nu x cell volume): the sites' weights sum to
//                   the volume and the solid volume of the charge in the regions that get sites;
//                   `weight_by` says which of the two the upscaling multiplies (tasks/upscale.hpp);
//   dissipation_share  the group's dissipated power over the mill's total;
//   shear rate, normal and shear stress (on the shear plane), pressure, granular temperature: means
//                   weighted by solid volume (what the media there experience); solid fraction,
//                   collision frequency and dissipation density: means over the group's volume.
// Empty regions give no sites.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "method/cross_section_grid.hpp"

namespace millflow::method {

// The region names, in rule order.
const std::vector<std::string>& region_names();

// The defaults are the campaign's (/sites/rules, tasks/campaign.cpp); docs/regions.md says why.
struct RegionRules {
  double charge_solid_fraction = 0.02;
  double flight_solid_fraction = 0.2;
  double liner_layer_diameters = 1.5;
  double toe_search_radius_fraction = 0.5;
  double impact_dissipation_fraction = 0.5;
  double toe_min_radius_fraction = 0.2;
  double shoulder_radius_fraction = 0.2;
  double en_masse_max_slip = 0.5;
};

// The rules as /sites/rules and the sites result write them, a key per field of the same name.
void to_json(nlohmann::json& out, const RegionRules& rules);
void from_json(const nlohmann::json& in, RegionRules& rules);

// Where the macro run saw the charge touch the shell (degrees, atan2(y, x)); none when
// centrifuging.
struct ChargeAngles {
  std::optional<double> toe_deg, shoulder_deg;
};

enum class WeightBasis { volume, solid_volume };

// The per-cell fields the classification reads (SI units; stresses compressive positive).
struct FlowMap {
  CrossSectionGrid grid;  // half_width: the mill radius
  double slice_length = 0.0;
  double media_diameter = 0.0;
  double angular_velocity = 0.0;  // rad/s, counter-clockwise seen from +z positive
  std::vector<double> solid_fraction, shear_rate, normal_stress, shear_stress, pressure,
      granular_temperature, collision_frequency, dissipation;
  std::vector<double> velocity_x, velocity_y;  // m/s, the mean velocity
};

// What drives a shear cell (dem::ShearCellSetup): the shear rate (1/s) and the normal stress (Pa)
// at a site. A site's JSON holds them, and so does every shear cell's result (its `site`);
// to_json and from_json are the one spelling of their keys, shear_rate_per_s and
// normal_stress_pa.
struct CellDrive {
  double shear_rate = 0.0, normal_stress = 0.0;
};

void to_json(nlohmann::json& out, const CellDrive& drive);
void from_json(const nlohmann::json& in, CellDrive& drive);

// Why a drive cannot drive a shear cell ("shear_rate_per_s = 0 is not positive": the first of
// its values that is not finite and positive, by its key), empty when it can.
std::string unusable_reason(const CellDrive& drive);

struct Site {
  std::string site_id;  // "<region>-<k>", k from the lowest shear rate up
  std::string region;
  double x = 0.0, y = 0.0;
  double weight_m3 = 0.0;
  double solid_volume_m3 = 0.0;
  double dissipation_share = 0.0;
  double shear_rate = 0.0, normal_stress = 0.0, shear_stress = 0.0, pressure = 0.0,
         solid_fraction = 0.0;
  double granular_temperature = 0.0, collision_frequency = 0.0, dissipation = 0.0;
};

// A site as the sites task's result lists it (the one spelling of its keys): site_id, region,
// position_m [x, y], weight_m3, solid_volume_m3, dissipation_share, the CellDrive keys
// (shear_rate_per_s, normal_stress_pa), shear_stress_pa, pressure_pa, solid_fraction,
// granular_temperature_m2_s2, collision_frequency_per_m3_s, dissipation_w_m3.
void to_json(nlohmann::json& out, const Site& site);
void from_json(const nlohmann::json& in, Site& site);

// A site's site_id from its JSON (as a sites result or a cell's result holds it).
std::string site_id_of(const nlohmann::json& site);

// A site of a `millflow cell` spec: its site_id, region and drive only.
nlohmann::json drive_site_json(const std::string& site_id, const std::string& region,
                               const CellDrive& drive);

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

// The toe as the rules found it.
struct Toe {
  double x = 0.0, y = 0.0, radius_m = 0.0;  // the disc
  std::size_t impact_cells = 0;             // the impact zone it holds
  std::optional<double> impact_angle_deg;   // atan2 of the impact zone's dissipation centroid
};

// The regions of one rule set.
struct Classification {
  std::vector<int> region_of_cell;     // index into region_names(), -1 outside the charge
  std::vector<RegionSummary> regions;  // every region, in region_names() order (no sites)
  std::optional<Toe> toe;
  double charge_volume_m3 = 0.0, charge_solid_volume_m3 = 0.0;  // all classified cells
  double total_dissipation_w = 0.0;                             // over the whole cross-section
};

Classification classify_regions(const FlowMap& map, const RegionRules& rules,
                                const ChargeAngles& angles);

struct SiteSelection : Classification {
  std::vector<Site> sites;
  WeightBasis weight_by = WeightBasis::solid_volume;
  std::optional<double> toe_angle_deg, shoulder_angle_deg;  // the macro run's
};

// Classifies the cells and picks up to `per_region` sites in each region of `site_regions`.
// Throws std::invalid_argument for an unknown region name or per_region < 1.
SiteSelection select_sites(const FlowMap& map, const RegionRules& rules, const ChargeAngles& angles,
                           const std::vector<std::string>& site_regions, int per_region,
                           WeightBasis weight_by = WeightBasis::solid_volume);

}  // namespace millflow::method
