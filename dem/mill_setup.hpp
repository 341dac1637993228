#pragma once
// A ball charge in a rotating mill slice, built from the quantities mill engineers use: mill and
// ball diameters, filling J, and speed as a fraction of critical speed.
#include <cstdint>
#include <vector>

#include "dem/system.hpp"

namespace millflow::dem {

// Critical speed, rad/s: the ball centre on the shell at R - r just stops touching it at the top,
// omega_c^2 (R - r) = g, i.e. N_c = 42.3 / sqrt(D - d) rpm with D, d in metres and g = 9.81.
double critical_speed(double mill_diameter, double ball_diameter, double gravity = 9.81);

// One size class of a ball charge: its diameter and its share of the charge's mass.
struct BallSizeClass {
  double diameter = 0.0;       // m
  double mass_fraction = 1.0;  // > 0; the fractions of a charge are normalised to sum to 1
};

struct MillSetup {
  MillShell shell;
  double ball_diameter = 0.04;
  // Several ball sizes; when empty, every ball has `ball_diameter`.
  std::vector<BallSizeClass> size_distribution;
  Material media{"steel", 7800.0};
  Material liner{"liner", 7800.0};
  InteractionSpec ball_ball;
  InteractionSpec ball_liner;
  double fill = 0.3;             // J: bed volume at rest (packing `packing`) / free mill volume
  double packing = 0.6;          // solid fraction of the bed at rest
  double speed_fraction = 0.75;  // of critical speed
  double gravity = 9.81;         // along -y
  std::uint64_t seed = 1;
};

// Throws std::invalid_argument naming the bad value (fill outside (0, 0.9], non-positive
// diameter or mass fraction, balls too big for the mill, ...).
void validate(const MillSetup& setup);

// The charge's size classes with mass fractions normalised to sum to 1 (one class of
// `ball_diameter` when no distribution is given).
std::vector<BallSizeClass> ball_size_classes(const MillSetup& setup);

// Mass-weighted mean ball diameter, sum f_i d_i: the reference size for critical speed and
// for collision times.
double mean_ball_diameter(const MillSetup& setup);

// Mass of a ball of the media's mass-weighted mean diameter, kg: the reference mass of the
// collision-time stiffness.
double reference_ball_mass(const MillSetup& setup);

// Balls per size class: the bed of all classes at packing `packing` fills J of the mill's free
// volume, each class taking its mass fraction of the solid volume (one material: mass fraction =
// volume fraction), rounded to whole balls.
std::vector<std::size_t> balls_per_class(const MillSetup& setup);

// Balls on a jittered close-packed lattice (dem/packing.hpp, spaced 1.1 x the largest size), lowest
// first, sizes shuffled so the classes start mixed; the shell at rest (angular velocity 0): settle
// the bed with settle_charge(), then set_mill_speed() to run. Wall 0 is the shell. When the media
// and liner materials have the same name, the liner's material is named "<name>_liner".
System build_mill(const MillSetup& setup);

// Steps until the charge's kinetic energy per ball falls below `kinetic_per_ball` J or
// `max_time` s of simulated time pass. Returns the simulated time spent.
double settle_charge(System& system, double max_time, double kinetic_per_ball);

void set_mill_speed(System& system, double angular_velocity);

}  // namespace millflow::dem
