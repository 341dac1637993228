#pragma once
// A ball charge in a rotating mill slice, built from the quantities mill engineers use: mill and
// ball diameters, filling J, and speed as a fraction of critical speed.
#include <cstdint>

#include "dem/system.hpp"

namespace millflow::dem {

// Critical speed, rad/s: the ball centre on the shell at R - r just stops touching it at the top,
// omega_c^2 (R - r) = g, i.e. N_c = 42.3 / sqrt(D - d) rpm with D, d in metres and g = 9.81.
double critical_speed(double mill_diameter, double ball_diameter, double gravity = 9.81);

struct MillSetup {
  MillShell shell;
  double ball_diameter = 0.04;
  Material media{"steel", 7800.0};
  Material liner{"liner", 7800.0};
  InteractionSpec ball_ball;
  InteractionSpec ball_liner;
  double fill = 0.3;            // J: bed volume at rest (packing `packing`) / free mill volume
  double packing = 0.6;         // solid fraction of the bed at rest
  double speed_fraction = 0.75; // of critical speed
  double gravity = 9.81;        // along -y
  std::uint64_t seed = 1;
};

// Throws std::invalid_argument naming the bad value (fill outside (0, 0.9], non-positive
// diameter, balls too big for the mill, ...).
void validate(const MillSetup& setup);

// Balls on a jittered lattice, lowest first, the shell at rest (angular velocity 0): settle the
// bed with settle_charge(), then set_mill_speed() to run. Wall 0 is the shell.
System build_mill(const MillSetup& setup);

// Steps until the charge's kinetic energy per ball falls below `kinetic_per_ball` J or
// `max_time` s of simulated time pass. Returns the simulated time spent.
double settle_charge(System& system, double max_time, double kinetic_per_ball);

void set_mill_speed(System& system, double angular_velocity);

}  // namespace millflow::dem
