#pragma once
// Small scenes shared by the DEM tests.
#include <tbb/task_arena.h>

#include "dem/system.hpp"

namespace millflow::dem::testing {

// One material ("steel", 7800 kg/m^3) interacting with itself.
inline MaterialTable steel_table(double restitution, double friction,
                                 double normal_stiffness = 1e6) {
  MaterialTable table;
  const MaterialId steel = table.add({"steel", 7800.0});
  table.set_interaction(
      steel, steel,
      InteractionSpec{
          .restitution = restitution, .friction = friction, .normal_stiffness = normal_stiffness});
  return table;
}

inline Domain open_box(double half_width) {
  Domain d;
  d.lo = Vec3::Constant(-half_width);
  d.hi = Vec3::Constant(half_width);
  return d;
}

inline double sphere_mass(double radius, double density = 7800.0) {
  return density * 4.0 / 3.0 * 3.14159265358979323846 * radius * radius * radius;
}

// Runs `body` with exactly `threads` worker threads.
template <class F>
void with_threads(int threads, F&& body) {
  tbb::task_arena arena(threads);
  arena.execute(body);
}

}  // namespace millflow::dem::testing

#include "dem/mill_setup.hpp"

namespace millflow::dem::testing {

// A 0.2 m mill slice with four lifters and 10 mm steel balls: a few hundred balls, so a physics
// test of a fraction of a revolution runs in seconds. Contacts are soft (t_c = 1 ms), which is
// fine for the invariants tested and keeps dt at 50 us.
inline MillSetup small_mill(double fill, double speed_fraction) {
  MillSetup setup;
  setup.shell = MillShell{
      .radius = 0.1,
      .length = 0.04,
      .lifter_count = 4,
      .lifter = LifterProfile{.height = 0.01, .base_width = 0.012, .face_angle_deg = 10.0},
      .end_walls = false};
  setup.ball_diameter = 0.01;
  const double ball_mass = sphere_mass(0.005);
  const double zeta_ball = damping_ratio_for_restitution(0.5);
  setup.ball_ball = InteractionSpec{
      .restitution = 0.5,
      .friction = 0.5,
      .normal_stiffness = stiffness_for_collision_duration(1e-3, ball_mass / 2, zeta_ball)};
  setup.ball_liner = InteractionSpec{
      .restitution = 0.5,
      .friction = 0.5,
      .normal_stiffness = stiffness_for_collision_duration(1e-3, ball_mass, zeta_ball)};
  setup.fill = fill;
  setup.speed_fraction = speed_fraction;
  return setup;
}

}  // namespace millflow::dem::testing
