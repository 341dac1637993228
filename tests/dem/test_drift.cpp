// The drift and the closing kick on four lanes against the same one particle at a time: the same
// bits in every array and the same maxima, whatever the range's length, with particles that leave
// the box through every face (Lees-Edwards included), displacements that need a periodic image, a
// NaN, and particles without force that the lanes pass by.
#include "dem/drift.hpp"
#include "tests/dem/same_bits.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace millflow::dem {
namespace {

using testing::same_bits;

// A Lees-Edwards box of 0.1 m with particles of the cells' scale: 5 mm, 1 m/s, dt 1e-5 s.
struct Particles {
  std::vector<Vec3> position, velocity, angular_velocity, predicted_velocity,
      predicted_angular_velocity, force, torque, reference;
  std::vector<double> inv_mass, inv_inertia;

  explicit Particles(std::size_t n, std::uint64_t seed, const Domain& domain) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0), fraction(0.0, 1.0);
    const auto random_vector = [&](double scale) {
      return Vec3(scale * unit(rng), scale * unit(rng), scale * unit(rng));
    };
    for (std::size_t p = 0; p < n; ++p) {
      Vec3 x;
      for (int a = 0; a < 3; ++a) x[a] = domain.lo[a] + fraction(rng) * domain.length()[a];
      // One in 23 sits within a step of a face, to leave the box in the drift.
      if (p % 23 == 3)
        x[p % 3] = (p % 2 == 0 ? domain.hi[p % 3] : domain.lo[p % 3]) - 1e-6 * unit(rng);
      position.push_back(x);
      velocity.push_back(random_vector(1.0));
      angular_velocity.push_back(random_vector(100.0));
      force.push_back(random_vector(50.0));
      torque.push_back(random_vector(0.01));
      inv_mass.push_back(1.0 / (1e-3 * (1.0 + fraction(rng))));
      inv_inertia.push_back(1.0 / (1e-8 * (1.0 + fraction(rng))));
      // One in 29 moved half a box since the list's build: its displacement takes an image.
      reference.push_back(p % 29 == 2 ? Vec3(x[0], x[1] - 0.5 * domain.length()[1], x[2])
                                      : x + random_vector(1e-4));
    }
    predicted_velocity.assign(n, Vec3::Zero());
    predicted_angular_velocity.assign(n, Vec3::Zero());
  }

  DriftArrays arrays(bool track) {
    return {.position = position.data(),
            .velocity = velocity.data(),
            .angular_velocity = angular_velocity.data(),
            .predicted_velocity = predicted_velocity.data(),
            .predicted_angular_velocity = predicted_angular_velocity.data(),
            .force = force.data(),
            .torque = torque.data(),
            .inv_mass = inv_mass.data(),
            .inv_inertia = inv_inertia.data(),
            .reference_position = track ? reference.data() : nullptr};
  }
};

Domain sheared_box() {
  Domain d;
  d.lo = Vec3(-0.05, 0.0, 0.02);
  d.hi = Vec3(0.05, 0.1, 0.12);
  d.periodic = {true, true, true};
  d.lees_edwards = LeesEdwards{true, 0, 1, 0.037, 0.2};
  return d;
}

DriftParameters parameters_for(const Domain& d) {
  DriftParameters prm;
  prm.dt = 1e-5;
  prm.half_dt = 0.5 * prm.dt;
  prm.gradient_axis = 1;
  prm.flow_centre = 0.5 * (d.lo[1] + d.hi[1]);
  prm.flow_per_height = Vec3(d.lees_edwards.velocity / d.length()[1], 0.0, 0.0);
  for (int a = 0; a < 3; ++a) prm.no_image_limit[a] = 0.5 * d.length()[a];
  prm.image_test_sq = 0.05 * 0.05;
  return prm;
}

// Every array the drift writes, the same to the bit.
void expect_same_bits(const Particles& got, const Particles& want) {
  EXPECT_TRUE(same_bits(got.position, want.position));
  EXPECT_TRUE(same_bits(got.velocity, want.velocity));
  EXPECT_TRUE(same_bits(got.angular_velocity, want.angular_velocity));
  EXPECT_TRUE(same_bits(got.predicted_velocity, want.predicted_velocity));
  EXPECT_TRUE(same_bits(got.predicted_angular_velocity, want.predicted_angular_velocity));
}

// Drifts [begin, end) in chunks of `chunk` particles both ways and compares every chunk's maxima
// (one particle's squared norm decides a chunk's) and then every array.
void expect_lanes_match(Particles lanes, Particles one_at_a_time, const Domain& domain,
                        std::size_t begin, std::size_t end, std::size_t chunk, bool track) {
  const DriftParameters prm = parameters_for(domain);
  const DriftMaxima before{1e-12, 1e-9};
  for (std::size_t first = begin; first < end; first += chunk) {
    const std::size_t last = std::min(first + chunk, end);
    const DriftMaxima got = drift_particles(lanes.arrays(track), prm, domain, first, last, before);
    const DriftMaxima want = drift_particles_one_at_a_time(one_at_a_time.arrays(track), prm, domain,
                                                           first, last, before);
    EXPECT_TRUE(same_bits(got.moved_sq, want.moved_sq))
        << "particles " << first << "-" << last << ": " << got.moved_sq << " " << want.moved_sq;
    EXPECT_TRUE(same_bits(got.peculiar_speed_sq, want.peculiar_speed_sq))
        << "particles " << first << "-" << last << ": " << got.peculiar_speed_sq << " "
        << want.peculiar_speed_sq;
  }
  expect_same_bits(lanes, one_at_a_time);
}

TEST(Drift, FourLanesGiveTheBitsOfOneParticleAtATime) {
  if (!drift_uses_lanes()) GTEST_SKIP() << "the DEM library is built without AVX2: one path only";
  const Domain domain = sheared_box();
  for (const std::size_t n : {1u, 3u, 4u, 7u, 64u, 1001u}) {
    const Particles particles(n, 40 + n, domain);
    for (const bool track : {true, false}) {
      SCOPED_TRACE(::testing::Message() << n << " particles, tracking " << track);
      for (const std::size_t chunk : {std::size_t{4}, std::size_t{5}, n}) {
        expect_lanes_match(particles, particles, domain, 0, n, chunk, track);
        if (n > 2) expect_lanes_match(particles, particles, domain, 1, n - 1, chunk, track);
      }
    }
  }
}

TEST(Drift, ParticlesLeavingTheBoxAreWrappedOnLanesAsOneAtATime) {
  if (!drift_uses_lanes()) GTEST_SKIP() << "the DEM library is built without AVX2: one path only";
  const Domain domain = sheared_box();
  Particles particles(400, 7, domain);
  // Every particle a step's travel from a face: most blocks take the path one at a time.
  for (std::size_t p = 0; p < 400; ++p) {
    const int axis = static_cast<int>(p % 3);
    particles.position[p][axis] = (p % 2 == 0 ? domain.hi[axis] : domain.lo[axis]);
    particles.velocity[p][axis] = p % 2 == 0 ? 0.5 : -0.5;
  }
  expect_lanes_match(particles, particles, domain, 0, 400, 4, true);
}

TEST(Drift, ANonFiniteParticleTakesThePathOneAtATime) {
  if (!drift_uses_lanes()) GTEST_SKIP() << "the DEM library is built without AVX2: one path only";
  const Domain domain = sheared_box();
  Particles particles(16, 11, domain);
  particles.force[5][1] = std::numeric_limits<double>::quiet_NaN();
  particles.velocity[10][0] = std::numeric_limits<double>::infinity();
  // NaN compares unequal to itself: the arrays are compared as bytes, where NaN matches NaN.
  expect_lanes_match(particles, particles, domain, 0, 16, 4, true);
}

TEST(Drift, TheClosingKickOnLanesGivesTheBitsOfOneParticleAtATime) {
  if (!drift_uses_lanes()) GTEST_SKIP() << "the DEM library is built without AVX2: one path only";
  const Domain domain = sheared_box();
  for (const std::size_t n : {1u, 6u, 259u}) {
    Particles lanes(n, 90 + n, domain), one_at_a_time(n, 90 + n, domain);
    for (const std::size_t begin : {std::size_t{0}, std::size_t{1}}) {
      kick_particles(lanes.arrays(true), 5e-6, begin, n);
      kick_particles_one_at_a_time(one_at_a_time.arrays(true), 5e-6, begin, n);
    }
    EXPECT_TRUE(same_bits(lanes.velocity, one_at_a_time.velocity)) << n << " particles";
    EXPECT_TRUE(same_bits(lanes.angular_velocity, one_at_a_time.angular_velocity))
        << n << " particles";
  }
}

// Marks particles as on their weight alone (no gravity: no force, no torque), in runs of 1 to 9
// so that blocks of four are wholly, partly and not at all marked, whatever the range's start.
std::vector<std::uint8_t> weight_only_runs(Particles& particles) {
  const std::size_t n = particles.position.size();
  std::vector<std::uint8_t> state(n, kForceSummed);
  std::size_t p = 0;
  for (std::size_t run = 1; p < n; run = run % 9 + 1) {
    for (std::size_t q = p; q < std::min(p + run, n); ++q) {
      state[q] = kWeightOnly;
      particles.force[q] = Vec3::Zero();
      particles.torque[q] = Vec3::Zero();
    }
    p += 2 * run;  // then as many not marked
  }
  return state;
}

TEST(Drift, ParticlesWithoutForcePassedByOnLanesKeepTheBitsOfOneParticleAtATime) {
  if (!drift_uses_lanes()) GTEST_SKIP() << "the DEM library is built without AVX2: one path only";
  const Domain domain = sheared_box();
  const DriftParameters prm = parameters_for(domain);
  for (const std::size_t n : {5u, 64u, 1001u}) {
    SCOPED_TRACE(::testing::Message() << n << " particles");
    Particles marked(n, 60 + n, domain);
    const std::vector<std::uint8_t> state = weight_only_runs(marked);
    Particles one_at_a_time = marked;
    for (const std::size_t begin : {std::size_t{0}, std::size_t{1}, std::size_t{2}}) {
      DriftArrays lanes = marked.arrays(true);
      lanes.force_state = state.data();
      drift_particles(lanes, prm, domain, begin, n, DriftMaxima{});
      kick_particles(lanes, prm.half_dt, begin, n);
      drift_particles_one_at_a_time(one_at_a_time.arrays(true), prm, domain, begin, n,
                                    DriftMaxima{});
      kick_particles_one_at_a_time(one_at_a_time.arrays(true), prm.half_dt, begin, n);
    }
    expect_same_bits(marked, one_at_a_time);
  }
}

// What the marks mean: a particle marked as on its weight is not kicked, so a mark on a particle
// with a force would be a wrong answer (this test fails if the marks were ignored, or if the
// lanes passed by a block with one particle unmarked).
TEST(Drift, TheKicksOnLanesPassByOnlyBlocksOfFourMarkedParticles) {
  if (!drift_uses_lanes()) GTEST_SKIP() << "the DEM library is built without AVX2: one path only";
  const Domain domain = sheared_box();
  Particles particles(12, 3, domain);  // every force and torque non-zero
  const Particles before = particles;
  std::vector<std::uint8_t> state(12, kWeightOnly);
  state[6] = kForceSummed;  // the second block of four
  DriftArrays arrays = particles.arrays(true);
  arrays.force_state = state.data();
  kick_particles(arrays, 5e-6, 0, 12);
  for (std::size_t p = 0; p < 12; ++p) {
    const bool kicked = p >= 4 && p < 8;
    EXPECT_EQ(particles.velocity[p] != before.velocity[p], kicked) << "particle " << p;
    EXPECT_EQ(particles.angular_velocity[p] != before.angular_velocity[p], kicked)
        << "particle " << p;
  }
}

}  // namespace
}  // namespace millflow::dem
