// The contact law as pure functions: derived coefficients and single-step responses.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "dem/contact_law.hpp"

namespace millflow::dem {
namespace {

TEST(DerivedCoefficients, DampingRatioReproducesRestitution) {
  for (double e : {0.1, 0.3, 0.5, 0.9, 1.0}) {
    const double zeta = damping_ratio_for_restitution(e);
    // Analytic restitution of a damped linear oscillator released at zero overlap.
    const double back = std::exp(-zeta * std::numbers::pi / std::sqrt(1.0 - zeta * zeta));
    EXPECT_NEAR(back, e, 1e-12) << "e = " << e;
  }
  EXPECT_EQ(damping_ratio_for_restitution(1.0), 0.0);
}

TEST(DerivedCoefficients, StiffnessAndDurationAreInverse) {
  const double zeta = damping_ratio_for_restitution(0.4);
  const double k = stiffness_for_collision_duration(1e-4, 0.25, zeta);
  EXPECT_NEAR(collision_duration(k, 0.25, zeta), 1e-4, 1e-16);
  // Undamped: t_c = pi sqrt(m / k).
  EXPECT_NEAR(collision_duration(1e6, 1.0, 0.0), std::numbers::pi * 1e-3, 1e-15);
}

TEST(DerivedCoefficients, StabilityLimitOfUndampedSpringIsTwoOverOmega) {
  EXPECT_NEAR(stable_time_step_limit(1e6, 1.0, 0.0), 2e-3, 1e-15);
  EXPECT_LT(stable_time_step_limit(1e6, 1.0, 0.5), 2e-3);
}

// The largest value |x| reaches over 2,000 steps of the library's integrator (velocity Verlet, the
// dashpot on the velocity predicted from the last forces, v + h a) on x'' = -x - 2 zeta v from
// x = 1 at rest.
double largest_swing(double zeta, double h) {
  double x = 1.0, v = 0.0, a = -1.0, largest = 1.0;
  for (int n = 0; n < 2000; ++n) {
    const double half = v + 0.5 * h * a;
    x += h * half;
    a = -x - 2.0 * zeta * (half + 0.5 * h * a);
    v = half + 0.5 * h * a;
    largest = std::max(largest, std::abs(x));
  }
  return largest;
}

// The limit is the integrator's own: a step 1% inside it decays, 1% beyond it grows, at every
// damping; heavily damped it is 1 / (2 zeta omega). The formula for a dashpot on the step's
// velocity, (2 / omega)(sqrt(1 + zeta^2) - zeta), which the library took until 7 December 2026,
// is 1.5-2 times too long where the damping is large.
TEST(DerivedCoefficients, StabilityLimitIsTheIntegratorsOwn) {
  for (const double zeta : {0.05, 0.2, 0.5, 0.98, 1.75, 3.0}) {
    const double limit = stable_time_step_limit(1.0, 1.0, zeta);
    EXPECT_LE(largest_swing(zeta, 0.99 * limit), 1.0) << zeta;
    EXPECT_GT(largest_swing(zeta, 1.01 * limit), 1e3) << zeta;
    if (zeta >= 0.5) {
      EXPECT_LT(limit, 0.7 * 2.0 * (std::sqrt(1.0 + zeta * zeta) - zeta)) << zeta;
    }
  }
  EXPECT_NEAR(stable_time_step_limit(1.0, 1.0, 10.0), 1.0 / 20.0, 0.01 / 20.0);
}

TEST(DerivedCoefficients, EffectiveMassTreatsWallAsInfinitelyHeavy) {
  EXPECT_DOUBLE_EQ(effective_mass(2.0, 2.0), 1.0);
  EXPECT_DOUBLE_EQ(effective_mass(3.0, 0.0), 3.0);
}

PairParams params(double e, double mu) {
  return derive_pair_params(
      InteractionSpec{.restitution = e, .friction = mu, .normal_stiffness = 1000.0}, "a-b");
}

TEST(LinearSpringDashpot, NormalForceIsSpringMinusDashpot) {
  const PairParams p = params(0.5, 0.3);
  const Vec3 approaching(0, 0, -0.2);  // m/s
  const ContactGeometry g{Vec3::UnitZ(), 1e-3, approaching, approaching};
  const ContactResponse r = linear_spring_dashpot(p, 0.1, g, Vec3::Zero(), 1e-4);
  const double c_n = normal_damping_coefficient(1000.0, 0.1, p.damping_ratio);
  EXPECT_NEAR(r.normal_force, 1000.0 * 1e-3 + c_n * 0.2, 1e-12);
  EXPECT_NEAR(r.force_on_a.z(), r.normal_force, 1e-12);
  EXPECT_NEAR(r.dissipated_normal, c_n * 0.04 * 1e-4, 1e-15);
  EXPECT_NEAR(r.elastic_energy, 0.5 * 1000.0 * 1e-6, 1e-15);
  EXPECT_FALSE(r.sliding);
}

// The spring follows the contact points' displacement over the step (their half-step velocity,
// here 0.008 m/s across and 0.003 m/s along the normal, which it leaves out); the dashpot acts on
// the velocity at the step's end (0.01 m/s).
TEST(LinearSpringDashpot, SpringGrowsWithTheStepsTangentialDisplacementWhileSticking) {
  const PairParams p = params(0.5, 1.0);
  const ContactGeometry g{Vec3::UnitZ(), 1e-3, Vec3(0.01, 0, 0), Vec3(0.008, 0, 0.003)};
  const ContactResponse r = linear_spring_dashpot(p, 0.1, g, Vec3(2e-6, 0, 0), 1e-4);
  EXPECT_NEAR(r.spring.x(), 2e-6 + 0.008 * 1e-4, 1e-18);
  EXPECT_EQ(r.spring.z(), 0.0);
  const double c_t =
      p.tangential_damping_ratio * normal_damping_coefficient(1000.0, 0.1, p.damping_ratio);
  EXPECT_NEAR(r.force_on_a.x(), -p.tangential_stiffness * r.spring.x() - c_t * 0.01, 1e-12);
  EXPECT_FALSE(r.sliding);
}

// A sliding contact's spring is reset so that spring and dashpot together sit on the limit,
// F_t = -(k_t s + C_t v_t), as LAMMPS and MercuryDPM reset theirs.
TEST(LinearSpringDashpot, SlidingCapsForceAtCoulombLimitAndResetsSpringWithItsDashpot) {
  const PairParams p = params(0.5, 0.2);
  const Vec3 v_t(0.01, 0, 0);
  const ContactGeometry g{Vec3::UnitZ(), 1e-3, v_t, v_t};
  const ContactResponse r = linear_spring_dashpot(p, 0.1, g, Vec3(5e-3, 0, 0), 1e-4);
  ASSERT_TRUE(r.sliding);
  const Vec3 tangential = r.force_on_a - r.normal_force * Vec3::UnitZ();
  EXPECT_NEAR(tangential.norm(), 0.2 * r.normal_force, 1e-12);
  EXPECT_LT(tangential.x(), 0.0);  // opposes the sliding
  const double c_t =
      p.tangential_damping_ratio * normal_damping_coefficient(1000.0, 0.1, p.damping_ratio);
  EXPECT_NEAR((p.tangential_stiffness * r.spring + c_t * v_t + tangential).norm(), 0.0, 1e-12);
  EXPECT_LT(r.spring.norm(), 5e-3);  // the spring let go of what it held above the limit
  EXPECT_GT(r.dissipated_friction, 0.0);
}

// In the damped tail of an unloading contact the dashpot pulls harder than the spring pushes
// (F_n < 0); the Coulomb limit takes |F_n| there, as LAMMPS's and MercuryDPM's laws do, so the
// contact still resists sliding (a limit of mu max(F_n, 0) would leave no tangential force).
TEST(LinearSpringDashpot, UnloadingTailPullsAndHoldsUpToMuTimesThePull) {
  const PairParams p = params(0.3, 0.5);
  const double c_n = normal_damping_coefficient(1000.0, 0.1, p.damping_ratio);
  const double separating = 0.5;  // m/s: C_n v_n > k_n overlap
  const ContactGeometry g{Vec3::UnitZ(), 1e-5, Vec3(1.0, 0, separating), Vec3(1.0, 0, separating)};
  const ContactResponse r = linear_spring_dashpot(p, 0.1, g, Vec3::Zero(), 1e-4);
  EXPECT_NEAR(r.normal_force, 1000.0 * 1e-5 - c_n * separating, 1e-12);
  ASSERT_LT(r.normal_force, 0.0);
  ASSERT_TRUE(r.sliding);
  const Vec3 tangential = r.force_on_a - r.normal_force * Vec3::UnitZ();
  EXPECT_NEAR(tangential.norm(), 0.5 * std::abs(r.normal_force), 1e-12);
  EXPECT_LT(tangential.x(), 0.0);  // opposes the sliding
  const double c_t = p.tangential_damping_ratio * c_n;
  EXPECT_NEAR((p.tangential_stiffness * r.spring + c_t * Vec3(1.0, 0, 0) + tangential).norm(), 0.0,
              1e-12);
}

TEST(LinearSpringDashpot, FrictionlessContactStoresAndDissipatesNothingTangential) {
  const PairParams p = params(1.0, 0.0);
  const ContactGeometry g{Vec3::UnitZ(), 1e-3, Vec3(1.0, 0.5, 0), Vec3(1.0, 0.5, 0)};
  const ContactResponse r = linear_spring_dashpot(p, 0.1, g, Vec3::Zero(), 1e-4);
  EXPECT_EQ(r.spring.norm(), 0.0);
  EXPECT_EQ(r.dissipated_friction, 0.0);
  EXPECT_EQ(r.dissipated_normal, 0.0);
}

TEST(LinearSpringDashpot, RotatedSpringKeepsLengthAndLiesInTangentPlane) {
  const Vec3 spring(1e-3, 0, 1e-4);
  const Vec3 normal = Vec3(0.1, 0, 1).normalized();
  const Vec3 rotated = rotate_spring_into_tangent_plane(spring, normal);
  EXPECT_NEAR(rotated.norm(), spring.norm(), 1e-18);
  EXPECT_NEAR(rotated.dot(normal), 0.0, 1e-18);
}

// The small turns of a step take the series, larger ones the exact rescale: on both sides of
// kSpringTurnSeriesLimit the length is kept to rounding (a series one term shorter would be off
// by 3e-13 near the limit).
TEST(LinearSpringDashpot, TurnedSpringKeepsLengthToRoundingOnBothSidesOfTheSeriesLimit) {
  const Vec3 spring(1e-3, 4e-4, 0);  // tangent to the old normal, z
  int series = 0, exact = 0;
  for (double angle = 1e-8; angle < 0.3; angle *= 1.25) {
    const Vec3 normal(std::sin(angle), 0, std::cos(angle));
    const double along = spring.dot(normal);
    (along * along / spring.squaredNorm() < kSpringTurnSeriesLimit ? series : exact) += 1;
    const Vec3 rotated = rotate_spring_into_tangent_plane(spring, normal);
    EXPECT_NEAR(rotated.norm() / spring.norm(), 1.0, 1e-15) << "turned by " << angle << " rad";
    EXPECT_NEAR(rotated.dot(normal), 0.0, 1e-18) << "turned by " << angle << " rad";
  }
  EXPECT_GT(series, 10);
  EXPECT_GT(exact, 10);
}

TEST(DerivePairParams, RejectsOutOfRangeValuesNamingThem) {
  auto message = [](InteractionSpec spec) {
    try {
      derive_pair_params(spec, "steel-steel");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message({.restitution = 0.0, .friction = 0.5, .normal_stiffness = 1e6}),
            "interaction steel-steel: restitution = 0 is outside (0, 1]; give the ratio of rebound "
            "to impact normal speed");
  EXPECT_EQ(message({.restitution = 1.2, .friction = 0.5, .normal_stiffness = 1e6}),
            "interaction steel-steel: restitution = 1.2 is outside (0, 1]; give the ratio of "
            "rebound to impact normal speed");
  EXPECT_EQ(message({.restitution = 0.5, .friction = -0.1, .normal_stiffness = 1e6}),
            "interaction steel-steel: friction = -0.1 must be a finite number >= 0");
  EXPECT_EQ(message({.restitution = 0.5, .friction = 0.5, .normal_stiffness = -1.0}),
            "interaction steel-steel: normal stiffness = -1 N/m must be a finite number > 0");
}

}  // namespace
}  // namespace millflow::dem
