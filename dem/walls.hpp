#pragma once
// Walls: analytic surfaces that particles touch. Geometry is in dem/wall_geometry.hpp (pure
// functions); this file holds the walls' motion and what is measured on them.
#include <string>
#include <variant>
#include <vector>

#include "dem/material.hpp"
#include "dem/vec.hpp"
#include "dem/wall_geometry.hpp"

namespace millflow::dem {

// An infinite plane. It translates with `velocity` (any direction: a tangential component
// shears the particles). With `servo_mobility` > 0 its normal velocity is instead set every step
// so that the force it exerts on the particles along its normal approaches `servo_target_force`:
//   v_normal = clamp(servo_mobility * (servo_target - measured normal force), +-servo_max_speed)
// The clamp keeps a wall that meets a stiff bed from being thrown back at a huge speed.
struct PlaneWall {
  Vec3 origin = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();  // unit, points towards the particles
  Vec3 velocity = Vec3::Zero();
  double servo_target_force = 0.0;  // N
  double servo_mobility = 0.0;      // m/(N s); 0 = velocity-driven
  double servo_max_speed = 0.0;     // m/s, > 0 when servo_mobility > 0
};

// A rotating cylindrical mill shell with lifters (and optional end walls), axis +z through the
// origin, turning counter-clockwise seen from +z at `angular_velocity` rad/s.
struct MillWall {
  MillShell shell;
  double angular_velocity = 0.0;  // rad/s
  double angle = 0.0;             // current rotation, rad
};

struct Wall {
  std::string name;
  MaterialId material = 0;
  std::variant<PlaneWall, MillWall> shape;
};

// What the particles do to a wall, measured every step.
struct WallLoad {
  Vec3 force = Vec3::Zero();   // total contact force on the wall, N
  Vec3 torque = Vec3::Zero();  // about the origin, N m
  double power = 0.0;          // rate of work done BY the wall on the particles, W
  double work = 0.0;           // cumulative work done by the wall on the particles, J
};

// Throws std::invalid_argument naming the wall and the bad value.
void validate_wall(const Wall& wall);

// What contact queries need of a wall where it is now, worked out once per step: a mill's pose.
struct WallPose {
  MillPose mill;  // for a mill wall
};
WallPose wall_pose(const Wall& wall);

// Appends the contacts of a sphere with the wall; `pose` is wall_pose(wall).
void wall_contacts(const Wall& wall, const WallPose& pose, const Vec3& centre, double radius,
                   std::vector<SurfaceContact>& out);

// True when the sphere certainly touches nothing of the wall, by a test cheaper than
// wall_contacts: a mill's interior (most of a charge). False says nothing (planes: always false,
// their own test is as cheap).
inline bool sphere_certainly_clear_of(const Wall& wall, const Vec3& centre, double radius) {
  const MillWall* mill = std::get_if<MillWall>(&wall.shape);
  return mill != nullptr && sphere_in_mill_interior(mill->shell, centre, radius);
}

// Velocity of the wall's surface at a point on it.
Vec3 wall_surface_velocity(const Wall& wall, const Vec3& point);

// Rate of work the wall does on the particles when it exerts minus `load` on them while moving
// with its current velocity, W.
double wall_power(const Wall& wall, const WallLoad& load);

// Moves the wall by one time step.
void advance_wall(Wall& wall, double dt);

// Applies the servo control (if any) from the load measured this step.
void control_wall(Wall& wall, const WallLoad& load);

}  // namespace millflow::dem
