// The pair pass's 3-vectors (PackedVec3 where the library has AVX2) against Eigen's Vector3d: the
// same bits for every operation the contact law and the pair kernel use, and for the whole law on
// contacts that stick, slide, turn their springs, start without one or cannot hold one.
#include "dem/packed_vec3.hpp"
#include "tests/dem/same_bits.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>

namespace millflow::dem {
namespace {

// The same bits, or NaN on both sides: where two NaNs meet in a sum, which one's sign and payload
// comes out depends on the order in which the compiler puts a commutative addition's operands,
// not on the arithmetic (this test's Eigen, compiled for baseline x86-64, puts some the other way).
bool same_bits(double a, double b) {
  return testing::same_bits(a, b) || (a != a && b != b);
}

bool same_vector(const Vec3& a, const Vec3& b) {
  return same_bits(a[0], b[0]) && same_bits(a[1], b[1]) && same_bits(a[2], b[2]);
}

TEST(PackedVec3, EveryOperationGivesEigensBits) {
  if (!contact_vec3_is_packed()) GTEST_SKIP() << "the library computes contacts on Vec3 itself";
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::array<double, 9> special{0.0, -0.0, 1e-310, -3.5e300, inf, -inf, nan, 1.0, -2.0};
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<std::size_t> scale(0, 18), pick(0, 4 * special.size() - 1);
  // Mostly ordinary values of mixed scales (rounding differs with the order of operations), one
  // in four special.
  const auto value = [&] {
    const std::size_t p = pick(rng);
    return p < special.size() ? special[p]
                              : unit(rng) * std::pow(10.0, static_cast<double>(scale(rng)) - 12.0);
  };
  int compared = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a(value(), value(), value()), b(value(), value(), value());
    const double s = value();
    const ContactVec3Operations packed = contact_vec3_operations(a, b, s);
    const Vec3 sum = a + b, difference = a - b, negated = -a, scaled_before = s * a,
               scaled_after = a * s, divided = a / s, cross = a.cross(b);
    EXPECT_TRUE(same_vector(packed.sum, sum)) << trial;
    EXPECT_TRUE(same_vector(packed.difference, difference)) << trial;
    EXPECT_TRUE(same_vector(packed.negated, negated)) << trial;
    EXPECT_TRUE(same_vector(packed.scaled_before, scaled_before)) << trial;
    EXPECT_TRUE(same_vector(packed.scaled_after, scaled_after)) << trial;
    EXPECT_TRUE(same_vector(packed.divided, divided)) << trial;
    EXPECT_TRUE(same_vector(packed.cross, cross)) << trial;
    EXPECT_TRUE(same_bits(packed.dot, a.dot(b))) << trial;
    EXPECT_TRUE(same_bits(packed.squared_norm, a.squaredNorm())) << trial;
    // Eigen's order, spelled out: what the packed sum reproduces.
    EXPECT_TRUE(same_bits(packed.dot, (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2])) << trial;
    ++compared;
  }
  EXPECT_EQ(compared, 20000);
}

// Contacts of a dense cell's scale: 5-50 mm particles, overlaps of 1e-7 to 1e-4 m, speeds to 2
// m/s, the springs of sticking contacts and of every kind of turn.
TEST(PackedVec3, TheContactLawGivesTheScalarLawsBits) {
  if (!contact_vec3_is_packed()) GTEST_SKIP() << "the library computes contacts on Vec3 itself";
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), fraction(0.0, 1.0);
  const auto random_vector = [&](double scale) {
    return Vec3(scale * unit(rng), scale * unit(rng), scale * unit(rng));
  };
  int sliding = 0, sticking = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    PairParams params;
    params.normal_stiffness = std::pow(10.0, 5.0 + 3.0 * fraction(rng));
    params.tangential_stiffness = (2.0 / 7.0) * params.normal_stiffness;
    params.damping_ratio = 0.2 * fraction(rng);
    params.tangential_damping_ratio = fraction(rng);
    params.friction = trial % 11 == 0 ? 0.0 : fraction(rng);  // some cannot hold a spring
    const double damping_n = params.damping_ratio * std::sqrt(params.normal_stiffness * 1e-3);
    const Vec3 normal = random_vector(1.0).normalized();
    const double overlap = std::pow(10.0, -7.0 + 3.0 * fraction(rng));
    const ContactGeometry geometry{normal, overlap, random_vector(2.0), random_vector(2.0)};
    // Springs: none, in the plane, slightly off it (the series' turn), far off it, along n.
    const Vec3 tangent = (random_vector(1.0) - random_vector(1.0).dot(normal) * normal);
    Vec3 spring;
    switch (trial % 5) {
      case 0:
        spring = Vec3::Zero();
        break;
      case 1:
        spring = 1e-3 * overlap * tangent;
        break;
      case 2:
        spring = 1e-2 * overlap * (tangent + 1e-3 * normal);
        break;
      case 3:
        spring = overlap * (tangent + 0.5 * unit(rng) * normal);
        break;
      default:
        spring = overlap * normal;
        break;
    }
    const double dt = 1e-7 * (1.0 + fraction(rng));
    const ContactResponse scalar =
        linear_spring_dashpot_damped(params, damping_n, geometry, spring, dt);
    const ContactResponse packed =
        contact_law_on_contact_vec3(params, damping_n, geometry, spring, dt);
    EXPECT_TRUE(same_vector(packed.force_on_a, scalar.force_on_a)) << trial;
    EXPECT_TRUE(same_vector(packed.spring, scalar.spring)) << trial;
    EXPECT_TRUE(same_bits(packed.normal_force, scalar.normal_force)) << trial;
    EXPECT_EQ(packed.sliding, scalar.sliding) << trial;
    EXPECT_TRUE(same_bits(packed.dissipated_normal, scalar.dissipated_normal)) << trial;
    EXPECT_TRUE(same_bits(packed.dissipated_tangential, scalar.dissipated_tangential)) << trial;
    EXPECT_TRUE(same_bits(packed.dissipated_friction, scalar.dissipated_friction)) << trial;
    EXPECT_TRUE(same_bits(packed.elastic_energy, scalar.elastic_energy)) << trial;
    (scalar.sliding ? sliding : sticking) += 1;
  }
  // Both sides of the Coulomb limit were compared.
  EXPECT_GT(sliding, 2000);
  EXPECT_GT(sticking, 2000);
}

}  // namespace
}  // namespace millflow::dem
