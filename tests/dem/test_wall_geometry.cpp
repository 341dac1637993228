#include "dem/wall_geometry.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace millflow::dem {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTol = 1e-12;

// R = 0.5 m, 4 lifters 5 cm high and 6 cm wide at the base; lifter 0 points along +x at theta 0.
MillShell test_mill(double face_angle_deg = 0.0, bool end_walls = true) {
  return MillShell{0.5, 0.4, 4, LifterProfile{0.05, 0.06, face_angle_deg}, end_walls};
}

std::vector<SurfaceContact> contacts_of(const MillShell& mill, double theta, const Vec3& centre,
                                        double radius) {
  std::vector<SurfaceContact> out;
  sphere_mill_contacts(mill, theta, centre, radius, out);
  return out;
}

void expect_vec_near(const Vec3& actual, const Vec3& expected, double tol = kTol) {
  EXPECT_NEAR((actual - expected).norm(), 0.0, tol)
      << "actual " << actual.transpose() << " expected " << expected.transpose();
}

// The one contact expected: with `feature`, `overlap`, `normal` and `point`.
void expect_single_contact(const std::vector<SurfaceContact>& contacts, int feature, double overlap,
                           const Vec3& normal, const Vec3& point) {
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_EQ(contacts[0].feature, feature);
  EXPECT_NEAR(contacts[0].overlap, overlap, kTol);
  expect_vec_near(contacts[0].normal, normal);
  expect_vec_near(contacts[0].point, point);
}

Vec3 rotate_z(const Vec3& v, double angle) {
  return Vec3(std::cos(angle) * v.x() - std::sin(angle) * v.y(),
              std::sin(angle) * v.x() + std::cos(angle) * v.y(), v.z());
}

TEST(SpherePlane, OverlapNormalAndPoint) {
  const auto c = sphere_plane_contact(Vec3(1, 2, 0.3), 0.5, Vec3(0, 0, 0), Vec3(0, 0, 1));
  ASSERT_TRUE(c.has_value());
  EXPECT_NEAR(c->overlap, 0.2, kTol);
  expect_vec_near(c->normal, Vec3(0, 0, 1));
  expect_vec_near(c->point, Vec3(1, 2, 0));
}

TEST(SpherePlane, TiltedPlane) {
  const Vec3 n = Vec3(1, 1, 0).normalized();
  const Vec3 origin(1, 0, 0);
  const Vec3 foot = origin + Vec3(-1, 1, 4);  // a point of the plane (offset orthogonal to n)
  const auto c = sphere_plane_contact(foot + 0.1 * n, 0.25, origin, n);
  ASSERT_TRUE(c.has_value());
  EXPECT_NEAR(c->overlap, 0.15, kTol);
  expect_vec_near(c->normal, n);
  expect_vec_near(c->point, foot);
}

TEST(SpherePlane, CentreBehindThePlaneIsADeepContact) {
  const auto c = sphere_plane_contact(Vec3(0, 0, -0.2), 0.5, Vec3::Zero(), Vec3::UnitZ());
  ASSERT_TRUE(c.has_value());
  EXPECT_NEAR(c->overlap, 0.7, kTol);
  expect_vec_near(c->point, Vec3::Zero());
}

TEST(SpherePlane, NoContactAtOrBeyondOneRadius) {
  EXPECT_FALSE(sphere_plane_contact(Vec3(0, 0, 0.5), 0.5, Vec3::Zero(), Vec3::UnitZ()));
  EXPECT_FALSE(sphere_plane_contact(Vec3(0, 0, 0.7), 0.5, Vec3::Zero(), Vec3::UnitZ()));
}

TEST(MillShellContact, OverlapNormalAndPointAtSeveralAngles) {
  const MillShell plain{0.5, 0.4, 0, LifterProfile{}, false};
  for (double angle : {0.0, 1.0, 2.5, -2.0, kPi}) {
    const Vec3 outward(std::cos(angle), std::sin(angle), 0.0);
    const Vec3 centre = (0.5 - 0.02 + 0.003) * outward + Vec3(0, 0, 0.1);
    expect_single_contact(contacts_of(plain, 0.3, centre, 0.02), shell_feature(), 0.003, -outward,
                          0.5 * outward + Vec3(0, 0, 0.1));
  }
}

TEST(MillShellContact, CentreOutsideTheShellIsPushedBackIn) {
  const MillShell plain{0.5, 0.4, 0, LifterProfile{}, false};
  expect_single_contact(contacts_of(plain, 0.0, Vec3(0, 0.6, 0), 0.02), shell_feature(), 0.12,
                        Vec3(0, -1, 0), Vec3(0, 0.5, 0));
}

TEST(MillShellContact, ShellContactBetweenLifters) {
  // Lifters at 0, 90, 180, 270 degrees; 45 degrees is far from all of them.
  const Vec3 outward = Vec3(1, 1, 0).normalized();
  expect_single_contact(contacts_of(test_mill(), 0.0, 0.49 * outward + Vec3(0, 0, 0.2), 0.02),
                        shell_feature(), 0.01, -outward, 0.5 * outward + Vec3(0, 0, 0.2));
}

TEST(MillShellContact, NothingInTheMiddle) {
  EXPECT_TRUE(contacts_of(test_mill(), 0.4, Vec3(0.1, -0.05, 0.2), 0.05).empty());
  EXPECT_TRUE(sphere_clear_of_mill(test_mill(), 0.4, Vec3(0.1, -0.05, 0.2), 0.05));
}

// Rectangular lifter 0: x in [0.45, 0.5+] (top face at x = 0.45), |y| <= 0.03.
TEST(RectangularLifter, TopFace) {
  expect_single_contact(contacts_of(test_mill(), 0.0, Vec3(0.435, 0.005, 0.1), 0.02),
                        lifter_feature(0), 0.005, Vec3(-1, 0, 0), Vec3(0.45, 0.005, 0.1));
}

TEST(RectangularLifter, EachSideFace) {
  expect_single_contact(contacts_of(test_mill(), 0.0, Vec3(0.47, 0.045, 0.1), 0.02),
                        lifter_feature(0), 0.005, Vec3(0, 1, 0), Vec3(0.47, 0.03, 0.1));
  expect_single_contact(contacts_of(test_mill(), 0.0, Vec3(0.47, -0.04, 0.1), 0.02),
                        lifter_feature(0), 0.01, Vec3(0, -1, 0), Vec3(0.47, -0.03, 0.1));
}

TEST(RectangularLifter, CornerNormalPointsFromCornerToCentre) {
  const Vec3 corner(0.45, 0.03, 0.1);
  const Vec3 direction(-0.6, 0.8, 0.0);
  expect_single_contact(contacts_of(test_mill(), 0.0, corner + 0.015 * direction, 0.02),
                        lifter_feature(0), 0.005, direction, corner);
}

TEST(RectangularLifter, DeepCentreLeavesThroughTheNearestFace) {
  // 5 mm from the +y side, 10 mm from the top.
  expect_single_contact(contacts_of(test_mill(), 0.0, Vec3(0.46, 0.025, 0.1), 0.02),
                        lifter_feature(0), 0.025, Vec3(0, 1, 0), Vec3(0.46, 0.03, 0.1));
}

TEST(RectangularLifter, OtherLiftersAreNumberedCounterClockwise) {
  // Lifter 1 points along +y: its top face is at y = 0.45.
  expect_single_contact(contacts_of(test_mill(), 0.0, Vec3(0.0, 0.44, 0.1), 0.02),
                        lifter_feature(1), 0.01, Vec3(0, -1, 0), Vec3(0, 0.45, 0.1));
}

// Trapezoidal lifter 0 with 20 degree faces: top half-width 0.03 - 0.05 tan(20 deg).
struct Trapezoid {
  double angle = 20.0 * kPi / 180.0;
  double half_top = 0.03 - 0.05 * std::tan(angle);
  Vec3 top_corner{0.45, half_top, 0.1};
  Vec3 base_corner{0.5, 0.03, 0.1};
  Vec3 side_normal{-std::sin(angle), std::cos(angle), 0.0};
};

TEST(TrapezoidalLifter, TopFace) {
  expect_single_contact(contacts_of(test_mill(20.0), 0.0, Vec3(0.435, -0.002, 0.1), 0.02),
                        lifter_feature(0), 0.005, Vec3(-1, 0, 0), Vec3(0.45, -0.002, 0.1));
}

TEST(TrapezoidalLifter, EachSideFace) {
  const Trapezoid t;
  const Vec3 on_face = 0.5 * (t.top_corner + t.base_corner);
  expect_single_contact(contacts_of(test_mill(20.0), 0.0, on_face + 0.015 * t.side_normal, 0.02),
                        lifter_feature(0), 0.005, t.side_normal, on_face);
  const Vec3 mirror(1, -1, 1);
  const Vec3 on_other = on_face.cwiseProduct(mirror),
             other_normal = t.side_normal.cwiseProduct(mirror);
  expect_single_contact(contacts_of(test_mill(20.0), 0.0, on_other + 0.012 * other_normal, 0.02),
                        lifter_feature(0), 0.008, other_normal, on_other);
}

TEST(TrapezoidalLifter, CornerNormalPointsFromCornerToCentre) {
  const Trapezoid t;
  // Halfway between the top face's normal and the side face's normal: in the corner's region.
  const Vec3 direction = (Vec3(-1, 0, 0) + t.side_normal).normalized();
  expect_single_contact(contacts_of(test_mill(20.0), 0.0, t.top_corner + 0.015 * direction, 0.02),
                        lifter_feature(0), 0.005, direction, t.top_corner);
}

TEST(TrapezoidalLifter, DeepCentreLeavesThroughTheNearestFace) {
  // 5 mm under the top face, more than 1 cm from either side face.
  expect_single_contact(contacts_of(test_mill(20.0), 0.0, Vec3(0.455, 0.0, 0.1), 0.02),
                        lifter_feature(0), 0.025, Vec3(-1, 0, 0), Vec3(0.45, 0.0, 0.1));
}

// Brute force: the distance from a centre to the exposed faces of lifter 0 (top face and the
// sides down to where they meet the shell), by dense sampling.
double distance_to_exposed_lifter(const MillShell& mill, const Vec3& centre) {
  const double angle = mill.lifter.face_angle_deg * kPi / 180.0;
  const double h = mill.lifter.height, half_base = 0.5 * mill.lifter.base_width;
  const double half_top = half_base - h * std::tan(angle);
  const double top_x = mill.radius - h;
  const Eigen::Vector2d p(centre.x(), centre.y());
  double best = 1e9;
  constexpr int kSamples = 4000;
  for (int i = 0; i <= kSamples; ++i) {
    const double s = static_cast<double>(i) / kSamples;
    best = std::min(best, (p - Eigen::Vector2d(top_x, (2 * s - 1) * half_top)).norm());
    for (double side : {-1.0, 1.0}) {  // side faces from the top corner to 1.2 h down
      const Eigen::Vector2d q(top_x + 1.2 * h * s,
                              side * (half_top + 1.2 * h * s * std::tan(angle)));
      if (q.norm() <= mill.radius) best = std::min(best, (p - q).norm());
    }
  }
  return best;
}

bool inside_lifter(const MillShell& mill, const Vec3& centre) {
  const double top_x = mill.radius - mill.lifter.height;
  const double half_width =
      0.5 * mill.lifter.base_width -
      (mill.radius - centre.x()) * std::tan(mill.lifter.face_angle_deg * kPi / 180.0);
  return centre.x() >= top_x && std::abs(centre.y()) <= half_width;
}

// Outside the bar the overlap is r - distance; with the centre inside, r + distance.
TEST(LifterContact, MatchesBruteForceDistanceForSpheresClearOfTheShell) {
  for (double face_angle : {0.0, 20.0, 28.0}) {
    const MillShell mill = test_mill(face_angle, false);
    const double r = 0.03;
    int checked = 0;
    std::size_t sample = 0;
    for (double x = 0.36; x < 0.5; x += 0.0037) {
      for (double y = -0.08; y < 0.08; y += 0.0041) {
        const Vec3 centre(x, y, 0.0);
        if (centre.norm() + r >= mill.radius) continue;  // keep to spheres not touching the shell
        const double depth_sign = inside_lifter(mill, centre) ? -1.0 : 1.0;
        const double expected = r - depth_sign * distance_to_exposed_lifter(mill, centre);
        // Lifter 0 turned to the branch cut of atan2 (pi) and elsewhere must give the same.
        const double theta = std::array{0.0, kPi, -2.5}[sample++ % 3];
        const auto contacts = contacts_of(mill, theta, rotate_z(centre, theta), r);
        if (expected > 1e-5) {
          ASSERT_EQ(contacts.size(), 1u) << "face angle " << face_angle << " at " << x << ", " << y;
          EXPECT_EQ(contacts[0].feature, lifter_feature(0));
          EXPECT_NEAR(contacts[0].overlap, expected, 2e-6) << x << ", " << y;
          ++checked;
        } else if (expected < -1e-5) {
          EXPECT_TRUE(contacts.empty()) << "face angle " << face_angle << " at " << x << ", " << y;
        }
      }
    }
    EXPECT_GT(checked, 100);
  }
}

// The lifter search's cheap angle: within its bound of std::atan2 everywhere, on the same
// half-plane (its slots are numbered from it), signed zeros and the axes included.
TEST(AngleWithinBound, WithinItsBoundOfStdAtan2) {
  double worst = 0.0;
  const double scales[] = {1e-300, 1e-9, 0.37, 1.0, 4.5e7, 1.7e308};
  for (int i = 0; i < 240000; ++i) {
    const double phi = -kPi + 2.0 * kPi * (i + 0.5) / 240000.0;
    const double scale = scales[i % 6];
    const double y = scale * std::sin(phi), x = scale * std::cos(phi);
    const double exact = std::atan2(y, x), cheap = angle_within_bound(y, x);
    ASSERT_EQ(std::signbit(exact), std::signbit(cheap)) << y << ", " << x;
    worst = std::max(worst, std::abs(cheap - exact));
  }
  EXPECT_LT(worst, 0.25 * kAngleWithinBound);
  EXPECT_GT(worst, 0.0);  // an approximation: the bound is what makes it safe
  for (const double y : {0.0, -0.0, 1.0, -1.0, 3e-310, -3e-310}) {
    for (const double x : {0.0, -0.0, 1.0, -1.0, 3e-310, -3e-310}) {
      EXPECT_NEAR(angle_within_bound(y, x), std::atan2(y, x), kAngleWithinBound) << y << ", " << x;
      EXPECT_EQ(std::signbit(angle_within_bound(y, x)), std::signbit(std::atan2(y, x)))
          << y << ", " << x;
    }
  }
  EXPECT_EQ(angle_within_bound(0.0, -1.0), kPi);
  EXPECT_EQ(angle_within_bound(-0.0, -1.0), -kPi);
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(angle_within_bound(inf, -inf), std::atan2(inf, -inf));
  EXPECT_EQ(angle_within_bound(-1.0, inf), std::atan2(-1.0, inf));
  EXPECT_TRUE(std::isnan(angle_within_bound(std::numeric_limits<double>::quiet_NaN(), 1.0)));
}

TEST(LifterContact, BuriedBaseIsNeverTouchedFromInsideTheMill) {
  // Centres inside the shell near the lifter's root, with spheres up to larger than the lifter is
  // high and overlapping the shell: every lifter contact is with the top face, a side face or a
  // top corner, never with the buried base or its corners.
  const Trapezoid t;
  const MillShell mill = test_mill(20.0, false);
  const Vec3 lower_normal = t.side_normal.cwiseProduct(Vec3(1, -1, 1));
  int checked = 0;
  for (double r : {0.02, 0.06}) {
    for (double rho = 0.44; rho < 0.4999; rho += 0.0023) {
      for (double y = -0.1; y < 0.1; y += 0.0019) {
        const Vec3 centre(std::sqrt(rho * rho - y * y), y, 0.0);
        for (const SurfaceContact& c : contacts_of(mill, 0.0, centre, r)) {
          if (c.feature != lifter_feature(0)) continue;
          const bool on_face = (c.normal - Vec3(-1, 0, 0)).norm() < 1e-12 ||
                               (c.normal - t.side_normal).norm() < 1e-12 ||
                               (c.normal - lower_normal).norm() < 1e-12;
          const bool on_top_corner = std::abs(c.point.x() - 0.45) < 1e-12 &&
                                     std::abs(std::abs(c.point.y()) - t.half_top) < 1e-12;
          EXPECT_TRUE(on_face || on_top_corner) << "r " << r << " at " << centre.transpose();
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 1000);
}

TEST(LifterContact, ContactsRotateWithTheShell) {
  const MillShell mill = test_mill(20.0);
  const double theta = 0.7;
  int compared = 0;
  for (double rho = 0.40; rho < 0.52; rho += 0.013) {
    for (double psi = -kPi; psi < kPi; psi += 0.037) {
      const Vec3 centre(rho * std::cos(psi), rho * std::sin(psi), 0.015);
      const auto turned = contacts_of(mill, theta, centre, 0.025);
      const auto reference = contacts_of(mill, 0.0, rotate_z(centre, -theta), 0.025);
      ASSERT_EQ(turned.size(), reference.size()) << rho << ", " << psi;
      for (std::size_t i = 0; i < turned.size(); ++i) {
        EXPECT_EQ(turned[i].feature, reference[i].feature);
        EXPECT_NEAR(turned[i].overlap, reference[i].overlap, 1e-12);
        expect_vec_near(turned[i].normal, rotate_z(reference[i].normal, theta), 1e-12);
        expect_vec_near(turned[i].point, rotate_z(reference[i].point, theta), 1e-12);
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 500);
}

TEST(LifterContact, LargeAccumulatedAngleIsTheSameAsItsRemainder) {
  const MillShell mill = test_mill(20.0);
  const Vec3 centre = rotate_z(Vec3(0.0, 0.44, 0.1), 0.3);  // under lifter 1
  const auto a = contacts_of(mill, 0.3 + 2 * kPi * 100, centre, 0.03);
  const auto b = contacts_of(mill, 0.3, centre, 0.03);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_FALSE(a.empty());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].feature, b[i].feature);
    EXPECT_NEAR(a[i].overlap, b[i].overlap, 1e-9);
  }
}

TEST(EndWalls, BothEndsWithTheirFeatures) {
  const MillShell mill = test_mill();
  expect_single_contact(contacts_of(mill, 0.0, Vec3(0.1, 0.2, 0.01), 0.02),
                        end_wall_feature(mill, 0), 0.01, Vec3(0, 0, 1), Vec3(0.1, 0.2, 0.0));
  EXPECT_EQ(end_wall_feature(mill, 0), 5);
  expect_single_contact(contacts_of(mill, 0.0, Vec3(-0.1, 0.0, 0.395), 0.02),
                        end_wall_feature(mill, 1), 0.015, Vec3(0, 0, -1), Vec3(-0.1, 0.0, 0.4));
  EXPECT_EQ(end_wall_feature(mill, 1), 6);
}

TEST(EndWalls, AbsentWhenTheMillIsPeriodic) {
  EXPECT_TRUE(contacts_of(test_mill(0.0, false), 0.0, Vec3(0.1, 0.2, 0.01), 0.02).empty());
}

TEST(EndWalls, CornerOfShellAndEndWallGivesTwoContacts) {
  const Vec3 between_lifters = 0.49 * Vec3(1, -1, 0).normalized() + Vec3(0, 0, 0.39);
  const auto contacts = contacts_of(test_mill(), 0.0, between_lifters, 0.02);
  ASSERT_EQ(contacts.size(), 2u);
  EXPECT_EQ(contacts[0].feature + contacts[1].feature, shell_feature() + 6);
}

TEST(ClearOfMill, FalseForEveryKindOfTouch) {
  const MillShell mill = test_mill();
  EXPECT_FALSE(sphere_clear_of_mill(mill, 0.0, Vec3(0.435, 0.0, 0.1), 0.02));  // lifter
  const Vec3 between_lifters = Vec3(1, -1, 0).normalized();
  EXPECT_FALSE(sphere_clear_of_mill(mill, 0.0, 0.49 * between_lifters, 0.02));  // shell
  EXPECT_FALSE(sphere_clear_of_mill(mill, 0.0, Vec3(0.0, 0.0, 0.41), 0.02));    // beyond an end
  EXPECT_FALSE(sphere_clear_of_mill(mill, 0.0, Vec3(0.0, 0.7, 0.1), 0.02));     // outside
  EXPECT_TRUE(sphere_clear_of_mill(mill, 0.0, 0.47 * between_lifters + Vec3(0, 0, 0.1), 0.02));
}

// Exposed area of a rectangular bar of width w and height h in a circle of radius R:
// integral over |y| <= w/2 of sqrt(R^2 - y^2) - (R - h).
double rectangular_lifter_area(double R, double h, double w) {
  const double y = 0.5 * w;
  return y * std::sqrt(R * R - y * y) + R * R * std::asin(y / R) - w * (R - h);
}

TEST(FreeCrossSection, PlainShellIsTheDisk) {
  const MillShell plain{0.5, 0.4, 0, LifterProfile{}, true};
  EXPECT_NEAR(mill_free_cross_section_area(plain), kPi * 0.25, 1e-14);
}

TEST(FreeCrossSection, RectangularLiftersByTheHandFormula) {
  const double expected = kPi * 0.25 - 4 * rectangular_lifter_area(0.5, 0.05, 0.06);
  EXPECT_NEAR(mill_free_cross_section_area(test_mill()), expected, 1e-13);
}

TEST(FreeCrossSection, TrapezoidalLiftersByTheHandFormula) {
  // Trapezoid on the tangent line x = R minus its part beyond the circle. The side face meets
  // the circle at |y| = y_star; inside that the buried part is R - sqrt(R^2 - y^2) thick, outside
  // it is a triangle between the side face and the tangent line.
  const double R = 0.5, h = 0.05, half_base = 0.03, t = std::tan(20.0 * kPi / 180.0);
  const double half_top = half_base - h * t;
  auto side_x = [&](double y) { return R - (half_base - y) / t; };  // the side face's x at y
  double lo = half_top, hi = half_base;  // side_x(y) - sqrt(R^2 - y^2) changes sign in between
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (side_x(mid) < std::sqrt(R * R - mid * mid) ? lo : hi) = mid;
  }
  const double y_star = lo;
  const double cap = 2 * (R * y_star - 0.5 * (y_star * std::sqrt(R * R - y_star * y_star) +
                                              R * R * std::asin(y_star / R)));
  const double corners = (half_base - y_star) * (half_base - y_star) / t;
  const double lifter = h * (half_base + half_top) - cap - corners;
  EXPECT_NEAR(mill_free_cross_section_area(test_mill(20.0)), kPi * R * R - 4 * lifter, 1e-13);
}

std::string validation_message(const MillShell& mill) {
  try {
    validate(mill);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(valid)";
}

TEST(Validate, AcceptsTheTestMills) {
  EXPECT_EQ(validation_message(test_mill()), "(valid)");
  EXPECT_EQ(validation_message(test_mill(20.0)), "(valid)");
  EXPECT_EQ(validation_message(MillShell{0.5, 0.4, 0, LifterProfile{}, false}), "(valid)");
}

TEST(Validate, NamesTheBadValueAndTheFix) {
  MillShell m = test_mill();
  m.radius = -1;
  EXPECT_EQ(validation_message(m), "mill: radius = -1 m must be positive and finite");
  m = test_mill();
  m.length = 0;
  EXPECT_EQ(validation_message(m),
            "mill: length = 0 m must be positive and finite (the axial length, or the periodic "
            "length without end walls)");
  m = test_mill();
  m.lifter_count = -2;
  EXPECT_EQ(validation_message(m), "mill: lifter_count = -2 must be >= 0");
  m = test_mill();
  m.lifter.height = 0;
  EXPECT_EQ(validation_message(m),
            "mill: lifter height = 0 m must be positive (or set lifter_count to 0 for a shell "
            "without lifters)");
  m = test_mill();
  m.lifter.height = 0.3;
  EXPECT_EQ(validation_message(m),
            "mill: lifter height = 0.3 m is taller than radius/2 = 0.25 m; use a lower lifter");
  m = test_mill();
  m.lifter.base_width = 0;
  EXPECT_EQ(validation_message(m), "mill: lifter base_width = 0 m must be positive");
  m = test_mill();
  m.lifter.face_angle_deg = 90;
  EXPECT_EQ(validation_message(m), "mill: lifter face_angle_deg = 90 must be in [0, 90)");
  m = test_mill();
  m.lifter.face_angle_deg = 45;  // top width 0.06 - 2 * 0.05 * 1 = -0.04
  EXPECT_EQ(validation_message(m),
            "mill: lifter top width = base_width - 2 height tan(face_angle) = -0.04 m must be "
            "positive; use a smaller face_angle_deg, a lower lifter or a wider base");
  m = test_mill();
  m.lifter_count = 40;  // 2 * 0.5 * tan(pi / 40) = 0.0787...
  m.lifter.base_width = 0.08;
  m.lifter.height = 0.01;
  EXPECT_EQ(validation_message(m),
            "mill: 40 lifters of base_width = 0.08 m overlap at the base; use base_width < "
            "2 radius tan(pi / lifter_count) = 0.0787017 m or fewer lifters");
}

}  // namespace
}  // namespace millflow::dem
