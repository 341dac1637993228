#pragma once
// Initial placement of spheres without overlaps: a loose lattice filled from the bottom up,
// which gravity then settles into a packed bed.
#include <span>
#include <vector>

#include "dem/rng.hpp"
#include "dem/vec.hpp"
#include "dem/wall_geometry.hpp"

namespace millflow::dem {

// Sites of a cubic lattice of spacing `spacing` inside the mill (clear of the shell, the lifters
// and the end walls by `radius`, with the shell at angle `theta`), lowest first (along -gravity
// direction `down`). With `axial_length` > 0 and no end walls the lattice spans z in
// [0, axial_length). Sites are jittered by up to `jitter` x (spacing - 2 radius) / 2 so the
// packing is not crystalline; they never overlap.
std::vector<Vec3> mill_lattice_sites(const MillShell& mill, double theta, double radius, double spacing,
                                     const Vec3& down, double jitter, Rng& rng);

// Number of balls of diameter d whose bed, at packing fraction `packing`, fills a fraction
// `fill` of the mill's free volume: the charge filling level J of comminution practice.
std::size_t balls_for_fill(const MillShell& mill, double fill, double diameter, double packing = 0.6);

}  // namespace millflow::dem
