// Bad input to the DEM library gets a clear error naming the value, never a silent NaN.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>

#include "dem/system.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

using testing::open_box;
using testing::steel_table;

template <class F>
std::string error_of(F&& action) {
  try {
    action();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

TEST(SystemInput, NegativeRadiusIsRefused) {
  System system(steel_table(0.5, 0.5), open_box(1.0), Vec3::Zero());
  EXPECT_EQ(error_of([&] { system.add_particle({.position = Vec3::Zero(), .radius = -0.01}); }),
            "particle 0: radius = -0.01 m must be > 0");
}

TEST(SystemInput, NanPositionIsRefused) {
  System system(steel_table(0.5, 0.5), open_box(1.0), Vec3::Zero());
  EXPECT_EQ(error_of([&] {
              system.add_particle({.position = Vec3(0, std::nan(""), 0), .radius = 0.01});
            }),
            "particle 0: position or velocity is not finite");
}

TEST(SystemInput, UnknownMaterialIsRefused) {
  System system(steel_table(0.5, 0.5), open_box(1.0), Vec3::Zero());
  EXPECT_EQ(error_of([&] { system.add_particle({.radius = 0.01, .material = 3}); }),
            "particle 0: material id 3 is not defined (1 materials)");
}

TEST(SystemInput, RestitutionOutsideRangeAndNegativeFrictionAreRefused) {
  MaterialTable table;
  const MaterialId steel = table.add({"steel", 7800.0});
  EXPECT_EQ(error_of([&] {
              table.set_interaction(steel, steel,
                                    {.restitution = 1.5, .friction = 0.5, .normal_stiffness = 1e6});
            }),
            "interaction steel-steel: restitution = 1.5 is outside (0, 1]; give the ratio of "
            "rebound to impact normal speed");
  EXPECT_EQ(error_of([&] {
              table.set_interaction(
                  steel, steel, {.restitution = 0.5, .friction = -0.2, .normal_stiffness = 1e6});
            }),
            "interaction steel-steel: friction = -0.2 must be a finite number >= 0");
}

TEST(SystemInput, OverlappingInitialParticlesAreNamed) {
  System system(steel_table(0.5, 0.5), open_box(1.0), Vec3::Zero());
  system.add_particle({.position = Vec3(0, 0, 0), .radius = 0.01});
  system.add_particle({.position = Vec3(0.015, 0, 0), .radius = 0.01});
  EXPECT_EQ(error_of([&] { system.check_overlaps(0.01); }),
            "particles 0 and 1 overlap by 0.005 m (50% of the smaller radius; tolerance 1%); "
            "move them apart or place them on a coarser lattice");
  EXPECT_EQ(error_of([&] { system.check_overlaps(0.6); }), "no error");
}

TEST(SystemInput, TimeStepAboveStabilityLimitIsRefused) {
  System system(steel_table(1.0, 0.5, 1e6), open_box(1.0), Vec3::Zero());
  system.add_particle({.position = Vec3::Zero(), .radius = 0.005});
  // Undamped: limit 2 sqrt(m_eff / k) with m_eff the mass of the lightest particle pair.
  const double limit = system.stable_time_step();
  EXPECT_NEAR(limit, 2.0 * std::sqrt(testing::sphere_mass(0.005) / 2.0 / 1e6), 1e-12);
  const std::string message = error_of([&] { system.set_time_step(2.0 * limit); });
  EXPECT_NE(message.find("is above the stability limit"), std::string::npos) << message;
  EXPECT_EQ(error_of([&] { system.set_time_step(0.5 * limit); }), "no error");
}

// What set_time_step_from_collisions(20) says when t_c / 20 is above the stability limit.
std::string refused_at_20_steps(double t_c, double limit) {
  return fmt::format(
      "time step dt = {:.4g} s is above the stability limit {:.4g} s of the stiffest, lightest "
      "contact; use dt <= {:.4g} s: {:.0f} or more steps per collision of the shortest contact "
      "(t_c = {:.4g} s)",
      t_c / 20.0, limit, limit, std::ceil(t_c / limit), t_c);
}

TEST(SystemInput, ACriticallyDampedContactIsToldHowManyStepsPerCollisionItNeeds) {
  // Restitution near 0: the contact lasts long, but its dashpot limits the step far below t_c /
  // 20. The message gives a count of steps per collision that works.
  System system(steel_table(1e-9, 0.5, 1e6), open_box(1.0), Vec3::Zero());
  system.add_particle({.position = Vec3::Zero(), .radius = 0.005});
  const double t_c = system.min_collision_duration(), limit = system.stable_time_step();
  const double needed = std::ceil(t_c / limit);
  ASSERT_GT(needed, 20.0);
  EXPECT_EQ(error_of([&] { system.set_time_step_from_collisions(20); }),
            refused_at_20_steps(t_c, limit));
  EXPECT_EQ(error_of([&] { system.set_time_step_from_collisions(static_cast<int>(needed)); }),
            "no error");
}

// A contact damped near the critical (restitution 1e-7) that sticks: its tangential spring and
// dashpot act on the contact point, whose effective mass is 2/7 of the pair's (the spheres roll),
// with C_t = C_n / 2, so its tangential oscillator is damped 1.75 times as hard as the normal one
// and bounds the step. A sphere resting on a floor, pushed along it, is refused 20 steps per
// collision (the old limit, the normal oscillator's by a formula for another scheme, allowed them,
// and such cells ran to NaN), and at the steps the message names comes to rest.
TEST(SystemInput, ANearlyCriticalDashpotGetsAStepItsTangentialOscillatorKeepsStable) {
  constexpr double kRadius = 0.005, kStiffness = 1e6, g = 9.81, e = 1e-7;
  const MaterialTable table = steel_table(e, 1e6, kStiffness);
  System system(table, open_box(1.0), Vec3(0, 0, -g));
  system.add_wall({.name = "floor",
                   .material = 0,
                   .shape = PlaneWall{.origin = Vec3::Zero(), .normal = Vec3::UnitZ()}});
  const double m = testing::sphere_mass(kRadius);
  const double v0 = 0.01;
  system.add_particle({.position = Vec3(0, 0, kRadius - m * g / kStiffness),
                       .velocity = Vec3(v0, 0, 0),
                       .radius = kRadius});
  // The lightest pair: two such spheres.
  const PairParams& pair = table.pair(0, 0);
  const double normal = stable_time_step_limit(kStiffness, m / 2.0, pair.damping_ratio);
  const double limit = pair_stable_time_step_limit(pair, m / 2.0);
  EXPECT_LT(limit, 0.75 * normal);  // the tangential oscillator's
  EXPECT_EQ(system.stable_time_step(), limit);
  const double t_c = system.min_collision_duration();
  const double needed = std::ceil(t_c / limit);
  ASSERT_GT(needed, 20.0);
  EXPECT_EQ(error_of([&] { system.set_time_step_from_collisions(20); }),
            refused_at_20_steps(t_c, limit));
  system.set_time_step_from_collisions(static_cast<int>(needed));
  const double start_energy = 0.5 * m * v0 * v0;
  for (int k = 0; k < 40; ++k) {
    system.step(static_cast<std::size_t>(needed));
    const double speed = system.velocities()[0].norm();
    ASSERT_TRUE(std::isfinite(speed)) << "after " << k + 1 << " contact durations";
    EXPECT_LE(0.5 * m * speed * speed, start_energy) << "after " << k + 1 << " contact durations";
  }
}

TEST(SystemInput, MissingInteractionIsNamedWhenDerivingTheTimeStep) {
  MaterialTable table;
  const MaterialId steel = table.add({"steel", 7800.0});
  const MaterialId powder = table.add({"powder", 3100.0});
  table.set_interaction(steel, steel,
                        {.restitution = 0.5, .friction = 0.5, .normal_stiffness = 1e6});
  System system(std::move(table), open_box(1.0), Vec3::Zero());
  system.add_particle({.position = Vec3::Zero(), .radius = 0.005, .material = steel});
  system.add_particle({.position = Vec3(0.1, 0, 0), .radius = 0.001, .material = powder});
  EXPECT_EQ(error_of([&] { system.min_collision_duration(); }),
            "no interaction is defined for steel-powder; add one for that material pair");
}

}  // namespace
}  // namespace millflow::dem
