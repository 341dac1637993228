// A sweep point's sites result (method/sites_result.hpp) and a cell's drive (method/sites.hpp): the
// JSON reads back to the same bytes, a missing or ill-typed field is refused with its JSON pointer
// and owner, and the drive's keys have one spelling.
#include <gtest/gtest.h>

#include <stdexcept>

#include "method/sites_result.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

// A result with a distinct value in most fields, a toe without an impact angle, an empty region
// and two rule sets.
SitesResult result() {
  SitesResult r{.weight_by = WeightBasis::volume,
                .regions = {{.name = "toe",
                             .cells = 3,
                             .volume_m3 = 0.004,
                             .solid_volume_m3 = 0.002,
                             .dissipation_w = 12.0,
                             .dissipation_share = 0.6,
                             .mean_shear_rate = 8.5,
                             .sites = 1},
                            {.name = "bulk"}},
                .empty_regions = {"bulk"},
                .charge_volume_m3 = 0.004,
                .charge_solid_volume_m3 = 0.002,
                .sites_volume_m3 = 0.004,
                .sites_solid_volume_m3 = 0.002,
                .total_dissipation_w = 20.0,
                .toe_angle_deg = 215.0,
                .toe = Toe{.x = -0.3,
                           .y = -0.2,
                           .radius_m = 0.1,
                           .impact_cells = 4,
                           .impact_angle_deg = std::nullopt},
                .sites = {{.site_id = "toe-0",
                           .region = "toe",
                           .x = -0.3,
                           .y = -0.2,
                           .weight_m3 = 0.004,
                           .shear_rate = 8.5,
                           .normal_stress = 2000.0}},
                .fill = 0.3,
                .speed_fraction = 0.75,
                .average_task = "average-key",
                .region_index = region_names()};
  r.rules.flight_solid_fraction = 0.25;
  RegionRules wide = r.rules;
  wide.toe_min_radius_fraction = 0.3;
  Classification classification;
  classification.regions = r.regions;
  r.rule_sets = {rule_set_of("default", r.rules, classification),
                 {.name = "wide",
                  .rules = wide,
                  .regions = {{.name = "toe", .dissipation_w = 15.0, .dissipation_share = 0.75}}}};
  return r;
}

std::string refusal(const json& document) {
  try {
    read_sites_result(document, "sites task s");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

TEST(SitesResult, JsonReadsBackToTheSameBytes) {
  const json written = result();
  EXPECT_EQ(written.at("weight_by"), "volume");
  EXPECT_TRUE(written.at("shoulder_angle_deg").is_null());
  EXPECT_EQ(written.at("toe").at("angle_deg"), 215.0) << "the macro run's toe angle";
  EXPECT_TRUE(written.at("toe").at("impact_angle_deg").is_null());
  EXPECT_EQ(written.at("regions").at(0).at("cells").dump(), "3") << "counts stay integers";
  EXPECT_EQ(
      written.at("rule_sets").at(0).at("regions").at(0).dump(),
      R"({"dissipation_share":0.6,"dissipation_w":12.0,"name":"toe","solid_volume_m3":0.002,"volume_m3":0.004})");
  const auto read = written.get<SitesResult>();
  EXPECT_EQ(read.weight_by, WeightBasis::volume);
  EXPECT_EQ(read.rules.flight_solid_fraction, 0.25);
  EXPECT_EQ(read.rule_sets.at(1).rules.toe_min_radius_fraction, 0.3);
  EXPECT_EQ(read.sites.at(0).shear_rate, 8.5);
  EXPECT_EQ(read.angles().toe_deg, 215.0);
  EXPECT_FALSE(read.angles().shoulder_deg);
  EXPECT_EQ(json(read).dump(), written.dump());
  SitesResult no_toe = result();
  no_toe.toe.reset();
  EXPECT_TRUE(json(no_toe).at("toe").is_null());
  EXPECT_FALSE(json(no_toe).get<SitesResult>().toe);
}

TEST(SitesResult, RefusesAFieldByItsPointer) {
  json missing = result();
  missing["rule_sets"][1]["regions"][0].erase("dissipation_w");
  EXPECT_EQ(refusal(missing).rfind(
                "sites task s: field /rule_sets/1/regions/0/dissipation_w is missing", 0),
            0u)
      << refusal(missing);
  json basis = result();
  basis["weight_by"] = "mass";
  EXPECT_NE(refusal(basis).find("field /weight_by is 'mass', not 'solid_volume' or 'volume'"),
            std::string::npos)
      << refusal(basis);
  json site = result();
  site["sites"][0].erase("normal_stress_pa");
  EXPECT_NE(refusal(site).find("field /sites/0 is not a site"), std::string::npos) << refusal(site);
}

TEST(CellDrive, OneSpellingOfTheKeys) {
  const json drive = CellDrive{.shear_rate = 20.0, .normal_stress = 2000.0};
  EXPECT_EQ(drive.dump(), R"({"normal_stress_pa":2000.0,"shear_rate_per_s":20.0})");
  EXPECT_EQ(
      drive_site_json("cell-0", "cell", {.shear_rate = 20.0, .normal_stress = 2000.0}).dump(),
      R"({"normal_stress_pa":2000.0,"region":"cell","shear_rate_per_s":20.0,"site_id":"cell-0"})");
  const json site =
      Site{.site_id = "toe-0", .region = "toe", .shear_rate = 5.0, .normal_stress = 300.0};
  EXPECT_EQ(site.at("shear_rate_per_s"), 5.0);
  EXPECT_EQ(site.at("normal_stress_pa"), 300.0);
  const auto read = site.get<CellDrive>();
  EXPECT_EQ(read.shear_rate, 5.0);
  EXPECT_EQ(read.normal_stress, 300.0);
}

TEST(CellDrive, SaysWhichValueCannotDriveACell) {
  EXPECT_EQ(unusable_reason({.shear_rate = 1.0, .normal_stress = 1.0}), "");
  EXPECT_EQ(unusable_reason({.shear_rate = 0.0, .normal_stress = -1.0}),
            "shear_rate_per_s = 0 is not positive");
  EXPECT_EQ(unusable_reason({.shear_rate = 3.0, .normal_stress = -1.5}),
            "normal_stress_pa = -1.5 is not positive");
}

}  // namespace
}  // namespace millflow::method
