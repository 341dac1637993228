#pragma once
// Shared by the shear cell's source files (dem/shear_cell*.cpp) and nothing else: the cell's
// geometry derived from its setup, and the constants more than one of its jobs uses.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <string>

#include "dem/shear_cell.hpp"
#include "util/sphere.hpp"

namespace millflow::dem::shear_cell_detail {

using util::sphere_volume_of_diameter;

// Solid fraction at which the walled cell is first filled: random sequential addition jams near
// 0.38, so particles go into a taller, looser cell that the servo then compresses.
inline constexpr double kPlacementSolidFraction = 0.3;
// Wall balls sit on a square lattice of this spacing (in diameters), each raised or lowered by a
// random amount up to kWallBallJitter diameters: a random bumpy surface that does not template a
// crystal in the bed. The lattice alone is nearly flat (a ball resting on four wall balls 0.5 d
// apart sits only 0.065 d lower than on one), so the jitter makes the roughness: at 0.25 d the
// walls of the 8 x 10 x 8 cell at 10 1/s slipped by 1-3 m/s of their 5.5 m/s and carried the bulk
// at 0.6 of the nominal rate after 10 strains; at 0.5 d by 0.4-1.7 m/s, the bulk at 0.8 of nominal
// (docs/cell_validation.md, table 4 a fifth time). 0.4 d, not 0.5: lattice neighbours then lie at
// most sqrt(0.5^2 + 0.8^2) = 0.94 d apart and always overlap, so the layer stays one connected
// heap of balls without a hole that powder could leak through.
inline constexpr double kWallBallSpacing = 0.5;
inline constexpr double kWallBallJitter = 0.4;
// First guess of bulk / nominal shear rate (rough walls slip: with the walls above the bulk of
// the 8 x 10 x 8 cell at 10 1/s ran at 0.65-0.69 of nominal from its sixth strain on at a fixed
// wall speed, docs/cell_validation.md, table 4 a fifth time; 0.5 with the flatter walls before).
inline constexpr double kInitialBulkFraction = 0.65;

inline void require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument("shear cell: " + message);
}

inline double nominal_gap(const ShearCellSetup& s) {
  return s.size_diameters.y() * s.media_diameter;
}
inline double cell_area(const ShearCellSetup& s) {
  return s.size_diameters.x() * s.size_diameters.z() * s.media_diameter * s.media_diameter;
}
inline double powder_diameter(const ShearCellSetup& s) {
  return s.powder_diameter_ratio * s.media_diameter;
}

// The mean height of a wall layer's ball centres: the wall balls are the system's first
// particles, the bottom layer's `count` then the top layer's (their indices never change).
inline double wall_layer_plane(const System& system, std::size_t first, std::size_t count) {
  double y = 0.0;
  for (std::size_t p = first; p < first + count; ++p) y += system.positions()[p].y();
  return y / static_cast<double>(count);
}

// Wall balls along one side of length `length` of a wall layer: kWallBallSpacing apart or closer.
inline std::size_t wall_layer_columns(double length, double media_diameter) {
  return static_cast<std::size_t>(std::ceil(length / (kWallBallSpacing * media_diameter)));
}

// Height of the particle bed when it is filled at kPlacementSolidFraction.
// Solid fraction of media and powder together in the nominal gap.
inline double nominal_solid_fraction(const ShearCellSetup& s) {
  return s.media_solid_fraction +
         s.powder_load * (1.0 - s.media_solid_fraction) * s.powder_bed_solid_fraction;
}

inline double placement_height(const ShearCellSetup& s) {
  return std::max(1.0, nominal_solid_fraction(s) / kPlacementSolidFraction) * nominal_gap(s);
}

// Height between the wall ball centre planes at which the walled cell is filled.
inline double placement_gap(const ShearCellSetup& s) {
  return (1.0 + 2.0 * kWallBallJitter) * s.media_diameter + placement_height(s);
}

// The cell's material table: media, powder and the wall balls' material, with the setup's
// interactions (dem/shear_cell.cpp).
MaterialTable make_materials(const ShearCellSetup& s);

}  // namespace millflow::dem::shear_cell_detail
