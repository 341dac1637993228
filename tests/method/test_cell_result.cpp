// A shear cell's result (method/cell_result.hpp): what it takes from the cell's measurements, its
// JSON read back to the same bytes, and the rules for reading older cells.
#include <gtest/gtest.h>

#include "method/cell_result.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

constexpr auto kMediaPowder = static_cast<std::size_t>(dem::ContactType::MediaPowder);
constexpr auto kPowderPowder = static_cast<std::size_t>(dem::ContactType::PowderPowder);
constexpr auto kWallMedia = static_cast<std::size_t>(dem::ContactType::WallMedia);
constexpr auto kWallPowder = static_cast<std::size_t>(dem::ContactType::WallPowder);

// Measurements with a distinct value in every field the result keeps.
dem::ShearCellMeasurements measurements() {
  dem::ShearCellMeasurements m;
  m.strain = 2.5;
  m.duration = 0.125;
  m.steps = 4096;
  m.shear_stress = 300.0;
  m.normal_stress = 1000.0;
  m.friction = 0.3;
  m.stress_tensor = {1010.0, 1000.0, 990.0, -300.0, 1.5, -2.5};
  m.media_solid_fraction = 0.55;
  m.powder_solid_fraction = 0.07;
  m.power_density = 6000.0;
  m.dissipation_density = {4000.0, 900.0, 300.0, 500.0, 200.0};
  m.dissipation_density_total = 5900.0;
  m.media_collisions.count = 480.0;
  m.media_collisions.rate_per_volume = 3.2e7;
  m.media_collisions.dissipated_energy.add(1e-6);
  m.powder_collisions.dissipated_energy.add(1e-9);
  m.steady = true;
  m.stationary = true;
  m.stationary_strain = 1.25;
  m.converged = false;
  m.overlaps[kWallMedia] = {
      .contacts = 50.0, .mean_fraction = 0.004, .p95_fraction = 0.012, .max_fraction = 0.02};
  m.overlaps[kPowderPowder] = {
      .contacts = 80.0, .mean_fraction = 0.006, .p95_fraction = 0.018, .max_fraction = 0.03};
  m.friction_error.standard_error = 0.01;
  m.dissipation_standard_error = {40.0, 9.0, 3.0, 5.0, 2.0};
  m.blocks = 50;
  m.batch_blocks = 5;
  return m;
}

TEST(CellResult, TakesTheMeasurementsWithThePowderDissipationAndTheWorstOverlap) {
  const CellResult r = cell_result(measurements());
  EXPECT_DOUBLE_EQ(r.powder_dissipation_w_m3, 900.0 + 300.0 + 200.0)
      << "media-powder, powder-powder and wall-powder";
  EXPECT_FALSE(r.overlaps[kMediaPowder]) << "a type without contacts has no overlap";
  EXPECT_DOUBLE_EQ(r.worst_overlap().p95_fraction, 0.018);
  EXPECT_EQ(r.spectrum_bin_edges_j.size(), r.media_spectrum.counts.size() + 1);
  ASSERT_TRUE(r.stationary_strain);
  EXPECT_DOUBLE_EQ(*r.stationary_strain, 1.25);
  ASSERT_TRUE(r.standard_errors);
  EXPECT_EQ(r.standard_errors->batch_blocks, 5u);
}

TEST(CellResult, JsonReadsBackToTheSameBytes) {
  CellResult r = cell_result(measurements());
  r.site = {{"site_id", "toe-0"}, {"shear_rate_per_s", 20.0}};
  r.slot = {{"region", "toe"}, {"index", 0}};
  r.powder_load = 0;  // an integer load stays one
  r.media_count = 60;
  r.stiffness = {{.pair = "media-media",
                  .given = 1e5,
                  .static_bound = 2e5,
                  .impact_bound = 3e5,
                  .chosen = 3e5,
                  .kappa = 1.5e4,
                  .governing = "impact"}};
  r.neighbor_skin_fraction = 0.15;
  const json written = r;
  EXPECT_EQ(written.at("neighbor_skin_fraction").get<double>(), 0.15);
  EXPECT_EQ(written.at("powder_load").dump(), "0");
  EXPECT_DOUBLE_EQ(written.at("overlap_p95_fraction").get<double>(), 0.018);
  EXPECT_DOUBLE_EQ(written.at("solid_fraction").get<double>(), 0.55 + 0.07);
  EXPECT_EQ(json(written.get<CellResult>()).dump(), written.dump());
}

TEST(CellResult, SkippedCellWritesOnlyWhyWhereAndItsLoad) {
  const json written =
      CellResult{.slot = {{"region", "toe"}, {"index", 3}}, .powder_load = 0.5, .skipped = "none"};
  EXPECT_EQ(written, (json{{"skipped", "none"},
                           {"slot", {{"region", "toe"}, {"index", 3}}},
                           {"powder_load", 0.5}}));
  EXPECT_EQ(json(written.get<CellResult>()), written);
}

TEST(CellResult, OlderCellsReadWithTheirOwnRules) {
  json older = CellResult(cell_result(measurements()));
  older.erase("steady");
  older.erase("converged");
  older.erase("standard_errors");
  older.erase("neighbor_skin_fraction");
  older["steady_state"]["steady"] = false;
  CellResult r = older.get<CellResult>();
  EXPECT_FALSE(r.neighbor_skin_fraction) << "no skin reported before it was";
  EXPECT_TRUE(json(r).at("neighbor_skin_fraction").is_null());
  EXPECT_FALSE(r.steady) << "steady_state.steady when there is no steady";
  EXPECT_FALSE(r.converged) << "converged when steady, without converged";
  EXPECT_FALSE(r.standard_errors);
  older["steady_state"]["steady"] = true;
  r = older.get<CellResult>();
  EXPECT_TRUE(r.steady);
  EXPECT_TRUE(r.converged);
}

}  // namespace
}  // namespace millflow::method
