// The shear cell's stiffness policy at realistic stiffness: powder stays rigid at the cell's own
// normal stress (docs/shear_cells.md), and without the policy it does not.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>

#include "dem/shear_cell.hpp"
#include "dem/stiffness_policy.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

// A dense Lees-Edwards cell of 10 mm steel balls at k_n / (p d) = 1e4 with powder of 0.4 d
// filling the voids (load 1); the powder pairs get the collision time of the balls' pair, as a
// campaign that gives every pair one collision time does.
ShearCellSetup dense_powder_cell() {
  ShearCellSetup s = testing::small_shear_cell(0.1, 1.0, 0.4);
  s.boundary = ShearCellSetup::Boundary::LeesEdwards;
  s.size_diameters = Vec3(4, 5, 4);
  s.media_media.normal_stiffness = 1e4 * s.normal_stress * s.media_diameter;
  const double powder_mass_ratio = (s.powder.density / s.media.density) * 0.4 * 0.4 * 0.4;
  // Same collision time: k scales with the pair's effective mass (media-media m/2).
  s.media_powder.normal_stiffness =
      s.media_media.normal_stiffness * 2.0 * powder_mass_ratio / (1.0 + powder_mass_ratio);
  s.powder_powder.normal_stiffness = s.media_media.normal_stiffness * powder_mass_ratio;
  return s;
}

// A sparse Lees-Edwards cell at I = 0.3 with fine powder (0.125 d) at load 0.05: single grains
// at the ball-ball contacts, caught in the balls' collisions, where the impact bound governs.
ShearCellSetup sparse_powder_cell() {
  ShearCellSetup s = testing::small_shear_cell(0.3, 0.05, 0.125);
  s.boundary = ShearCellSetup::Boundary::LeesEdwards;
  s.size_diameters = Vec3(5, 5, 5);
  s.media_media.normal_stiffness = 1e4 * s.normal_stress * s.media_diameter;
  return s;
}

ShearCellMeasurements run(const ShearCellSetup& setup, double max_warmup_strain,
                          double warmup_strain = 1.0) {
  ShearCellRun cell(setup, {.warmup_strain = warmup_strain,
                            .warmup_windows = 2,
                            .max_warmup_strain = max_warmup_strain,
                            .measure_strain = 0.5,
                            .measure = {.samples = 50}});
  cell.advance(~std::uint64_t{0});
  return cell.measurements();
}

void print(const char* label, const ShearCellMeasurements& m) {
  for (std::size_t t = 0; t < kContactTypeCount; ++t) {
    const OverlapStats& o = m.overlaps[t];
    if (o.contacts == 0.0) continue;
    std::printf("%s %s: overlap mean %.4f p95 %.4f max %.4f of d_small (%g samples)\n", label,
                contact_type_name(static_cast<ContactType>(t)).c_str(), o.mean_fraction,
                o.p95_fraction, o.max_fraction, o.contacts);
  }
  std::printf("%s: p_yy %.4g Pa, p %.4g Pa, mu %.4g, stationary %d at strain %.3g, phi %.3g\n",
              label, m.normal_stress, m.mean_pressure, m.friction, m.stationary,
              m.stationary_strain, m.media_solid_fraction + m.powder_solid_fraction);
}

TEST(ShearCellStiffnessPolicy, KeepsEveryPairsOverlapWithinTheBoundAtRealisticStiffness) {
  spdlog::set_level(std::getenv("MF_DEBUG") ? spdlog::level::debug : spdlog::level::warn);
  ShearCellSetup setup = dense_powder_cell();
  const std::vector<PairStiffness> derived = apply_overlap_bound(setup);
  for (const PairStiffness& p : derived)
    std::printf("%s: k_n %.4g N/m (given %.4g), kappa %.4g\n", p.pair.c_str(), p.chosen, p.given,
                p.kappa);
  const ShearCellMeasurements m = run(setup, 4.0);
  print("policy", m);
  EXPECT_TRUE(m.stationary) << "the overlaps are those of the cell at its normal stress";
  for (std::size_t t = 0; t < kContactTypeCount; ++t) {
    const OverlapStats& o = m.overlaps[t];
    if (o.contacts == 0.0) continue;
    const std::string pair = contact_type_name(static_cast<ContactType>(t));
    EXPECT_LE(o.mean_fraction, setup.overlap_bound.mean_fraction) << pair;
    EXPECT_LE(o.p95_fraction, setup.overlap_bound.p95_fraction) << pair;
  }
  EXPECT_GT(m.overlaps[static_cast<std::size_t>(ContactType::MediaPowder)].contacts, 0.0);
  EXPECT_TRUE(m.overlap_ok);
}

// With the static bound alone the sparse cell's ball-powder p95 reached 4.3% of d_s in the
// campaign's cell (docs/cell_validation.md, table 5); the impact bound keeps it within 3%.
TEST(ShearCellStiffnessPolicy, KeepsBallPowderOverlapsWithinTheBoundAtLowLoad) {
  spdlog::set_level(spdlog::level::warn);
  ShearCellSetup setup = sparse_powder_cell();
  const std::vector<PairStiffness> derived = apply_overlap_bound(setup);
  ASSERT_EQ(derived[1].governing, "impact");
  std::printf("media-powder: k_n %.4g N/m (static bound %.4g), kappa %.4g\n", derived[1].chosen,
              derived[1].static_bound, derived[1].kappa);
  const ShearCellMeasurements m = run(setup, 0.5, 0.25);
  print("sparse", m);
  const OverlapStats& o = m.overlaps[static_cast<std::size_t>(ContactType::MediaPowder)];
  EXPECT_GT(o.contacts, 500.0);
  EXPECT_NEAR(m.normal_stress, setup.normal_stress, 0.2 * setup.normal_stress);
  EXPECT_LE(o.mean_fraction, setup.overlap_bound.mean_fraction);
  EXPECT_LE(o.p95_fraction, setup.overlap_bound.p95_fraction);
  EXPECT_TRUE(m.overlap_ok);
}

// The same cell with powder 50 times softer, kept as given: the check above can fail. Two strains
// of warm-up: after one the barostat had not settled on this soft bed (p_yy 1103-1239 Pa,
// depending on the phases it sampled; 1008 Pa after two).
TEST(ShearCellStiffnessPolicy, SoftPowderKeptAsGivenBreaksTheBoundAndIsFlagged) {
  spdlog::set_level(spdlog::level::warn);
  ShearCellSetup setup = dense_powder_cell();
  setup.media_powder.normal_stiffness /= 50.0;
  setup.powder_powder.normal_stiffness /= 50.0;
  const ShearCellMeasurements m = run(setup, 2.0, 2.0);
  print("soft", m);
  EXPECT_NEAR(m.normal_stress, setup.normal_stress, 0.2 * setup.normal_stress);
  EXPECT_GT(m.overlaps[static_cast<std::size_t>(ContactType::MediaPowder)].p95_fraction,
            setup.overlap_bound.p95_fraction);
  EXPECT_FALSE(m.overlap_ok);
}

}  // namespace
}  // namespace millflow::dem
