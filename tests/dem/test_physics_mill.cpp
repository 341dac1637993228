// A ball charge in a small rotating mill: rigid rotation at low speed, the energy balance,
// determinism across thread counts and checkpoint/restart identity.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include "dem/binary_io.hpp"
#include "dem/checkpoint.hpp"
#include "dem/mill_setup.hpp"
#include "tests/dem/same_bits.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

using testing::same_bits;
using testing::small_mill;
using testing::with_threads;

System settled_mill(double fill) {
  System system = build_mill(small_mill(fill, 0.0));
  system.set_time_step_from_collisions(20);
  settle_charge(system, 1.0, 1e-6);
  return system;
}

TEST(MillPhysics, SlowMillCarriesTheBedAsARigidBody) {
  System system = settled_mill(0.3);
  const double omega = 0.05 * critical_speed(0.2, 0.01);
  set_mill_speed(system, omega);
  system.step(static_cast<std::size_t>(0.3 / system.time_step()));  // spin-up
  // The bed below the axis, away from its free surface, turns with the shell: the angular
  // velocity about the axis of balls in the lower half, more than 2 diameters in from the
  // surface of the bed, averages to the shell's within 5%.
  double sum = 0.0;
  int count = 0;
  const auto x = system.positions();
  const auto v = system.velocities();
  double top_of_bed = -1.0;
  for (const Vec3& p : x) top_of_bed = std::max(top_of_bed, p.y());
  for (std::size_t b = 0; b < system.size(); ++b) {
    const double r2 = x[b].x() * x[b].x() + x[b].y() * x[b].y();
    if (x[b].y() > top_of_bed - 0.02 || x[b].y() > 0.0 || r2 < 0.04 * 0.04) continue;
    sum += (x[b].x() * v[b].y() - x[b].y() * v[b].x()) / r2;
    ++count;
  }
  ASSERT_GT(count, 30);
  EXPECT_NEAR(sum / count, omega, 0.05 * omega) << count << " balls";
}

TEST(MillPhysics, ShellWorkEqualsEnergyChangePlusDissipation) {
  System system = settled_mill(0.3);
  set_mill_speed(system, 0.75 * critical_speed(0.2, 0.01));
  const EnergyBudget start = system.energy();
  system.step(static_cast<std::size_t>(0.4 / system.time_step()));
  const EnergyBudget end = system.energy();
  const double work = end.wall_work - start.wall_work;
  const double accounted =
      end.mechanical() - start.mechanical() + end.dissipated - start.dissipated;
  ASSERT_GT(work, 0.0);
  EXPECT_NEAR(accounted, work, 0.01 * work) << "shell work " << work << " J";
}

TEST(MillPhysics, SameBitsAtOneAndTwoThreads) {
  auto run = [](int threads) {
    System system = build_mill(small_mill(0.3, 0.75));
    with_threads(threads, [&] {
      system.set_time_step_from_collisions(20);
      set_mill_speed(system, 0.75 * critical_speed(0.2, 0.01));
      system.step(3000);
    });
    return system;
  };
  const System one = run(1), two = run(2);
  EXPECT_TRUE(same_bits(one.positions(), two.positions()));
  EXPECT_TRUE(same_bits(one.velocities(), two.velocities()));
  EXPECT_TRUE(same_bits(one.angular_velocities(), two.angular_velocities()));
  EXPECT_EQ(one.wall_load(0).work, two.wall_load(0).work);
  EXPECT_EQ(one.energy().dissipated, two.energy().dissipated);
}

TEST(MillPhysics, ContinuingFromACheckpointGivesTheSameBits) {
  const auto path = std::filesystem::temp_directory_path() / "millflow_test_mill.ckpt";
  System reference = build_mill(small_mill(0.3, 0.75));
  reference.set_time_step_from_collisions(20);
  set_mill_speed(reference, 0.75 * critical_speed(0.2, 0.01));
  System interrupted = reference;
  reference.step(2000);

  interrupted.step(1000);
  save_checkpoint(interrupted, path);
  System resumed = load_checkpoint(path);
  std::filesystem::remove(path);
  resumed.step(1000);

  EXPECT_EQ(resumed.time(), reference.time());
  EXPECT_TRUE(same_bits(resumed.positions(), reference.positions()));
  EXPECT_TRUE(same_bits(resumed.velocities(), reference.velocities()));
  EXPECT_TRUE(same_bits(resumed.angular_velocities(), reference.angular_velocities()));
  EXPECT_EQ(resumed.wall_load(0).work, reference.wall_load(0).work);
  EXPECT_EQ(resumed.energy().dissipated, reference.energy().dissipated);
  EXPECT_EQ(resumed.rng().state(), reference.rng().state());
}

TEST(MillPhysics, CorruptCheckpointIsRefused) {
  const auto path = std::filesystem::temp_directory_path() / "millflow_test_corrupt.ckpt";
  System system = build_mill(small_mill(0.2, 0.75));
  system.set_time_step_from_collisions(20);
  system.step(10);
  save_checkpoint(system, path);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - 7);
  EXPECT_THROW(load_checkpoint(path), CorruptData);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace millflow::dem
