// Lees-Edwards boundaries: crossing particles get the image shift in position and velocity, and
// contacts across the sheared boundary see the image's velocity; the affine stretch of a barostat.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <tuple>
#include <vector>

#include "dem/checkpoint.hpp"
#include "dem/rng.hpp"
#include "dem/system.hpp"
#include "tests/dem/same_bits.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

using testing::same_bits;
using testing::steel_table;
using testing::with_threads;

Domain sheared_box(double shear_velocity) {
  Domain box;
  box.lo = Vec3::Zero();
  box.hi = Vec3(0.1, 0.08, 0.06);
  box.periodic = {true, true, true};
  box.lees_edwards = LeesEdwards{.enabled = true,
                                 .flow_axis = 0,
                                 .gradient_axis = 1,
                                 .offset = 0.0,
                                 .velocity = shear_velocity};
  return box;
}

TEST(LeesEdwards, ParticleCrossingUpperFaceReentersShiftedInPositionAndVelocity) {
  const double shear_velocity = 0.8;  // relative velocity of the upper image, m/s
  System system(steel_table(0.5, 0.5), sheared_box(shear_velocity), Vec3::Zero());
  const Vec3 v0(0.1, 2.0, 0.0);
  system.add_particle({.position = Vec3(0.05, 0.0795, 0.03), .velocity = v0, .radius = 0.004});
  system.set_time_step(1e-5);
  std::size_t steps = 0;
  while (system.positions()[0].y() > 0.04 && steps < 1000) {
    system.step();
    ++steps;
  }
  ASSERT_LT(steps, 1000u) << "the particle never crossed";
  const double t = system.time();
  const double offset = system.domain().lees_edwards.offset;
  EXPECT_NEAR(offset, shear_velocity * t, 1e-12);
  // Straight-line motion, then the image shift: x - offset, vx - shear velocity.
  EXPECT_NEAR(system.positions()[0].y(), 0.0795 + v0.y() * t - 0.08, 1e-12);
  EXPECT_NEAR(system.positions()[0].x(), 0.05 + v0.x() * t - offset, 1e-12);
  EXPECT_NEAR(system.velocities()[0].x(), v0.x() - shear_velocity, 1e-12);
  EXPECT_NEAR(system.velocities()[0].y(), v0.y(), 1e-12);
}

TEST(LeesEdwards, ParticleCrossingLowerFaceReentersWithOppositeShift) {
  const double shear_velocity = 0.8;
  System system(steel_table(0.5, 0.5), sheared_box(shear_velocity), Vec3::Zero());
  system.domain().lees_edwards.offset = 0.03;
  system.add_particle(
      {.position = Vec3(0.09, 0.0005, 0.03), .velocity = Vec3(0, -2.0, 0), .radius = 0.004});
  system.set_time_step(1e-5);
  system.step(50);
  const double offset = system.domain().lees_edwards.offset;
  EXPECT_NEAR(system.positions()[0].x(), std::fmod(0.09 + offset, 0.1), 1e-12);
  EXPECT_NEAR(system.velocities()[0].x(), shear_velocity, 1e-12);
}

TEST(LeesEdwards, ContactAcrossTheBoundaryFeelsTheImageVelocity) {
  // Two frictional spheres touching across the sheared boundary, at rest in their own boxes:
  // the image of the lower sphere above the box moves along +x at the shear velocity, so
  // friction drags the upper sphere along +x and the lower one along -x.
  const double shear_velocity = 0.5;
  System system(steel_table(0.5, 0.5), sheared_box(shear_velocity), Vec3::Zero());
  const double r = 0.004;
  system.add_particle({.position = Vec3(0.05, 0.0795, 0.03), .radius = r});  // top of the box
  system.add_particle(
      {.position = Vec3(0.05, 0.0075 - 0.0001, 0.03), .radius = r});  // image above touches it
  system.set_time_step(1e-6);
  system.step();
  ASSERT_EQ(system.active_contact_count(), 1u);
  EXPECT_GT(system.forces()[0].x(), 0.0);
  EXPECT_LT(system.forces()[1].x(), 0.0);
  EXPECT_NEAR(system.forces()[0].x(), -system.forces()[1].x(), 1e-12);
  // Normal pushes them apart: the top one down, the image of the bottom one up.
  EXPECT_LT(system.forces()[0].y(), 0.0);
  EXPECT_GT(system.forces()[1].y(), 0.0);
}

TEST(LeesEdwards, AffineStretchScalesPositionsTheBoxAndTheImageVelocity) {
  System system(steel_table(0.5, 0.5), sheared_box(0.8), Vec3::Zero());
  system.add_particle(
      {.position = Vec3(0.05, 0.02, 0.03), .velocity = Vec3(0.1, 0.2, 0.3), .radius = 0.004});
  system.add_particle({.position = Vec3(0.05, 0.03, 0.03), .radius = 0.004});
  system.deform_affinely(1, 0.9);
  EXPECT_DOUBLE_EQ(system.domain().length().y(), 0.08 * 0.9);
  EXPECT_DOUBLE_EQ(system.positions()[0].y(), 0.02 * 0.9);
  EXPECT_DOUBLE_EQ(system.positions()[1].y(), 0.03 * 0.9);
  EXPECT_DOUBLE_EQ(system.positions()[0].x(), 0.05);
  EXPECT_EQ(system.velocities()[0], Vec3(0.1, 0.2, 0.3));
  EXPECT_DOUBLE_EQ(system.domain().lees_edwards.velocity, 0.8 * 0.9) << "the shear rate stays";
  // The neighbour list follows the new box: 9 mm apart, then 7.65 mm, closer than 2 r = 8 mm.
  system.set_time_step(1e-6);
  system.step();
  EXPECT_EQ(system.active_contact_count(), 0u);
  system.deform_affinely(1, 0.85);
  system.step();
  EXPECT_EQ(system.active_contact_count(), 1u);
}

TEST(LeesEdwards, AffineStretchRefusesAWalledAxisAndABadFactor) {
  Domain walled = sheared_box(0.0);
  walled.lees_edwards.enabled = false;
  walled.periodic = {true, false, true};
  System system(steel_table(0.5, 0.5), walled, Vec3::Zero());
  EXPECT_THROW(system.deform_affinely(1, 0.9), std::invalid_argument);
  EXPECT_THROW(system.deform_affinely(0, 0.0), std::invalid_argument);
  EXPECT_THROW(system.deform_affinely(0, std::nan("")), std::invalid_argument);
}

// A dense, sheared Lees-Edwards box: balls of 4-6 mm on a jittered lattice of 9 mm spacing,
// squeezed along y so that neighbours overlap, at a shear velocity that keeps them colliding.
System dense_sheared_box() {
  System system(steel_table(0.5, 0.5, 1e5), sheared_box(0.8), Vec3::Zero());
  Rng rng(7);
  for (int i = 0; i < 11; ++i) {
    for (int j = 0; j < 9; ++j) {
      for (int k = 0; k < 6; ++k) {
        const Vec3 jitter(rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3),
                          rng.uniform(-1e-3, 1e-3));
        system.add_particle(
            {.position = Vec3(0.0045 + 0.009 * i, 0.0045 + 0.0088 * j, 0.005 + 0.01 * k) + jitter,
             .velocity = Vec3(rng.uniform(-0.1, 0.1), 0.0, 0.0),
             .radius = rng.uniform(0.004, 0.005)});
      }
    }
  }
  system.deform_affinely(1, 0.92);
  return system;
}

TEST(LeesEdwards, ContactVirialIsTheSumOverContactsInForceWithTheSameBitsAtAnyThreadCount) {
  const auto expected_virial = [](const System& system) {
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    for (const ActiveContact& c : system.active_contacts())
      sum += c.force_on_a * c.branch.transpose();
    return sum;
  };
  std::array<Eigen::Matrix3d, 2> virial;
  for (const int threads : {1, 2}) {
    System system = dense_sheared_box();
    with_threads(threads, [&] { system.step(100); });
    ASSERT_GT(system.active_contact_count(), system.size()) << "the box should be dense";
    EXPECT_LT((system.contact_virial() - expected_virial(system)).norm(),
              1e-12 * system.contact_virial().norm());
    // The barostat's stretch scales the branch vectors, and the virial with them.
    system.deform_affinely(1, 1.01);
    EXPECT_LT((system.contact_virial() - expected_virial(system)).norm(),
              1e-12 * system.contact_virial().norm());
    with_threads(threads, [&] { system.step(100); });
    EXPECT_LT((system.contact_virial() - expected_virial(system)).norm(),
              1e-12 * system.contact_virial().norm());
    virial[threads - 1] = system.contact_virial();
  }
  EXPECT_TRUE(same_bits(virial[0], virial[1]));
}

// The pair pass's contacts in force four at a time in lanes against each alone, over a run long
// enough for contacts to start, slide, cross the boundary and end: the same bits.
TEST(LeesEdwards, ContactsInLanesGiveTheBitsOfEachContactAlone) {
  System lanes = dense_sheared_box();
  if (!lanes.contacts_in_lanes()) GTEST_SKIP() << "the DEM library is built without AVX2 lanes";
  System alone = lanes;
  alone.set_contacts_in_lanes(false);
  ASSERT_FALSE(alone.contacts_in_lanes());
  lanes.step(100);
  alone.step(100);
  ASSERT_GT(lanes.active_contact_count(), lanes.size()) << "the box should be dense";
  lanes.step(200);
  alone.step(200);
  EXPECT_TRUE(same_bits(lanes.positions(), alone.positions()));
  EXPECT_TRUE(same_bits(lanes.velocities(), alone.velocities()));
  EXPECT_TRUE(same_bits(lanes.angular_velocities(), alone.angular_velocities()));
  EXPECT_TRUE(same_bits(lanes.forces(), alone.forces()));
  EXPECT_TRUE(same_bits(lanes.contact_virial(), alone.contact_virial()));
  const EnergyBudget a = lanes.energy(), b = alone.energy();
  EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "the same energy books to the bit";
}

TEST(LeesEdwards, ReorderingCarriesEveryContactAlong) {
  System original = dense_sheared_box();
  original.step(100);  // contacts with loaded tangential springs
  System reordered = original;
  const std::vector<ParticleId> old_of = reordered.reorder_particles();
  ASSERT_NE(old_of, [&] {
    std::vector<ParticleId> identity(old_of.size());
    for (std::size_t p = 0; p < identity.size(); ++p) identity[p] = static_cast<ParticleId>(p);
    return identity;
  }()) << "the lattice order should not already be the curve's";
  EXPECT_EQ(reordered.active_contact_count(), original.active_contact_count());
  original.step(1);
  reordered.step(1);
  double largest = 0.0, worst = 0.0;
  for (std::size_t p = 0; p < old_of.size(); ++p) {
    largest = std::max(largest, original.forces()[old_of[p]].norm());
    worst = std::max(worst, (reordered.forces()[p] - original.forces()[old_of[p]]).norm());
    worst = std::max(worst, (reordered.positions()[p] - original.positions()[old_of[p]]).norm());
  }
  EXPECT_LT(worst, 1e-12 * largest) << "the same contacts, springs and forces, renumbered";
}

TEST(LeesEdwards, TheContactStoreLaidOutAgainMovesNoBit) {
  System automatic = dense_sheared_box();
  automatic.step(100);  // contacts with loaded tangential springs, some slots reused
  const std::uint64_t compactions_before = automatic.contact_compaction_count();
  System forced = automatic;
  for (int n = 0; n < 200; ++n) {
    forced.compact_contacts();
    forced.step();
  }
  automatic.step(200);
  EXPECT_GE(forced.contact_compaction_count(), compactions_before + 200);
  EXPECT_TRUE(same_bits(forced.positions(), automatic.positions()));
  EXPECT_TRUE(same_bits(forced.velocities(), automatic.velocities()));
  EXPECT_TRUE(same_bits(forced.angular_velocities(), automatic.angular_velocities()));
  EXPECT_TRUE(same_bits(forced.forces(), automatic.forces()));
  EXPECT_TRUE(same_bits(forced.contact_virial(), automatic.contact_virial()));
  EXPECT_EQ(forced.active_contact_count(), automatic.active_contact_count());
  const EnergyBudget a = automatic.energy(), f = forced.energy();
  EXPECT_EQ(std::memcmp(&a, &f, sizeof a), 0) << "the same energy books to the bit";
}

TEST(LeesEdwards, AStepLaysTheContactStoreOutAgainOnceItsContactsHaveComeAndGone) {
  System system = dense_sheared_box();
  system.step(400);
  // Between the rebuilds (which lay the store out too, and are not counted here).
  EXPECT_GT(system.contact_compaction_count(), 0u);
}

TEST(LeesEdwards, ReorderedRunsHaveTheSameBitsAtAnyThreadCountAndAcrossACheckpoint) {
  const auto run = [](int threads, std::size_t pause) {
    System system = dense_sheared_box();
    system.set_reorder_interval(25);
    with_threads(threads, [&] { system.step(pause); });
    System resumed = system_from_checkpoint_payload(checkpoint_payload(system), kCheckpointVersion);
    with_threads(threads, [&] { resumed.step(210 - pause); });
    return std::vector<Vec3>(resumed.positions().begin(), resumed.positions().end());
  };
  const std::vector<Vec3> straight = run(1, 210);
  for (const auto& [threads, pause] :
       {std::pair{2, std::size_t{210}}, std::pair{1, std::size_t{60}},
        std::pair{2, std::size_t{137}}}) {
    const std::vector<Vec3> other = run(threads, pause);
    EXPECT_TRUE(same_bits(straight, other))
        << threads << " threads, checkpoint after " << pause << " steps";
  }
}

TEST(LeesEdwards, ChangingTheSkinOfARunningSystemKeepsItsBits) {
  const auto run = [](double skin_fraction) {
    System system = dense_sheared_box();
    system.set_reorder_interval(25);  // the renumbering's cells do not follow the skin either
    system.step(50);                  // contacts with loaded tangential springs
    const auto radii = system.radii();
    system.set_neighbor_skin(skin_fraction * 2.0 * *std::min_element(radii.begin(), radii.end()));
    system.step(150);
    return system;
  };
  const System wide = run(0.5), narrow = run(0.05);
  EXPECT_LT(narrow.candidate_pairs().size(), wide.candidate_pairs().size());
  EXPECT_TRUE(same_bits(wide.positions(), narrow.positions()));
  EXPECT_TRUE(same_bits(wide.velocities(), narrow.velocities()));
}

// The contacts in force between steps, as (first, second, force on the first) in old numbers.
std::vector<std::tuple<ParticleId, std::uint32_t, Vec3>> contacts_in_old_numbers(
    const System& system, const std::vector<ParticleId>& old_of) {
  std::vector<std::tuple<ParticleId, std::uint32_t, Vec3>> out;
  for (const ActiveContact& c : system.active_contacts()) {
    ParticleId a = old_of.empty() ? c.a : old_of[c.a];
    std::uint32_t b = old_of.empty() ? c.b : old_of[c.b];
    Vec3 force = c.force_on_a;
    if (a > b) {
      std::swap(a, b);
      force = -force;
    }
    out.emplace_back(a, b, force);
  }
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) {
    return std::pair(std::get<0>(x), std::get<1>(x)) < std::pair(std::get<0>(y), std::get<1>(y));
  });
  return out;
}

TEST(LeesEdwards, ContactsInForceSurviveANewSkinAndARenumberingBetweenSteps) {
  System system = dense_sheared_box();
  system.step(50);
  const auto before = contacts_in_old_numbers(system, {});
  const double elastic = system.energy().elastic;
  ASSERT_GT(before.size(), 10u);
  const auto radii = system.radii();
  system.set_neighbor_skin(0.05 * 2.0 * *std::min_element(radii.begin(), radii.end()));
  EXPECT_EQ(contacts_in_old_numbers(system, {}), before);
  EXPECT_EQ(system.energy().elastic, elastic);
  const std::vector<ParticleId> old_of = system.reorder_particles();
  EXPECT_EQ(contacts_in_old_numbers(system, old_of), before);
  EXPECT_NEAR(system.energy().elastic, elastic, 1e-12 * elastic);  // summed in another order
}

}  // namespace
}  // namespace millflow::dem
