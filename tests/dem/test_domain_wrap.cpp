// Domain::wrap and Domain::advance_shear at the edges where rounding lands exactly on hi or L;
// round_half_away against std::round.
#include "dem/domain.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace millflow::dem {
namespace {

Domain unit_lees_edwards_box(double offset, double velocity) {
  Domain d;
  d.periodic = {true, true, true};
  d.lees_edwards = LeesEdwards{true, 0, 1, offset, velocity};
  return d;
}

// A wrapped particle is the same physical point: its separation from the unwrapped one is zero,
// and its image there (velocity + the image velocity separation reports) moves as before.
void expect_same_point(const Domain& d, const Vec3& before, const Vec3& v_before, const Vec3& after,
                       const Vec3& v_after) {
  Vec3 image_velocity;
  EXPECT_LT(d.separation(before, after, &image_velocity).norm(), 1e-12);
  for (int a = 0; a < 3; ++a) {
    EXPECT_GE(after[a], d.lo[a]);
    EXPECT_LT(after[a], d.hi[a]);
  }
  EXPECT_LT((v_after + image_velocity - v_before).norm(), 1e-12);
}

TEST(DomainWrap, JustBelowTheLowerLeesEdwardsFaceRoundingUpToHi) {
  // -1e-17 + 1 rounds to exactly 1 = hi: the particle ends on the lower face, where its flow
  // coordinate and velocity must be those of the point just below it, not shifted by the offset.
  const Domain d = unit_lees_edwards_box(0.3, 2.0);
  const Vec3 x0(0.5, -1e-17, 0.5), v0(0.1, 0.0, 0.0);
  Vec3 x = x0, v = v0;
  d.wrap(x, v);
  EXPECT_EQ(x.y(), 0.0);
  EXPECT_NEAR(x.x(), 0.5, 1e-12);
  EXPECT_NEAR(v.x(), 0.1, 1e-12);
  expect_same_point(d, x0, v0, x, v);
}

TEST(DomainWrap, RandomPositionsAroundALeesEdwardsBoxStayTheSamePoint) {
  Domain d = unit_lees_edwards_box(0.37, -1.5);
  d.lo = Vec3(-0.2, 0.1, 0.0);
  d.hi = Vec3(0.8, 0.6, 0.3);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-0.6, 1.6);
  for (int k = 0; k < 1000; ++k) {
    const Vec3 len = d.length();
    const Vec3 x0(d.lo.x() + u(rng) * len.x(), d.lo.y() + u(rng) * len.y(),
                  d.lo.z() + u(rng) * len.z());
    const Vec3 v0(1.0, 2.0, 3.0);
    Vec3 x = x0, v = v0;
    d.wrap(x, v);
    expect_same_point(d, x0, v0, x, v);
  }
}

TEST(DomainAdvanceShear, OffsetStaysBelowTheFlowLength) {
  // fmod gives -1e-20; adding L = 1 rounds to exactly 1, outside [0, L).
  Domain d = unit_lees_edwards_box(0.0, -1e-20);
  d.advance_shear(1.0);
  EXPECT_GE(d.lees_edwards.offset, 0.0);
  EXPECT_LT(d.lees_edwards.offset, 1.0);

  d.lees_edwards = LeesEdwards{true, 0, 1, 0.75, 0.5};
  d.advance_shear(1.0);
  EXPECT_DOUBLE_EQ(d.lees_edwards.offset, 0.25);
  d.lees_edwards.velocity = -0.5;
  d.advance_shear(1.0);
  EXPECT_DOUBLE_EQ(d.lees_edwards.offset, 0.75);
}

// The image code's rounding must give std::round's bits for every double: ties away from zero,
// the sign of a zero, the values next to each half, the range where the conversion stops, and
// random values of every magnitude.
TEST(RoundHalfAway, GivesStdRoundBitsForEveryKindOfDouble) {
  const auto bits = [](double x) { return std::bit_cast<std::uint64_t>(x); };
  const double inf = std::numeric_limits<double>::infinity();
  // Each value is tried with both signs.
  std::vector<double> values = {0.0,    0.5,    1.5,   2.5,    0.3, 0x1p52,
                                0x1p53, 0x1p63, 1e300, 5e-324, inf};
  for (double n = -4.0; n <= 4.0; n += 1.0) {
    for (const double x : {n + 0.5, n - 0.5, n})
      for (const double toward : {-1e9, 1e9}) values.push_back(std::nextafter(x, toward));
  }
  for (const double edge : {0x1p52, 0x1p51})
    for (const double toward : {0.0, 1e300}) values.push_back(std::nextafter(edge, toward));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-60, 60);
  for (int k = 0; k < 100000; ++k) values.push_back(std::ldexp(unit(rng), exponent(rng)));
  for (const double x : values) {
    EXPECT_EQ(bits(round_half_away(x)), bits(std::round(x))) << x;
    EXPECT_EQ(bits(round_half_away(-x)), bits(std::round(-x))) << -x;
  }
  EXPECT_TRUE(std::isnan(round_half_away(std::numeric_limits<double>::quiet_NaN())));
}

}  // namespace
}  // namespace millflow::dem
