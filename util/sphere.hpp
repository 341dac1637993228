#pragma once
// Sphere volume, written once for dem/, method/ and tasks/. Two forms, because callers hold a
// radius or a diameter and each form's rounding is part of results already stored (goldens, task
// keys' cached results): they agree to the last bit or two, not bit for bit.
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

}  // namespace millflow::util
