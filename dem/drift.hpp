#pragma once
// The per-particle passes of velocity Verlet over a range of particles (System::step): the first
// half kick and the drift, with the two maxima the neighbour list needs, and the closing half
// kick. Passes over seven arrays of 3-vectors per particle, a third of the step of a sparse cell
// (docs/benchmarks.md, "The drift and the kick on four lanes"): where the build has AVX2, four
// particles at a time, with the same IEEE operations in the same order as one at a time, so the
// bits do not depend on the instruction set.
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "dem/domain.hpp"
#include "dem/vec.hpp"

namespace millflow::dem {

struct KinematicGroup;

// What the drift finds, per particle at most: the squared displacement since the neighbour list's
// build and the squared speed against the shear flow. Exact maxima, so any split of the particles
// gives the same answers.
struct DriftMaxima {
  double moved_sq = 0.0;
  double peculiar_speed_sq = 0.0;
};

// What a particle's force and torque hold, one byte per particle (System::particle_force_state_).
// The contact law marks the particles with a pair in force; the force gather then sums their
// forces and marks them summed, and writes the weight over a summed particle's force once its
// pairs are out of force. A particle on its weight alone keeps it, unwritten, step after step: in
// the campaign's fine cells most particles touch nothing (docs/benchmarks.md, "Particles that
// touch nothing are passed by").
enum ParticleForceState : std::uint8_t {
  kWeightOnly = 0,   // force is exactly m g, torque zero
  kPairInForce = 1,  // a pair in force this step: the gather sums its force
  kForceSummed = 2,  // force and torque hold a sum (or are not known: written by the next gather)
};

// Whether the N particles whose states start at `state` are all kWeightOnly: one load of a word.
template <std::size_t N>
inline bool all_weight_only(const std::uint8_t* state) {
  static_assert(N == 4 || N == 8);
  std::conditional_t<N == 4, std::uint32_t, std::uint64_t> word;
  std::memcpy(&word, state, N);
  return word == 0;
}

// The particle arrays the pass reads and writes (System's structure of arrays).
struct DriftArrays {
  Vec3* position = nullptr;
  Vec3* velocity = nullptr;
  Vec3* angular_velocity = nullptr;
  Vec3* predicted_velocity = nullptr;          // at the end of the step, for the dashpots
  Vec3* predicted_angular_velocity = nullptr;  // the same
  const Vec3* force = nullptr;
  const Vec3* torque = nullptr;
  const double* inv_mass = nullptr;
  const double* inv_inertia = nullptr;
  // Per particle its kinematic group (kFreeParticle for none), whose members move with its
  // velocity (groups[group - 1]); nullptr when the system has no group.
  const std::uint32_t* group = nullptr;
  const KinematicGroup* groups = nullptr;
  // Where the neighbour list was built, per particle; nullptr: no displacement tracked.
  const Vec3* reference_position = nullptr;
  // Per particle its ParticleForceState, given only where gravity is zero: a kWeightOnly particle
  // then has no force and no torque, and the kicks on lanes pass four such by (their velocities
  // stay what a kick by zero leaves them, to the bit but for a zero's sign).
  const std::uint8_t* force_state = nullptr;
};

struct DriftParameters {
  double half_dt = 0.0;
  double dt = 0.0;
  // The shear flow the speeds are taken against: its velocity is flow_per_height x (the position
  // along gradient_axis - flow_centre).
  int gradient_axis = 1;
  double flow_centre = 0.0;
  Vec3 flow_per_height = Vec3::Zero();
  // Per axis, the largest displacement that needs no periodic image (System::no_image_limits),
  // and the square of the smallest of them.
  std::array<double, 3> no_image_limit{};
  double image_test_sq = 0.0;
};

// Kicks the velocities by half a step of the forces and torques, moves the particles a step
// (wrapped into the box), predicts the velocities at the step's end, for particles [begin, end);
// returns the maxima of `running` and those of the range.
DriftMaxima drift_particles(const DriftArrays& arrays, const DriftParameters& parameters,
                            const Domain& domain, std::size_t begin, std::size_t end,
                            DriftMaxima running);

// The step's closing half kick over particles [begin, end): velocity and angular velocity from
// force and torque (the other arrays are not read but force_state), on four lanes where the build
// has AVX2.
void kick_particles(const DriftArrays& arrays, double half_dt, std::size_t begin, std::size_t end);
void kick_particles_one_at_a_time(const DriftArrays& arrays, double half_dt, std::size_t begin,
                                  std::size_t end);

// Whether drift_particles and kick_particles run on four lanes in this build (the DEM library
// built for AVX2).
bool drift_uses_lanes();

// The same one particle at a time: what the four lanes must match bit for bit (tests).
DriftMaxima drift_particles_one_at_a_time(const DriftArrays& arrays,
                                          const DriftParameters& parameters, const Domain& domain,
                                          std::size_t begin, std::size_t end, DriftMaxima running);

}  // namespace millflow::dem
