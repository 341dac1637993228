// Flow regions and sites on a synthetic field map: a bed under a tilted free surface with a
// sheared surface layer, balls in flight above it, in a mill turning counter-clockwise.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tasks/sites.hpp"

namespace millflow::tasks {
namespace {

constexpr double kR = 0.1, kD = 0.01, kSurface0 = -0.02, kLayer = 0.015, kFlight = 0.02;
const double kSlope = std::tan(30.0 * std::numbers::pi / 180.0);

// Signed height above the free surface y = kSurface0 + kSlope x, perpendicular to it; `mirror`
// flips x (the same charge in a mill turning clockwise).
double height_above_surface(double x, double y, bool mirror) {
  if (mirror) x = -x;
  return (y - kSurface0 - kSlope * x) / std::hypot(1.0, kSlope);
}

FlowMap synthetic_map(bool with_flight = true, bool mirror = false) {
  FlowMap map;
  map.grid = CrossSectionGrid{.nx = 40, .ny = 40, .half_width = kR};
  map.slice_length = 0.04;
  map.media_diameter = kD;
  map.angular_velocity = mirror ? -4.0 : 4.0;
  const std::size_t n = map.grid.size();
  for (auto* field :
       {&map.solid_fraction, &map.shear_rate, &map.normal_stress, &map.shear_stress, &map.pressure,
        &map.granular_temperature, &map.collision_frequency, &map.dissipation}) {
    field->assign(n, 0.0);
  }
  for (std::size_t c = 0; c < n; ++c) {
    if (!map.grid.inside_mill(c)) continue;
    const double h = height_above_surface(map.grid.x_of(c), map.grid.y_of(c), mirror);
    const double x = mirror ? -map.grid.x_of(c) : map.grid.x_of(c);
    if (h < 0.0) {
      const bool layer = h > -kLayer;
      map.solid_fraction[c] = 0.6;
      map.shear_rate[c] = layer ? 20.0 + 100.0 * h : 0.5;  // rises towards the surface
      map.dissipation[c] = layer ? 100.0 : 10.0;
      map.pressure[c] = map.normal_stress[c] = -1e4 * h;
      map.shear_stress[c] = 0.4 * map.normal_stress[c];
    } else if (with_flight && h < kFlight && x < 0.0) {
      map.solid_fraction[c] = 0.1;
      map.shear_rate[c] = 5.0;
      map.dissipation[c] = 1.0;
    }
  }
  return map;
}

int region_at(const FlowMap& map, const SiteSelection& s, double x, double y) {
  const int i = static_cast<int>((x + kR) / map.grid.dx()),
            j = static_cast<int>((y + kR) / map.grid.dy());
  return s.region_of_cell[map.grid.index(i, j)];
}

int region(const std::string& name) {
  const auto& names = region_names();
  return static_cast<int>(std::find(names.begin(), names.end(), name) - names.begin());
}

// Where the free surface crosses the circle just inside the liner layer: {left, right} angles.
std::pair<double, double> surface_meets_shell() {
  const double r = kR - 1.5 * kD, a = 1 + kSlope * kSlope, b = 2 * kSurface0 * kSlope,
               c = kSurface0 * kSurface0 - r * r;
  const double root = std::sqrt(b * b - 4 * a * c);
  const double left = (-b - root) / (2 * a), right = (-b + root) / (2 * a);
  auto angle = [](double x) {
    return std::atan2(kSurface0 + kSlope * x, x) * 180.0 / std::numbers::pi;
  };
  return {angle(left), angle(right)};
}

// a - b in degrees, in [-180, 180).
double angle_between(double a, double b) {
  return std::remainder(a - b, 360.0);
}

TEST(Sites, RegionsFollowTheRules) {
  const FlowMap map = synthetic_map();
  const SiteSelection s = select_sites(map, RegionRules{}, region_names(), 3);
  const auto [left, right] = surface_meets_shell();
  ASSERT_TRUE(s.toe_angle_deg && s.shoulder_angle_deg);
  EXPECT_NEAR(*s.toe_angle_deg, left, 5.0);        // the bed's lower end, against the rotation
  EXPECT_NEAR(*s.shoulder_angle_deg, right, 5.0);  // carried up the rising (+x) side

  EXPECT_EQ(region_at(map, s, 0.001, -0.06), region("bulk"));
  EXPECT_EQ(region_at(map, s, 0.001, kSurface0 - 0.004), region("cascading"));
  EXPECT_EQ(region_at(map, s, 0.001, -0.097), region("near_liner"));
  EXPECT_EQ(region_at(map, s, -0.03, kSurface0 - 0.03 * kSlope + 0.012), region("cataracting"));
  // 10 degrees into the bed from its ends.
  const double toe = (*s.toe_angle_deg + 10) * std::numbers::pi / 180;
  const double shoulder = (*s.shoulder_angle_deg - 10) * std::numbers::pi / 180;
  EXPECT_EQ(region_at(map, s, 0.075 * std::cos(toe), 0.075 * std::sin(toe)), region("toe"));
  EXPECT_EQ(region_at(map, s, 0.075 * std::cos(shoulder), 0.075 * std::sin(shoulder)),
            region("shoulder"));
  EXPECT_EQ(region_at(map, s, 0.0, 0.05), -1);  // empty space above the charge
}

TEST(Sites, WeightsSumToTheChargeAndSitesLieInTheirRegions) {
  const FlowMap map = synthetic_map();
  const SiteSelection s = select_sites(map, RegionRules{}, region_names(), 3);
  double charge = 0.0;
  for (std::size_t c = 0; c < map.grid.size(); ++c) {
    if (map.solid_fraction[c] > 0.0) charge += map.grid.cell_area() * map.slice_length;
  }
  double weights = 0.0, shares = 0.0;
  for (const Site& site : s.sites) {
    weights += site.weight_m3;
    shares += site.dissipation_share;
    EXPECT_EQ(region_at(map, s, site.x, site.y), region(site.region)) << site.site_id;
    // Both stresses are means with the same (solid) weights.
    EXPECT_NEAR(site.shear_stress, 0.4 * site.normal_stress, 1e-9 * site.normal_stress)
        << site.site_id;
  }
  EXPECT_EQ(s.sites.size(), 6u * 3u);
  EXPECT_NEAR(s.charge_volume_m3, charge, 1e-12);
  EXPECT_NEAR(weights, charge, 1e-12);
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

TEST(Sites, AnEmptyRegionGivesNoSitesAndOnlyRequestedRegionsGetSites) {
  const FlowMap map = synthetic_map(false);
  const SiteSelection s = select_sites(map, RegionRules{}, {"cataracting", "toe"}, 2);
  EXPECT_EQ(s.regions[static_cast<std::size_t>(region("cataracting"))].cells, 0u);
  ASSERT_EQ(s.sites.size(), 2u);
  double toe_volume = s.regions[static_cast<std::size_t>(region("toe"))].volume_m3;
  EXPECT_NEAR(s.sites[0].weight_m3 + s.sites[1].weight_m3, toe_volume, 1e-15);
  EXPECT_EQ(s.sites[0].site_id, "toe-0");
}

TEST(Sites, AClockwiseMillHasItsToeOnTheOtherSide) {
  const SiteSelection s = select_sites(synthetic_map(true, true), RegionRules{}, region_names(), 1);
  const auto [left, right] = surface_meets_shell();
  ASSERT_TRUE(s.toe_angle_deg && s.shoulder_angle_deg);
  // Mirroring x maps the angle a to 180 - a.
  EXPECT_NEAR(angle_between(*s.toe_angle_deg, 180.0 - left), 0.0, 5.0);
  EXPECT_NEAR(angle_between(*s.shoulder_angle_deg, 180.0 - right), 0.0, 5.0);
}

TEST(Sites, RefusesUnknownRegionsAndZeroSites) {
  const FlowMap map = synthetic_map();
  EXPECT_THROW(select_sites(map, RegionRules{}, {"belly"}, 2), std::invalid_argument);
  EXPECT_THROW(select_sites(map, RegionRules{}, {"toe"}, 0), std::invalid_argument);
}

}  // namespace
}  // namespace millflow::tasks
