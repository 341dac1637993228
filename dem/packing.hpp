#pragma once
// Initial placement of spheres without overlaps: a close-packed lattice filled from the bottom up,
// which gravity then settles into a packed bed.
#include <span>
#include <vector>

#include "dem/rng.hpp"
#include "dem/vec.hpp"
#include "dem/wall_geometry.hpp"

namespace millflow::dem {

// Sites of a close-packed lattice with nearest-neighbour distance at least `spacing`, inside the
// mill (clear of the shell, the lifters and the end walls by `radius`, with the shell at angle
// `theta`), lowest first (along -gravity direction `down`). Layers normal to the axis are
// triangular lattices of spacing `spacing` in x-y, stacked along z at least spacing sqrt(2/3)
// apart, each layer shifted from its neighbours onto the hollows of theirs (stackings A B A B ...,
// ending in C for an odd count across a periodic boundary): solid fraction 0.74 (2 radius /
// spacing)^3 in the bulk, against 0.52 for a cubic lattice, so a small mill can hold J = 0.5.
// With no end walls the layers span z in [0, mill.length) evenly and stay apart across the
// periodic boundary. Sites are jittered by up to `jitter` x (spacing - 2 radius) / 2 so the
// packing is not a perfect crystal; they never overlap. Throws std::invalid_argument when
// spacing < 2 radius, or when a periodic mill is shorter than `spacing`.
std::vector<Vec3> mill_lattice_sites(const MillShell& mill, double theta, double radius,
                                     double spacing, const Vec3& down, double jitter, Rng& rng);

// Number of balls of diameter d whose bed, at packing fraction `packing`, fills a fraction
// `fill` of the mill's free volume: the charge filling level J of comminution practice.
std::size_t balls_for_fill(const MillShell& mill, double fill, double diameter,
                           double packing = 0.6);

}  // namespace millflow::dem
