// Shear cell construction: counts from the solid fraction and the powder load, placement without
// overlaps, the wall layers, the servo's derived constants, and input checks.
#include <gtest/gtest.h>
#include <algorithm>

#include <numbers>
#include <numeric>
#include <vector>

#include "dem/shear_cell.hpp"
#include "tests/dem/scenes.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

using testing::small_shear_cell;

double sphere_volume(double d) {
  return std::numbers::pi / 6.0 * d * d * d;
}

std::size_t count_material(const System& system, const std::string& name) {
  const MaterialId id = system.materials().find(name);
  std::size_t n = 0;
  for (std::size_t p = 0; p < system.size(); ++p) {
    n += system.particle_groups()[p] == kFreeParticle && system.particle_materials()[p] == id ? 1
                                                                                              : 0;
  }
  return n;
}

TEST(ShearCell, MediaCountFollowsTheSolidFractionAndPowderCountTheLoad) {
  const ShearCellSetup setup = small_shear_cell(0.05, 0.5, 0.3);
  const ShearCell cell(setup);
  const double d = setup.media_diameter, area = 16 * d * d, height = 6 * d;
  const double media = setup.media_solid_fraction * area * height / sphere_volume(d);  // 105.04
  // U = 0.5 of the voids (1 - 0.55) filled by a powder bed at solid fraction 0.6.
  const double powder = 0.5 * 0.45 * area * height * 0.6 / sphere_volume(0.3 * d);
  EXPECT_EQ(cell.media_count(), static_cast<std::size_t>(std::llround(media)));
  EXPECT_EQ(cell.powder_count(), static_cast<std::size_t>(std::llround(powder)));
  EXPECT_EQ(count_material(cell.system(), "steel"), cell.media_count());
  EXPECT_EQ(count_material(cell.system(), "clinker"), cell.powder_count());
}

TEST(ShearCell, ZeroLoadHasNoPowder) {
  const ShearCell cell(small_shear_cell(0.05, 0.0));
  EXPECT_EQ(cell.powder_count(), 0u);
  EXPECT_EQ(count_material(cell.system(), "clinker"), 0u);
  EXPECT_EQ(cell.system().size(), cell.media_count() + cell.wall_ball_count());
}

TEST(ShearCell, ParticlesArePlacedWithoutOverlaps) {
  for (auto boundary :
       {ShearCellSetup::Boundary::RoughWalls, ShearCellSetup::Boundary::LeesEdwards}) {
    ShearCellSetup setup = small_shear_cell(0.05, 0.4, 0.25);
    setup.boundary = boundary;
    setup.size_diameters = Vec3(6, 6, 6);
    const ShearCell cell(setup);
    ASSERT_GT(cell.powder_count(), 100u);
    EXPECT_NO_THROW(cell.system().check_overlaps(0.0));
  }
}

TEST(ShearCell, WallLayersAreGroupsMovingOppositeWaysWithTheGapBetweenThem) {
  const ShearCellSetup setup = small_shear_cell(0.05);
  const ShearCell cell(setup);
  const System& system = cell.system();
  ASSERT_EQ(system.group_count(), 2u);
  EXPECT_DOUBLE_EQ(system.group(1).velocity.x(), -system.group(2).velocity.x());
  EXPECT_DOUBLE_EQ(system.group(2).velocity.x() - system.group(1).velocity.x(), cell.wall_speed());
  // Every free particle lies between the layers, clear of them.
  const double d = setup.media_diameter;
  for (std::size_t p = 0; p < system.size(); ++p) {
    if (system.particle_groups()[p] != kFreeParticle) continue;
    EXPECT_GT(system.positions()[p].y(), 0.5 * d);
    EXPECT_LT(system.positions()[p].y(), cell.gap() - 0.5 * d);
  }
  // Wall balls use their own material so their contacts count as "wall".
  EXPECT_EQ(system.materials().material(system.particle_materials()[0]).name, "steel_wall");
}

TEST(ShearCell, LeesEdwardsCellIsPeriodicWithTheImposedProfile) {
  ShearCellSetup setup = small_shear_cell(0.05);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.size_diameters = Vec3(6, 6, 6);
  const ShearCell cell(setup);
  const Domain& domain = cell.system().domain();
  EXPECT_TRUE(domain.lees_edwards.enabled);
  // Filled loose, taller than the nominal 6 diameters, for the barostat to compress.
  EXPECT_GT(domain.length().y(), 6 * setup.media_diameter);
  EXPECT_DOUBLE_EQ(domain.lees_edwards.velocity, setup.shear_rate * domain.length().y());
  EXPECT_EQ(cell.system().group_count(), 0u);
  // The imposed profile, agitated by at most 0.1 gdot d per component (twice that after the
  // mean agitation is taken out) and without net momentum.
  const double y_mid = 0.5 * domain.length().y();
  const double agitation = 0.2 * setup.shear_rate * setup.media_diameter;
  Vec3 momentum = Vec3::Zero();
  double largest_z_speed = 0.0;
  for (std::size_t p = 0; p < cell.system().size(); ++p) {
    const Vec3 v = cell.system().velocities()[p];
    EXPECT_NEAR(v.x(), setup.shear_rate * (cell.system().positions()[p].y() - y_mid), agitation);
    EXPECT_LE(std::abs(v.y()), agitation);
    EXPECT_LE(std::abs(v.z()), agitation);
    largest_z_speed = std::max(largest_z_speed, std::abs(v.z()));
    momentum += v - Vec3(setup.shear_rate * (cell.system().positions()[p].y() - y_mid), 0, 0);
  }
  EXPECT_GT(largest_z_speed, 0.0);
  EXPECT_LT(momentum.norm(), 1e-12 * agitation * static_cast<double>(cell.system().size()));
}

TEST(ShearCell, LeesEdwardsMeasurementHasTheSameBitsAtOneAndTwoThreads) {
  // The boundary's power and the barostat's spring energies are sums over all particles and
  // pairs, taken by every thread of the cell (deterministic_sum): the same bits at any count.
  const auto measured = [](int threads) {
    ShearCellMeasurements m;
    testing::with_threads(threads, [&] {
      // Both sums in several blocks (of 512 particles, of 2,048 candidate pairs).
      ShearCellSetup setup = small_shear_cell(0.05, 1.0, 0.25);
      setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
      ShearCell cell(setup);
      cell.compact();
      EXPECT_GT(cell.system().size(), 4 * 512u);
      EXPECT_GT(cell.system().candidate_pairs().size(), 4 * 2048u);
      m = cell.measure(0.02, MeasureOptions{.samples = 20, .record_collisions = false});
    });
    return m;
  };
  const ShearCellMeasurements one = measured(1), two = measured(2);
  ASSERT_GT(one.work_in, 0.0);
  ASSERT_NE(one.stress_control_work, 0.0) << "the barostat stretched the box";
  EXPECT_EQ(one.power_density, two.power_density);
  EXPECT_EQ(one.work_in, two.work_in);
  EXPECT_EQ(one.stress_control_work, two.stress_control_work);
  EXPECT_EQ(one.shear_stress, two.shear_stress);
}

// The barostat stretches an answer larger than its part strain in equal parts over its interval,
// as few as keep each part within it, not at once at the interval's end (a stretch at once made
// the stress ring: dem/stress_control.hpp).
TEST(ShearCell, BarostatStretchesALargeAnswerInEqualPartsOverItsInterval) {
  ShearCellSetup setup = small_shear_cell(0.3);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.media_media.normal_stiffness = 1e4 * setup.normal_stress * setup.media_diameter;
  setup.steps_per_collision = 40;  // the campaigns' default: at most 5 parts
  ShearCell cell(setup);
  cell.compact();
  const auto interval = static_cast<std::uint64_t>(setup.steps_per_collision);
  const std::uint64_t most_parts = interval / kBarostatStretchEvery;
  const double part_strain = cell.stress_control().settings().part_strain;
  EXPECT_DOUBLE_EQ(part_strain, 0.5 * setup.normal_stress * setup.media_diameter /
                                    setup.media_media.normal_stiffness);
  // From the next answer on, over eight intervals: the strain of each step.
  while (cell.system().step_count() % interval != interval - 1) cell.advance(1);
  std::vector<double> strains;
  for (std::uint64_t s = 0; s < 8 * interval; ++s) {
    const double before = cell.system().domain().length().y();
    cell.advance(1);
    strains.push_back(cell.system().domain().length().y() / before - 1.0);
  }
  // strains[s] is the step to step count (answer + s): the answers at s = 0 mod interval, parts
  // only at s = 0 mod kBarostatStretchEvery, the first ones of the interval, all alike.
  int split = 0;
  for (std::uint64_t answer = 0; answer < strains.size(); answer += interval) {
    const double part = strains[answer];
    ASSERT_NE(part, 0.0) << "answer at step " << answer;
    std::uint64_t parts = 0;
    for (std::uint64_t s = answer; s < answer + interval; ++s) {
      if (strains[s] == 0.0) continue;
      EXPECT_EQ((s - answer) % kBarostatStretchEvery, 0u) << "step " << s;
      EXPECT_EQ(s - answer, parts * kBarostatStretchEvery) << "step " << s;
      EXPECT_NEAR(strains[s], part, 1e-9 * std::abs(part)) << "step " << s;
      ++parts;
    }
    // As few parts as keep each within the part strain (to rounding), at most one per
    // kBarostatStretchEvery steps.
    EXPECT_LE(parts, most_parts);
    if (parts < most_parts) {
      EXPECT_LE(std::abs(part), part_strain * (1.0 + 1e-9));
    }
    if (parts > 1) {
      EXPECT_GT(std::abs(part) * static_cast<double>(parts) / (static_cast<double>(parts) - 1.0),
                part_strain);
    }
    split += parts > 1;
  }
  EXPECT_GT(split, 0) << "no answer of this cell at I = 0.3 was large enough to split";
}

TEST(ShearCell, ServoConstantsFollowTheDocumentedLaw) {
  const ShearCellSetup setup = small_shear_cell(0.05);
  const ShearCell cell(setup);
  const double d = setup.media_diameter, m = 7800.0 * sphere_volume(d);
  const double t_c =
      collision_duration(setup.media_media.normal_stiffness, 0.5 * m,
                         damping_ratio_for_restitution(setup.media_media.restitution));
  const double t_wave = 6.0 * t_c;
  // tau = max(t_wave, 0.1 / gdot) / g; M = H / (10 p A tau): the flowing bed's modulus.
  const double tau = std::max(t_wave, 0.1 / setup.shear_rate) / 0.5;
  const double area = 16.0 * d * d, gap = 6.0 * d;
  EXPECT_NEAR(cell.servo_mobility(), gap / (10.0 * 1000.0 * area * tau),
              1e-12 * cell.servo_mobility());
  EXPECT_NEAR(cell.servo_max_speed(), 0.5 * d / t_wave, 1e-12);
}

// A measurement's samples must not sit at a fixed phase of the barostat's interval, which stretches
// the box at its end (the stress rings after each stretch): the sample interval is the first from
// the window's own that is prime to the control interval.
TEST(ShearCell, SampleIntervalWalksThroughEveryPhaseOfTheControlInterval) {
  EXPECT_EQ(sample_interval_across_control_phases(80, 40), 81u);
  EXPECT_EQ(sample_interval_across_control_phases(83, 40), 83u);
  EXPECT_EQ(sample_interval_across_control_phases(250, 40), 251u);
  EXPECT_EQ(sample_interval_across_control_phases(0, 40), 1u);
  EXPECT_EQ(sample_interval_across_control_phases(6, 1), 6u);
  EXPECT_EQ(sample_interval_across_control_phases(6, 0), 6u);
  for (const std::uint64_t control : {2u, 20u, 37u, 40u, 160u, 1000u}) {
    for (std::uint64_t every = 1; every <= 500; ++every) {
      const std::uint64_t chosen = sample_interval_across_control_phases(every, control);
      EXPECT_EQ(std::gcd(chosen, control), 1u) << every << " against " << control;
      for (std::uint64_t smaller = every; smaller < chosen; ++smaller)
        EXPECT_GT(std::gcd(smaller, control), 1u) << every << " against " << control;
      // So `control` consecutive samples fall on `control` different phases.
      std::vector<bool> seen(control, false);
      for (std::uint64_t k = 0; k < control; ++k) seen[(k * chosen) % control] = true;
      EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](bool b) { return b; }));
    }
  }
}

TEST(ShearCell, SizeScaledStiffnessUsesTheHarmonicMeanDiameter) {
  EXPECT_DOUBLE_EQ(size_scaled_stiffness(1000.0, 0.01, 0.01, 0.01), 1000.0);
  EXPECT_DOUBLE_EQ(size_scaled_stiffness(1000.0, 0.01, 0.002, 0.002), 200.0);
  EXPECT_NEAR(size_scaled_stiffness(1000.0, 0.01, 0.01, 0.002),
              1000.0 * (2 * 0.01 * 0.002 / 0.012) / 0.01, 1e-9);
  EXPECT_THROW(size_scaled_stiffness(1000.0, 0.01, -1.0, 0.002), std::invalid_argument);
}

TEST(ShearCell, RejectsBadSettingsNamingThem) {
  auto message = [](auto change) {
    ShearCellSetup setup = small_shear_cell(0.05);
    change(setup);
    try {
      ShearCell cell(setup);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(
      message([](auto& s) { s.powder_diameter_ratio = 1.5; }).find("powder diameter ratio = 1.5"),
      std::string::npos);
  EXPECT_NE(message([](auto& s) { s.servo_gain = 0.0; }).find("servo gain"), std::string::npos);
  EXPECT_NE(message([](auto& s) { s.shear_rate = -1.0; }).find("shear rate = -1"),
            std::string::npos);
  EXPECT_NE(message([](auto& s) {
              s.boundary = ShearCellSetup::Boundary::LeesEdwards;
              s.gravity = true;
            }).find("gravity"),
            std::string::npos);
}

TEST(ShearCell, AStrainOfMoreStepsThanACountHoldsIsRefused) {
  ShearCellSetup setup = small_shear_cell(0.05);
  setup.shear_rate = 1e-300;  // accepted (> 0), but no strain can be reached
  ShearCell cell(setup);
  try {
    cell.measure(0.5);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("shear cell: strain = 0.5 at 1e-300 1/s is ", 0), 0u) << message;
    EXPECT_NE(message.find(", more than 9.01e+15; raise the shear rate or lower the strain"),
              std::string::npos)
        << message;
  }
}

// A run's progress counts compaction against the steps it is expected to take, so that a
// compaction of many minutes is seen to move; it never goes back and ends at 1. At the stiffness
// the campaigns run (k_n / (p d) = 1e4) with powder, where compaction is long.
TEST(ShearCellRun, ProgressMovesThroughCompactionAndNeverGoesBack) {
  ShearCellSetup setup = small_shear_cell(0.1, 0.5, 0.5);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.size_diameters = Vec3(4, 5, 4);
  const double k = 1e4 * setup.normal_stress * setup.media_diameter;
  for (InteractionSpec* pair : {&setup.media_media, &setup.media_powder, &setup.powder_powder})
    pair->normal_stiffness = k;
  ShearCellRun run(setup, {.warmup_strain = 0.1,
                           .warmup_windows = 2,
                           .max_warmup_strain = 0.1,
                           .measure_strain = 0.1,
                           .measure = {.samples = 10, .max_strain = 0.1}});
  EXPECT_EQ(run.progress(), 0.0);
  double last = 0.0;
  int reports_while_compacting = 0;
  while (!run.advance(500)) {
    const double now = run.progress();
    EXPECT_GE(now, last) << run.phase_name() << " at step " << run.cell().system().step_count();
    EXPECT_LT(now, 1.0);
    if (!run.cell().compacted()) {
      ++reports_while_compacting;
      EXPECT_GT(now, 0.0) << "compaction at step " << run.cell().system().step_count();
    }
    last = now;
  }
  EXPECT_GE(reports_while_compacting, 3);
  EXPECT_TRUE(run.cell().compacted_under_load());
  EXPECT_EQ(run.progress(), 1.0);
}

}  // namespace
}  // namespace millflow::dem
