#pragma once
// Sphere volume and mass, written once for dem/, method/ and tasks/. Two volume forms, because
// callers hold a radius or a diameter and each form's rounding is part of results already stored
// (goldens, task keys' cached results): they agree to the last bit or two, not bit for bit.
#include <numbers>

namespace millflow::util {

// 4/3 pi r^3.
inline double sphere_volume_of_radius(double radius) {
  return 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
}

// pi/6 d^3.
inline double sphere_volume_of_diameter(double diameter) {
  return std::numbers::pi / 6.0 * diameter * diameter * diameter;
}

// rho pi d^3 / 6: the reference masses of the collision-time stiffness (macro balls, a shear
// cell's media and powder), in the order their stored results were computed in.
inline double sphere_mass(double density, double diameter) {
  return density * std::numbers::pi * diameter * diameter * diameter / 6.0;
}

}  // namespace millflow::util
