// A bed sheared between two planar walls, the upper one sliding and stress-controlled: the energy
// balance closes and the servo holds the normal force.
#include <gtest/gtest.h>

#include <cmath>

#include "dem/system.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

using testing::sphere_mass;
using testing::steel_table;

constexpr double kRadius = 0.005;
constexpr double kWidth = 0.06;  // periodic x and z

struct ShearedBed {
  System system;
  double target_force;
};

ShearedBed make_sheared_bed(double wall_speed, double pressure) {
  Domain box;
  box.lo = Vec3(0, -0.01, 0);
  box.hi = Vec3(kWidth, 0.08, kWidth);
  box.periodic = {true, false, true};
  const double ball_mass = sphere_mass(kRadius);
  const double stiffness =
      stiffness_for_collision_duration(5e-4, ball_mass / 2, damping_ratio_for_restitution(0.5));
  System system(steel_table(0.5, 0.5, stiffness), box, Vec3(0, -9.81, 0));
  const double target_force = pressure * kWidth * kWidth;
  system.add_wall({.name = "bottom",
                   .material = 0,
                   .shape = PlaneWall{.origin = Vec3::Zero(), .normal = Vec3::UnitY()}});
  // The 125 balls settle into about three layers (top near y = 34 mm); the wall starts above
  // them and descends at the servo's speed limit until it carries the target force.
  // Mobility: a force error of 1 N moves the wall at 5 mm/s, slow enough for the servo loop to
  // stay linear (well below the 50 mm/s limit) and stable.
  system.add_wall({.name = "top",
                   .material = 0,
                   .shape = PlaneWall{.origin = Vec3(0, 0.040, 0),
                                      .normal = -Vec3::UnitY(),
                                      .velocity = Vec3(wall_speed, 0, 0),
                                      .servo_target_force = target_force,
                                      .servo_mobility = 0.005,
                                      .servo_max_speed = 0.05}});
  Rng rng(3);
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      for (int k = 0; k < 5; ++k) {
        const Vec3 site = Vec3(i + 0.5, j + 0.5, k + 0.5) * 0.012 +
                          0.0004 * Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
        system.add_particle({.position = site, .radius = kRadius});
      }
    }
  }
  system.set_time_step_from_collisions(25);
  return {std::move(system), target_force};
}

TEST(ShearedBed, WallWorkEqualsEnergyChangePlusDissipation) {
  auto [system, target] = make_sheared_bed(0.5, 2000.0);
  system.step(static_cast<std::size_t>(0.3 / system.time_step()));  // compaction and start of shear
  const EnergyBudget start = system.energy();
  system.step(static_cast<std::size_t>(0.2 / system.time_step()));
  const EnergyBudget end = system.energy();
  const double work = end.wall_work - start.wall_work;
  const double accounted =
      end.mechanical() - start.mechanical() + end.dissipated - start.dissipated;
  ASSERT_GT(work, 0.0);
  EXPECT_NEAR(accounted, work, 0.01 * work) << "wall work " << work << " J";
}

TEST(ShearedBed, StressControlledWallHoldsTheTargetNormalForce) {
  // A linear servo moves the wall at v = M (F_target - F): over a window T its mean force is
  // exactly F_target - (wall displacement) / (M T), which tends to the target as the wall settles.
  auto [system, target] = make_sheared_bed(0.5, 2000.0);
  system.step(static_cast<std::size_t>(0.3 / system.time_step()));
  auto wall_height = [&] { return std::get<PlaneWall>(system.wall(1).shape).origin.y(); };
  const double start_height = wall_height();
  double impulse = 0.0;
  const std::size_t steps = static_cast<std::size_t>(0.3 / system.time_step());
  for (std::size_t s = 0; s < steps; ++s) {
    system.step();
    impulse += system.wall_load(1).force.y() *
               system.time_step();  // the particles push the top wall up (+y)
  }
  const double window = static_cast<double>(steps) * system.time_step();
  const double mean_force = impulse / window;
  const double mobility = std::get<PlaneWall>(system.wall(1).shape).servo_mobility;
  EXPECT_NEAR(mean_force, target + (wall_height() - start_height) / (mobility * window),
              0.02 * target)
      << "servo law";
  EXPECT_NEAR(mean_force, target, 0.1 * target) << "wall settled near the target";
}

}  // namespace
}  // namespace millflow::dem
