// Flow regions and sites on a synthetic flow field with known regions: a bed turning as a rigid
// body with the shell under a tilted free surface, a sheared surface layer flowing down it, a
// landing zone at the toe where the stream dissipates most, and balls in flight above the lower
// half of the surface, in a mill turning counter-clockwise.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "method/sites.hpp"

namespace millflow::method {
namespace {

constexpr double kR = 0.1, kD = 0.01, kSurface0 = -0.02, kLayer = 0.015, kFlight = 0.02;
constexpr double kOmega = 4.0, kStreamSpeed = 0.5;
const double kSlope = std::tan(30.0 * std::numbers::pi / 180.0);

// Signed height above the free surface y = kSurface0 + kSlope x, perpendicular to it; `mirror`
// flips x (the same charge in a mill turning clockwise).
double height_above_surface(double x, double y, bool mirror) {
  if (mirror) x = -x;
  return (y - kSurface0 - kSlope * x) / std::hypot(1.0, kSlope);
}

double degrees(double radians) {
  return radians * 180.0 / std::numbers::pi;
}

// Where the free surface crosses the circle just inside the liner layer: {left, right} angles,
// the toe and the shoulder the macro run would see.
std::pair<double, double> surface_meets_shell() {
  const double r = kR - 1.5 * kD, a = 1 + kSlope * kSlope, b = 2 * kSurface0 * kSlope,
               c = kSurface0 * kSurface0 - r * r;
  const double root = std::sqrt(b * b - 4 * a * c);
  const double left = (-b - root) / (2 * a), right = (-b + root) / (2 * a);
  auto angle = [](double x) { return degrees(std::atan2(kSurface0 + kSlope * x, x)); };
  return {angle(left), angle(right)};
}

method::ChargeAngles macro_angles() {
  const auto [left, right] = surface_meets_shell();
  return {.toe_deg = left, .shoulder_deg = right};
}

// The toe point of macro_angles() on the circle just inside the liner layer.
std::pair<double, double> toe_point() {
  const double a = *macro_angles().toe_deg * std::numbers::pi / 180.0, r = kR - 1.5 * kD;
  return {r * std::cos(a), r * std::sin(a)};
}

method::FlowMap synthetic_map(double landing_radius = 0.02, bool mirror = false) {
  method::FlowMap map;
  map.grid = method::CrossSectionGrid{.nx = 40, .ny = 40, .half_width = kR};
  map.slice_length = 0.04;
  map.media_diameter = kD;
  map.angular_velocity = mirror ? -kOmega : kOmega;
  const std::size_t n = map.grid.size();
  for (auto* field : {&map.solid_fraction, &map.shear_rate, &map.normal_stress, &map.shear_stress,
                      &map.pressure, &map.granular_temperature, &map.collision_frequency,
                      &map.dissipation, &map.velocity_x, &map.velocity_y}) {
    field->assign(n, 0.0);
  }
  const auto [toe_x, toe_y] = toe_point();
  const double downhill = std::atan(kSlope) + std::numbers::pi;  // along the surface, to the toe
  for (std::size_t c = 0; c < n; ++c) {
    if (!map.grid.inside_mill(c)) continue;
    const double x = map.grid.x_of(c), y = map.grid.y_of(c);
    const double h = height_above_surface(x, y, mirror);
    const double unmirrored_x = mirror ? -x : x;
    const bool landing = std::hypot(unmirrored_x - toe_x, y - toe_y) <= landing_radius;
    if (h < 0.0) {
      const bool layer = h > -kLayer;
      map.solid_fraction[c] = 0.6;
      map.shear_rate[c] = layer ? 20.0 + 100.0 * h : 0.5;  // rises towards the surface
      map.dissipation[c] = landing ? 1000.0 : layer ? 100.0 : 10.0;
      map.pressure[c] = map.normal_stress[c] = -1e4 * h;
      map.shear_stress[c] = 0.4 * map.normal_stress[c];
      if (layer) {  // the stream flows down the surface
        map.velocity_x[c] = kStreamSpeed * std::cos(downhill) * (mirror ? -1.0 : 1.0);
        map.velocity_y[c] = kStreamSpeed * std::sin(downhill);
      } else {  // the bed turns with the shell
        map.velocity_x[c] = -map.angular_velocity * y;
        map.velocity_y[c] = map.angular_velocity * x;
      }
    } else if (h < kFlight && unmirrored_x < 0.0) {
      map.solid_fraction[c] = 0.1;
      map.shear_rate[c] = 5.0;
      map.dissipation[c] = landing ? 1000.0 : 1.0;
    }
  }
  return map;
}

int region_at(const method::FlowMap& map, const method::Classification& s, double x, double y) {
  const int i = static_cast<int>((x + kR) / map.grid.dx()),
            j = static_cast<int>((y + kR) / map.grid.dy());
  return s.region_of_cell[map.grid.index(i, j)];
}

int region(const std::string& name) {
  const auto& names = method::region_names();
  return static_cast<int>(std::find(names.begin(), names.end(), name) - names.begin());
}

// a - b in degrees, in [-180, 180).
double angle_between(double a, double b) {
  return std::remainder(a - b, 360.0);
}

TEST(Sites, RegionsFollowTheRules) {
  const method::FlowMap map = synthetic_map();
  const method::SiteSelection s =
      method::select_sites(map, method::RegionRules{}, macro_angles(), method::region_names(), 3);
  const auto [toe_x, toe_y] = toe_point();
  ASSERT_TRUE(s.toe);
  EXPECT_EQ(region_at(map, s, 0.001, -0.06), region("bulk"));  // turns with the shell
  EXPECT_EQ(region_at(map, s, 0.001, kSurface0 - 0.004), region("cascading"));
  EXPECT_EQ(region_at(map, s, 0.001, -0.097), region("near_liner"));
  EXPECT_EQ(region_at(map, s, -0.03, kSurface0 - 0.03 * kSlope + 0.012), region("cataracting"));
  // The toe holds the landing zone, its shell side (before near_liner) and its flight side (before
  // cataracting) included.
  EXPECT_EQ(region_at(map, s, toe_x, toe_y), region("toe"));
  EXPECT_EQ(region_at(map, s, toe_x * 1.1, toe_y * 1.1), region("toe"));
  EXPECT_EQ(region_at(map, s, toe_x + 0.01, toe_y + 0.012), region("toe"));
  // Its impact zone is the landing zone, around the macro run's toe.
  ASSERT_TRUE(s.toe->impact_angle_deg);
  EXPECT_NEAR(angle_between(*s.toe->impact_angle_deg, *macro_angles().toe_deg), 0.0, 5.0);
  const double shoulder = (*macro_angles().shoulder_deg - 5) * std::numbers::pi / 180;
  EXPECT_EQ(region_at(map, s, 0.08 * std::cos(shoulder), 0.08 * std::sin(shoulder)),
            region("shoulder"));
  EXPECT_EQ(region_at(map, s, 0.0, 0.05), -1);  // empty space above the charge
}

TEST(Sites, TheToeGrowsToHoldALargerImpactZone) {
  for (const double landing : {0.01, 0.03, 0.04}) {
    const method::FlowMap map = synthetic_map(landing);
    const method::Classification s =
        method::classify_regions(map, method::RegionRules{}, macro_angles());
    ASSERT_TRUE(s.toe);
    // At least the smallest toe, and no larger than the landing zone needs (half a diagonal).
    EXPECT_NEAR(s.toe->radius_m,
                std::max(0.2 * kR, landing + 0.5 * std::hypot(map.grid.dx(), map.grid.dy())),
                map.grid.dx() * 0.75)
        << landing;
    const auto [toe_x, toe_y] = toe_point();
    for (std::size_t c = 0; c < map.grid.size(); ++c) {
      if (map.dissipation[c] == 1000.0) {
        EXPECT_EQ(s.region_of_cell[c], region("toe")) << landing;
        EXPECT_LE(std::hypot(map.grid.x_of(c) - toe_x, map.grid.y_of(c) - toe_y), landing + 1e-12);
      }
    }
  }
}

TEST(Sites, WeightsSumToTheChargeVolumeAndSolidVolume) {
  const method::FlowMap map = synthetic_map();
  const method::SiteSelection s =
      method::select_sites(map, method::RegionRules{}, macro_angles(), method::region_names(), 3);
  const double cell_volume = map.grid.cell_area() * map.slice_length;
  double charge = 0.0, solid = 0.0;
  for (std::size_t c = 0; c < map.grid.size(); ++c) {
    if (map.solid_fraction[c] > 0.0) charge += cell_volume;
    solid += map.solid_fraction[c] * cell_volume;
  }
  double weights = 0.0, solid_weights = 0.0, shares = 0.0;
  for (const method::Site& site : s.sites) {
    weights += site.weight_m3;
    solid_weights += site.solid_volume_m3;
    shares += site.dissipation_share;
    EXPECT_EQ(region_at(map, s, site.x, site.y), region(site.region)) << site.site_id;
    // Both stresses are means with the same (solid) weights.
    EXPECT_NEAR(site.shear_stress, 0.4 * site.normal_stress, 1e-9 * site.normal_stress)
        << site.site_id;
  }
  EXPECT_EQ(s.sites.size(), 6u * 3u);
  EXPECT_NEAR(s.charge_volume_m3, charge, 1e-12);
  EXPECT_NEAR(weights, charge, 1e-12);
  EXPECT_NEAR(s.charge_solid_volume_m3, solid, 1e-12);
  EXPECT_NEAR(solid_weights, solid, 1e-12);
  EXPECT_NEAR(shares, 1.0, 1e-12);  // every watt is dissipated in the charge here
  // Sites of a region are its shear-rate quantiles, lowest first.
  for (std::size_t k = 1; k < s.sites.size(); ++k) {
    if (s.sites[k].region == s.sites[k - 1].region) {
      EXPECT_GE(s.sites[k].shear_rate, s.sites[k - 1].shear_rate);
    }
  }
  // The cascading layer shears and dissipates more than the bulk.
  const auto& cascading = s.regions[static_cast<std::size_t>(region("cascading"))];
  const auto& bulk = s.regions[static_cast<std::size_t>(region("bulk"))];
  EXPECT_GT(cascading.mean_shear_rate, 10 * bulk.mean_shear_rate);
  EXPECT_GT(cascading.dissipation_w / cascading.volume_m3, 5 * bulk.dissipation_w / bulk.volume_m3);
}

TEST(Sites, SitesSplitTheirRegionIntoNearlyEqualWeights) {
  const method::FlowMap map = synthetic_map();
  const double cell_volume = map.grid.cell_area() * map.slice_length;
  // The toe mixes bed (0.6) and flight (0.1) cells: equal solid volumes need unequal counts.
  const method::SiteSelection by_solid = method::select_sites(
      map, method::RegionRules{}, macro_angles(), {"toe"}, 3, method::WeightBasis::solid_volume);
  const method::SiteSelection by_volume = method::select_sites(
      map, method::RegionRules{}, macro_angles(), {"toe"}, 3, method::WeightBasis::volume);
  ASSERT_EQ(by_solid.sites.size(), 3u);
  ASSERT_EQ(by_volume.sites.size(), 3u);
  const double toe_solid =
      by_solid.regions[static_cast<std::size_t>(region("toe"))].solid_volume_m3;
  for (const method::Site& site : by_solid.sites)
    EXPECT_NEAR(site.solid_volume_m3, toe_solid / 3, 0.6 * cell_volume) << site.site_id;
  for (const method::Site& site : by_volume.sites) {
    EXPECT_NEAR(site.weight_m3 / cell_volume,
                by_volume.regions[static_cast<std::size_t>(region("toe"))].cells / 3.0, 1.0)
        << site.site_id;
  }
}

TEST(Sites, OnlyRequestedRegionsGetSites) {
  const method::FlowMap map = synthetic_map();
  const method::SiteSelection s =
      method::select_sites(map, method::RegionRules{}, macro_angles(), {"shoulder", "toe"}, 2);
  ASSERT_EQ(s.sites.size(), 4u);
  const double toe_volume = s.regions[static_cast<std::size_t>(region("toe"))].volume_m3;
  EXPECT_NEAR(s.sites[2].weight_m3 + s.sites[3].weight_m3, toe_volume, 1e-15);
  EXPECT_EQ(s.sites[0].site_id, "shoulder-0");
  EXPECT_EQ(s.sites[2].site_id, "toe-0");
}

TEST(Sites, ACentrifugingChargeHasNoToeOrShoulder) {
  const method::FlowMap map = synthetic_map();
  const method::SiteSelection s =
      method::select_sites(map, method::RegionRules{}, {}, method::region_names(), 1);
  EXPECT_FALSE(s.toe);
  EXPECT_EQ(s.regions[static_cast<std::size_t>(region("toe"))].cells, 0u);
  EXPECT_EQ(s.regions[static_cast<std::size_t>(region("shoulder"))].cells, 0u);
}

TEST(Sites, AClockwiseMillMovesItsBulkWithTheShellToo) {
  const method::FlowMap map = synthetic_map(0.02, true);
  const method::Classification s = method::classify_regions(map, method::RegionRules{}, {});
  EXPECT_EQ(region_at(map, s, 0.001, -0.06), region("bulk"));
  EXPECT_EQ(region_at(map, s, -0.001, kSurface0 - 0.004), region("cascading"));
}

TEST(Sites, WiderRulesGiveTheEnMasseRegionMoreOfTheCharge) {
  const method::FlowMap map = synthetic_map();
  method::RegionRules strict, loose;
  strict.en_masse_max_slip = 0.3;
  loose.en_masse_max_slip = 0.7;
  // The stream's slip is far above both, the bed's zero: the regions do not move with the slip...
  const auto bulk = static_cast<std::size_t>(region("bulk"));
  EXPECT_EQ(method::classify_regions(map, strict, macro_angles()).regions[bulk].cells,
            method::classify_regions(map, loose, macro_angles()).regions[bulk].cells);
  // ... until the bed itself slips: at 0.5 |omega r| behind the shell it is bulk for the loose
  // rules only.
  method::FlowMap slipping = map;
  for (std::size_t c = 0; c < map.grid.size(); ++c) {
    slipping.velocity_x[c] *= 0.5;
    slipping.velocity_y[c] *= 0.5;
  }
  EXPECT_EQ(
      region_at(slipping, method::classify_regions(slipping, strict, macro_angles()), 0.001, -0.06),
      region("cascading"));
  EXPECT_EQ(
      region_at(slipping, method::classify_regions(slipping, loose, macro_angles()), 0.001, -0.06),
      region("bulk"));
}

TEST(Sites, RefusesUnknownRegionsAndZeroSites) {
  const method::FlowMap map = synthetic_map();
  EXPECT_THROW(method::select_sites(map, method::RegionRules{}, macro_angles(), {"belly"}, 2),
               std::invalid_argument);
  EXPECT_THROW(method::select_sites(map, method::RegionRules{}, macro_angles(), {"toe"}, 0),
               std::invalid_argument);
}

}  // namespace
}  // namespace millflow::method
