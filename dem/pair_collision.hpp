#pragma once
// Two particles meeting once, alone: a probe of the contact law for checks against analytic
// results and other codes. bench_cell_physics prints it for a cell's pair types and
// bench/lammps/in.restitution_pair runs the same collisions in LAMMPS; a physics test pins it.
#include "dem/material.hpp"

namespace millflow::dem {

// Particle a at the origin, b just touching it along +x; they meet at 1 m/s along the line of
// centres and `tangential_speed` m/s across it (along y), without spin.
struct PairCollision {
  double radius_a = 0.0, radius_b = 0.0;  // m
  MaterialId material_a = 0, material_b = 0;
  double tangential_speed = 0.0;  // m/s
  double time_step = 0.0;         // s
};

// Once the contact is over, over the same before it: the relative velocity of b to a along the
// line of centres (the restitution the integrator gives the pair), and that of their contact
// points across it (negative where the contact's spring turned the motion back; 0 for a head-on
// collision).
struct Rebound {
  double normal = 0.0;
  double tangential = 0.0;
};

// Throws std::runtime_error if the contact has not ended within a million steps.
Rebound pair_rebound(const MaterialTable& materials, const PairCollision& collision);

}  // namespace millflow::dem
