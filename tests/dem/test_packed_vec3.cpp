// The pair pass's 3-vectors (PackedVec3 where the library has AVX2) and its four contacts in lanes
// (Vec3Lanes) against Eigen's Vector3d: the same bits for every operation the contact law and the
// pair kernel use, and for the whole law on contacts that stick, slide, turn their springs, start
// without one or cannot hold one.
#include "dem/contact_lanes.hpp"
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

// Mostly ordinary values of mixed scales (rounding differs with the order of operations), one in
// four special: 0, -0, subnormal, huge, infinite, NaN.
class MixedValues {
 public:
  double operator()() {
    const std::size_t p = pick_(rng_);
    return p < kSpecial.size()
               ? kSpecial[p]
               : unit_(rng_) * std::pow(10.0, static_cast<double>(scale_(rng_)) - 12.0);
  }
  Vec3 vector() { return {(*this)(), (*this)(), (*this)()}; }

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  static constexpr std::array<double, 9> kSpecial{
      0.0, -0.0, 1e-310, -3.5e300, kInf, -kInf, std::numeric_limits<double>::quiet_NaN(),
      1.0, -2.0};
  std::mt19937_64 rng_{17};
  std::uniform_real_distribution<double> unit_{-1.0, 1.0};
  std::uniform_int_distribution<std::size_t> scale_{0, 18}, pick_{0, 4 * kSpecial.size() - 1};
};

// What Eigen gives, operation by operation.
void expect_eigens_bits(const ContactVec3Operations& got, const Vec3& a, const Vec3& b, double s,
                        int trial) {
  EXPECT_TRUE(same_vector(got.sum, a + b)) << trial;
  EXPECT_TRUE(same_vector(got.difference, a - b)) << trial;
  EXPECT_TRUE(same_vector(got.negated, -a)) << trial;
  EXPECT_TRUE(same_vector(got.scaled_before, s * a)) << trial;
  EXPECT_TRUE(same_vector(got.scaled_after, a * s)) << trial;
  EXPECT_TRUE(same_vector(got.divided, a / s)) << trial;
  EXPECT_TRUE(same_vector(got.cross, a.cross(b))) << trial;
  EXPECT_TRUE(same_bits(got.dot, a.dot(b))) << trial;
  EXPECT_TRUE(same_bits(got.squared_norm, a.squaredNorm())) << trial;
  // Eigen's order, spelled out: what the packed and the lanes' sums reproduce.
  EXPECT_TRUE(same_bits(got.dot, (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2])) << trial;
}

TEST(PackedVec3, EveryOperationGivesEigensBits) {
  if (!contact_vec3_is_packed()) GTEST_SKIP() << "the library computes contacts on Vec3 itself";
  MixedValues value;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a = value.vector(), b = value.vector();
    const double s = value();
    expect_eigens_bits(contact_vec3_operations(a, b, s), a, b, s, trial);
  }
}

TEST(ContactLanes, EveryOperationGivesEachLaneEigensBits) {
  if (!contact_lanes_available()) GTEST_SKIP() << "the library has no AVX2 lanes";
  MixedValues value;
  for (int trial = 0; trial < 5000; ++trial) {
    std::array<Vec3, 4> a, b;
    std::array<double, 4> s;
    for (std::size_t l = 0; l < 4; ++l) {
      a[l] = value.vector();
      b[l] = value.vector();
      s[l] = value();
    }
    const std::array<ContactVec3Operations, 4> lanes = operations_in_lanes(a, b, s);
    for (std::size_t l = 0; l < 4; ++l) expect_eigens_bits(lanes[l], a[l], b[l], s[l], trial);
  }
}

// Contacts of a dense cell's scale: 5-50 mm particles, overlaps of 1e-7 to 1e-4 m, speeds to 2
// m/s, the springs of sticking contacts and of every kind of turn, one kind after another.
class CellContacts {
 public:
  ContactLawInputs next() {
    ContactLawInputs c;
    c.params.normal_stiffness = std::pow(10.0, 5.0 + 3.0 * fraction_(rng_));
    c.params.tangential_stiffness = (2.0 / 7.0) * c.params.normal_stiffness;
    c.params.damping_ratio = 0.2 * fraction_(rng_);
    c.params.tangential_damping_ratio = fraction_(rng_);
    c.params.friction = count_ % 11 == 0 ? 0.0 : fraction_(rng_);  // some cannot hold a spring
    c.damping_n = c.params.damping_ratio * std::sqrt(c.params.normal_stiffness * 1e-3);
    const Vec3 normal = random_vector(1.0).normalized();
    const double overlap = std::pow(10.0, -7.0 + 3.0 * fraction_(rng_));
    c.geometry = {normal, overlap, random_vector(2.0), random_vector(2.0)};
    // Springs: none, in the plane, slightly off it (the series' turn), far off it, along n.
    const Vec3 tangent = (random_vector(1.0) - random_vector(1.0).dot(normal) * normal);
    switch (count_ % 5) {
      case 0:
        c.spring = Vec3::Zero();
        break;
      case 1:
        c.spring = 1e-3 * overlap * tangent;
        break;
      case 2:
        c.spring = 1e-2 * overlap * (tangent + 1e-3 * normal);
        break;
      case 3:
        c.spring = overlap * (tangent + 0.5 * unit_(rng_) * normal);
        break;
      default:
        c.spring = overlap * normal;
        break;
    }
    ++count_;
    return c;
  }
  double time_step() { return 1e-7 * (1.0 + fraction_(rng_)); }

 private:
  Vec3 random_vector(double scale) {
    return {scale * unit_(rng_), scale * unit_(rng_), scale * unit_(rng_)};
  }
  std::mt19937_64 rng_{29};
  std::uniform_real_distribution<double> unit_{-1.0, 1.0}, fraction_{0.0, 1.0};
  int count_ = 0;
};

ContactResponse scalar_law(const ContactLawInputs& c, double dt) {
  return linear_spring_dashpot_damped(c.params, c.damping_n, c.geometry, c.spring, dt);
}

void expect_same_response(const ContactResponse& got, const ContactResponse& scalar, int trial) {
  EXPECT_TRUE(same_vector(got.force_on_a, scalar.force_on_a)) << trial;
  EXPECT_TRUE(same_vector(got.spring, scalar.spring)) << trial;
  EXPECT_TRUE(same_bits(got.normal_force, scalar.normal_force)) << trial;
  EXPECT_EQ(got.sliding, scalar.sliding) << trial;
  EXPECT_TRUE(same_bits(got.dissipated_normal, scalar.dissipated_normal)) << trial;
  EXPECT_TRUE(same_bits(got.dissipated_tangential, scalar.dissipated_tangential)) << trial;
  EXPECT_TRUE(same_bits(got.dissipated_friction, scalar.dissipated_friction)) << trial;
  EXPECT_TRUE(same_bits(got.elastic_energy, scalar.elastic_energy)) << trial;
}

TEST(PackedVec3, TheContactLawGivesTheScalarLawsBits) {
  if (!contact_vec3_is_packed()) GTEST_SKIP() << "the library computes contacts on Vec3 itself";
  CellContacts contacts;
  int sliding = 0, sticking = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const ContactLawInputs c = contacts.next();
    const double dt = contacts.time_step();
    const ContactResponse scalar = scalar_law(c, dt);
    expect_same_response(
        contact_law_on_contact_vec3(c.params, c.damping_n, c.geometry, c.spring, dt), scalar,
        trial);
    (scalar.sliding ? sliding : sticking) += 1;
  }
  // Both sides of the Coulomb limit were compared.
  EXPECT_GT(sliding, 2000);
  EXPECT_GT(sticking, 2000);
}

// Four contacts of mixed kinds in the lanes (one sliding beside three sticking, a spring beyond
// the series beside three within it): each lane gets what its contact gets alone.
TEST(ContactLanes, TheContactLawGivesEachLaneTheScalarLawsBits) {
  if (!contact_lanes_available()) GTEST_SKIP() << "the library has no AVX2 lanes";
  CellContacts contacts;
  int sliding = 0, sticking = 0, mixed_groups = 0;
  for (int trial = 0; trial < 5000; ++trial) {
    std::array<ContactLawInputs, 4> four;
    for (ContactLawInputs& c : four) c = contacts.next();
    const double dt = contacts.time_step();
    const std::array<ContactResponse, 4> lanes = contact_law_in_lanes(four, dt);
    int sliding_here = 0;
    for (std::size_t l = 0; l < 4; ++l) {
      const ContactResponse scalar = scalar_law(four[l], dt);
      expect_same_response(lanes[l], scalar, trial);
      sliding_here += scalar.sliding;
    }
    sliding += sliding_here;
    sticking += 4 - sliding_here;
    mixed_groups += sliding_here > 0 && sliding_here < 4;
  }
  EXPECT_GT(sliding, 2000);
  EXPECT_GT(sticking, 2000);
  EXPECT_GT(mixed_groups, 1000);
}

}  // namespace
}  // namespace millflow::dem
