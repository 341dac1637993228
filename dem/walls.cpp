#include "dem/walls.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace millflow::dem {
namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};

}  // namespace

void validate_wall(const Wall& wall) {
  std::visit(
      Overloaded{
          [&](const PlaneWall& plane) {
            if (std::abs(plane.normal.norm() - 1.0) > 1e-9) {
              throw std::invalid_argument(
                  fmt::format("wall '{}': normal has length {}; give a unit vector", wall.name,
                              plane.normal.norm()));
            }
            if (!(plane.servo_mobility >= 0.0)) {
              throw std::invalid_argument(fmt::format("wall '{}': servo mobility = {} must be >= 0",
                                                      wall.name, plane.servo_mobility));
            }
            if (plane.servo_mobility > 0.0 && !(plane.servo_max_speed > 0.0)) {
              throw std::invalid_argument(fmt::format(
                  "wall '{}': servo max speed = {} m/s must be > 0 for a stress-controlled wall",
                  wall.name, plane.servo_max_speed));
            }
          },
          [&](const MillWall& mill) {
            try {
              validate(mill.shell);
            } catch (const std::invalid_argument& e) {
              throw std::invalid_argument(fmt::format("wall '{}': {}", wall.name, e.what()));
            }
            if (!std::isfinite(mill.angular_velocity)) {
              throw std::invalid_argument(
                  fmt::format("wall '{}': angular velocity is not finite", wall.name));
            }
          }},
      wall.shape);
}

WallPose wall_pose(const Wall& wall) {
  WallPose pose;
  if (const auto* mill = std::get_if<MillWall>(&wall.shape))
    pose.mill = mill_pose(mill->shell, mill->angle);
  return pose;
}

void wall_contacts(const Wall& wall, const WallPose& pose, const Vec3& centre, double radius,
                   std::vector<SurfaceContact>& out) {
  std::visit(
      Overloaded{[&](const PlaneWall& plane) {
                   if (auto c = sphere_plane_contact(centre, radius, plane.origin, plane.normal)) {
                     out.push_back(*c);
                   }
                 },
                 [&](const MillWall& mill) {
                   sphere_mill_contacts(mill.shell, pose.mill, centre, radius, out);
                 }},
      wall.shape);
}

Vec3 wall_surface_velocity(const Wall& wall, const Vec3& point) {
  return std::visit(Overloaded{[&](const PlaneWall& plane) -> Vec3 { return plane.velocity; },
                               [&](const MillWall& mill) -> Vec3 {
                                 return Vec3(-mill.angular_velocity * point.y(),
                                             mill.angular_velocity * point.x(), 0.0);
                               }},
                    wall.shape);
}

double wall_power(const Wall& wall, const WallLoad& load) {
  return std::visit(
      Overloaded{[&](const PlaneWall& plane) { return -load.force.dot(plane.velocity); },
                 [&](const MillWall& mill) { return -load.torque.z() * mill.angular_velocity; }},
      wall.shape);
}

void advance_wall(Wall& wall, double dt) {
  std::visit(Overloaded{[&](PlaneWall& plane) { plane.origin += plane.velocity * dt; },
                        [&](MillWall& mill) { mill.angle += mill.angular_velocity * dt; }},
             wall.shape);
}

void control_wall(Wall& wall, const WallLoad& load) {
  if (auto* plane = std::get_if<PlaneWall>(&wall.shape); plane && plane->servo_mobility > 0.0) {
    // The wall pushes the particles with -load.force; its component along the normal is the
    // measured force the servo compares with its target.
    const double pushing = -load.force.dot(plane->normal);
    const double normal_speed =
        std::clamp(plane->servo_mobility * (plane->servo_target_force - pushing),
                   -plane->servo_max_speed, plane->servo_max_speed);
    plane->velocity += (normal_speed - plane->velocity.dot(plane->normal)) * plane->normal;
  }
}

}  // namespace millflow::dem
