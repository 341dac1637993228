#pragma once
// Small scenes shared by the DEM tests.
#include <tbb/task_arena.h>

#include "dem/system.hpp"

namespace millflow::dem::testing {

// One material ("steel", 7800 kg/m^3) interacting with itself.
inline MaterialTable steel_table(double restitution, double friction, double normal_stiffness = 1e6) {
  MaterialTable table;
  const MaterialId steel = table.add({"steel", 7800.0});
  table.set_interaction(steel, steel,
                        InteractionSpec{.restitution = restitution, .friction = friction, .normal_stiffness = normal_stiffness});
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
