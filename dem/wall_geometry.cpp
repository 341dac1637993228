#include "dem/wall_geometry.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace millflow::dem {

namespace {

using Vec2 = Eigen::Vector2d;
constexpr double kPi = std::numbers::pi;

double cross2(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// A lifter's cross-section in its own frame: x radial (outwards along the lifter's centreline),
// y tangential (towards increasing angle). Vertices counter-clockwise, edge i runs from vertex i
// to vertex i + 1: 0 buried base, 1 side at +y, 2 top, 3 side at -y.
struct LifterPolygon {
  std::array<Vec2, 4> vertex;
  std::array<Vec2, 4> outward_normal;
};

// `buried_depth`: how far beyond the shell (x = R) the side faces are extended; 0 gives the
// trapezoid whose base is the tangent line of the shell at the centreline.
// `s`, `c`: sine and cosine of the face angle.
LifterPolygon lifter_polygon(const MillShell& mill, double s, double c, double buried_depth) {
  const LifterProfile& p = mill.lifter;
  const double half_base = 0.5 * p.base_width + buried_depth * (s / c);
  const double half_top = 0.5 * p.base_width - p.height * (s / c);
  const double base_x = mill.radius + buried_depth, top_x = mill.radius - p.height;
  return LifterPolygon{{Vec2(base_x, -half_base), Vec2(base_x, half_base), Vec2(top_x, half_top),
                        Vec2(top_x, -half_top)},
                       {Vec2(1.0, 0.0), Vec2(-s, c), Vec2(-1.0, 0.0), Vec2(-s, -c)}};
}

struct PlanarContact {
  Vec2 normal;
  double overlap;
  Vec2 point;
};

// Closest point of the segment [a, b] to p.
Vec2 closest_on_segment(const Vec2& a, const Vec2& b, const Vec2& p) {
  const Vec2 d = b - a;
  const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return a + t * d;
}

// Contact of a disk (centre p, radius r) with a convex polygon.
std::optional<PlanarContact> disk_polygon_contact(const LifterPolygon& poly, const Vec2& p,
                                                  double r) {
  std::array<double, 4> distance{};
  for (std::size_t i = 0; i < 4; ++i) distance[i] = poly.outward_normal[i].dot(p - poly.vertex[i]);
  const auto farthest = std::max_element(distance.begin(), distance.end());
  // The distance to a convex polygon is at least the distance to any of its edge lines.
  if (*farthest >= r) return std::nullopt;
  if (*farthest <= 0.0) {  // centre inside: push out through the nearest face
    const Vec2& n = poly.outward_normal[static_cast<std::size_t>(farthest - distance.begin())];
    return PlanarContact{n, r - *farthest, p - *farthest * n};
  }
  Vec2 closest = p;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < 4; ++i) {
    if (distance[i] <= 0.0) continue;  // p is behind this edge: its closest point is elsewhere
    const Vec2 q = closest_on_segment(poly.vertex[i], poly.vertex[(i + 1) % 4], p);
    const double d2 = (p - q).squaredNorm();
    if (d2 < best) {
      best = d2;
      closest = q;
    }
  }
  const double dist = std::sqrt(best);
  if (dist >= r) return std::nullopt;
  return PlanarContact{(p - closest) / dist, r - dist, closest};
}

std::optional<SurfaceContact> shell_contact(const MillShell& mill, const Vec3& centre, double rho,
                                            double radius) {
  const double overlap = rho + radius - mill.radius;
  if (!(overlap > 0.0)) return std::nullopt;
  // A centre on the axis has no preferred direction; any outward direction is as good.
  const Vec3 outward = rho > 0.0 ? Vec3(centre.x() / rho, centre.y() / rho, 0.0) : Vec3::UnitX();
  const Vec3 point(mill.radius * outward.x(), mill.radius * outward.y(), centre.z());
  return SurfaceContact{-outward, overlap, point, shell_feature()};
}

// Range of lifter slots m (lifter index m mod n, centreline at theta + m * 2 pi / n) that the
// sphere can reach, judged by angles around the axis: every point of the lifter polygon lies
// within atan(half width / (R - height)) of its centreline, every point of the sphere within
// asin(r / rho) of the centre's direction. Both angles are bounded from above by their tangents,
// which cost no transcendental call; a wider range only adds candidates that the exact test
// rejects.
struct SlotRange {
  long first;
  long last;
};

SlotRange reachable_lifter_slots(const MillShell& mill, const LifterPolygon& poly, double theta,
                                 const Vec3& centre, double rho, double radius) {
  const long n = mill.lifter_count;
  const double lifter_half_angle = poly.vertex[1].y() / (mill.radius - mill.lifter.height);
  const double sphere_half_angle =
      radius < rho ? radius / std::sqrt(rho * rho - radius * radius) : kPi;
  // The margin keeps a lifter touched by a rounding-level overlap from being skipped.
  const double reach = lifter_half_angle + sphere_half_angle + 1e-9;
  if (reach >= kPi) return {0, n - 1};
  const double spacing = 2.0 * kPi / static_cast<double>(n);
  const auto slots_within = [spacing](double alpha, double reach) {
    return SlotRange{static_cast<long>(std::ceil((alpha - reach) / spacing)),
                     static_cast<long>(std::floor((alpha + reach) / spacing))};
  };
  // The cheap angle, its reach widened by twice its bound: the slots hold those of std::atan2's
  // angle (rounding keeps the order of the ends), numbered the same (the same half-plane). The
  // extra slots at either end lie beyond the reach, where the exact test finds nothing. Where
  // the slots could go round the mill, those of std::atan2 (one visit per lifter).
  const SlotRange wide = slots_within(angle_within_bound(centre.y(), centre.x()) - theta,
                                      reach + 2.0 * kAngleWithinBound);
  if (wide.last - wide.first < n) return wide;
  const SlotRange exact = slots_within(std::atan2(centre.y(), centre.x()) - theta, reach);
  return {exact.first, std::min(exact.last, exact.first + n - 1)};
}

double face_angle(const MillShell& mill) {
  return mill.lifter.face_angle_deg * kPi / 180.0;
}

double slot_spacing(const MillShell& mill) {
  return 2.0 * kPi / static_cast<double>(mill.lifter_count);
}

// An accumulated rotation angle reduced to one turn keeps the slot numbers small.
double reduced_angle(double theta) {
  return theta - 2.0 * kPi * std::round(theta / (2.0 * kPi));
}

Vec3 slot_direction(const MillShell& mill, double reduced_theta, long slot) {
  const double phi = reduced_theta + static_cast<double>(slot) * slot_spacing(mill);
  return Vec3(std::cos(phi), std::sin(phi), 0.0);
}

// Calls visit(contact) for each contact; stops early (returning false) when visit returns false.
template <class Visit>
bool visit_mill_contacts(const MillShell& mill, const MillPose& pose, const Vec3& centre,
                         double radius, Visit&& visit) {
  if (mill.end_walls) {
    for (int end = 0; end < 2; ++end) {
      const Vec3 origin(0.0, 0.0, end == 0 ? 0.0 : mill.length);
      const Vec3 normal(0.0, 0.0, end == 0 ? 1.0 : -1.0);
      if (auto c = sphere_plane_contact(centre, radius, origin, normal)) {
        c->feature = end_wall_feature(mill, end);
        if (!visit(*c)) return false;
      }
    }
  }
  // Lifter tops are the innermost wall surface: a sphere well inside them touches nothing more.
  if (sphere_within_lifter_tops(mill, centre, radius)) return true;

  const double rho = std::sqrt(centre.x() * centre.x() + centre.y() * centre.y());
  if (auto c = shell_contact(mill, centre, rho, radius)) {
    if (!visit(*c)) return false;
  }
  if (mill.lifter_count == 0) return true;

  // Extending the sides by height + radius puts the buried base more than `radius` beyond the
  // shell, and farther from any centre inside the bar than its top face.
  const LifterPolygon poly =
      lifter_polygon(mill, pose.face_sin, pose.face_cos, mill.lifter.height + radius);
  const SlotRange slots = reachable_lifter_slots(mill, poly, pose.theta, centre, rho, radius);
  const long n = mill.lifter_count;
  const auto table_size = static_cast<long>(pose.slot_radial.size());
  for (long m = slots.first; m <= slots.last; ++m) {
    const long s = m - pose.first_slot;
    const Vec3 radial = s >= 0 && s < table_size ? pose.slot_radial[static_cast<std::size_t>(s)]
                                                 : slot_direction(mill, pose.theta, m);
    const Vec3 tangential(-radial.y(), radial.x(), 0.0);
    const Vec2 local(centre.dot(radial), centre.dot(tangential));
    const auto c = disk_polygon_contact(poly, local, radius);
    if (!c) continue;
    const Vec3 normal = c->normal.x() * radial + c->normal.y() * tangential;
    const Vec3 point = c->point.x() * radial + c->point.y() * tangential + Vec3(0, 0, centre.z());
    const int lifter = static_cast<int>(((m % n) + n) % n);
    if (!visit(SurfaceContact{normal, c->overlap, point, lifter_feature(lifter)})) return false;
  }
  return true;
}

// Signed area of (triangle origin, a, b) intersected with the disk of radius r at the origin.
double triangle_disk_area(const Vec2& a, const Vec2& b, double r) {
  const Vec2 d = b - a;
  // Split [a, b] where it crosses the circle: |a + t d| = r.
  const double qa = d.squaredNorm(), qb = a.dot(d), qc = a.squaredNorm() - r * r;
  std::array<double, 4> cuts{0.0, 1.0, 1.0, 1.0};
  std::size_t cut_count = 1;
  const double disc = qb * qb - qa * qc;
  // A line that misses or only grazes the circle (the lifter's base is tangent to the shell)
  // has no part inside it.
  const bool line_enters_disk = qa > 0.0 && disc > 0.0;
  if (line_enters_disk) {
    const double root = std::sqrt(disc);
    for (double t : {(-qb - root) / qa, (-qb + root) / qa}) {
      if (t > 0.0 && t < 1.0) cuts[cut_count++] = t;
    }
  }
  cuts[cut_count] = 1.0;
  double area = 0.0;
  for (std::size_t i = 0; i < cut_count; ++i) {
    const Vec2 p = a + cuts[i] * d, q = a + cuts[i + 1] * d;
    const bool inside = line_enters_disk && (0.5 * (p + q)).squaredNorm() < r * r;
    area += inside ? 0.5 * cross2(p, q) : 0.5 * r * r * std::atan2(cross2(p, q), p.dot(q));
  }
  return area;
}

void require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument("mill: " + message);
}

}  // namespace

double angle_within_bound(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double larger = std::max(ax, ay), smaller = std::min(ax, ay);
  // The signed zeros, infinities and NaNs, and sums that could overflow: the library's.
  if (!(ax < 1e300 && ay < 1e300) || larger == 0.0) return std::atan2(y, x);
  // atan(a) for a = smaller / larger in [0, 1], through atan(a) = pi/4 + atan((a - 1) / (a + 1))
  // above tan(pi/8): the series' argument u stays within tan(pi/8) = 0.4142, where its terms up
  // to u^13 leave an error below u^15 / 15 = 1.3e-7. One division either way.
  const bool upper = smaller > 0.41421356237309503 * larger;
  const double u = upper ? (smaller - larger) / (smaller + larger) : smaller / larger;
  const double u2 = u * u;
  const double series =
      ((((((1.0 / 13.0) * u2 - 1.0 / 11.0) * u2 + 1.0 / 9.0) * u2 - 1.0 / 7.0) * u2 + 1.0 / 5.0) *
           u2 -
       1.0 / 3.0) *
          u2 +
      1.0;
  double angle = (upper ? 0.25 * kPi : 0.0) + u * series;
  if (ay > ax) angle = 0.5 * kPi - angle;
  if (x < 0.0) angle = kPi - angle;
  return std::signbit(y) ? -angle : angle;
}

std::optional<SurfaceContact> sphere_plane_contact(const Vec3& centre, double radius,
                                                   const Vec3& plane_origin,
                                                   const Vec3& plane_normal) {
  const double distance = (centre - plane_origin).dot(plane_normal);
  if (!(distance < radius)) return std::nullopt;
  return SurfaceContact{plane_normal, radius - distance, centre - distance * plane_normal, 0};
}

void validate(const MillShell& mill) {
  require(mill.radius > 0.0 && std::isfinite(mill.radius),
          fmt::format("radius = {} m must be positive and finite", mill.radius));
  require(mill.length > 0.0 && std::isfinite(mill.length),
          fmt::format("length = {} m must be positive and finite (the axial length, or the "
                      "periodic length without end walls)",
                      mill.length));
  require(mill.lifter_count >= 0, fmt::format("lifter_count = {} must be >= 0", mill.lifter_count));
  if (mill.lifter_count == 0) return;
  const LifterProfile& p = mill.lifter;
  require(p.height > 0.0, fmt::format("lifter height = {} m must be positive (or set "
                                      "lifter_count to 0 for a shell without lifters)",
                                      p.height));
  require(p.height <= 0.5 * mill.radius,
          fmt::format("lifter height = {} m is taller than radius/2 = {} m; use a lower lifter",
                      p.height, 0.5 * mill.radius));
  require(p.base_width > 0.0 && std::isfinite(p.base_width),
          fmt::format("lifter base_width = {} m must be positive", p.base_width));
  require(p.face_angle_deg >= 0.0 && p.face_angle_deg < 90.0,
          fmt::format("lifter face_angle_deg = {} must be in [0, 90)", p.face_angle_deg));
  const double top_width = p.base_width - 2.0 * p.height * std::tan(p.face_angle_deg * kPi / 180.0);
  require(top_width > 0.0,
          fmt::format("lifter top width = base_width - 2 height tan(face_angle) = {:.6g} m must be "
                      "positive; use a smaller face_angle_deg, a lower lifter or a wider base",
                      top_width));
  const double widest = 2.0 * mill.radius * std::tan(kPi / mill.lifter_count);
  require(mill.lifter_count == 1 || p.base_width < widest,
          fmt::format("{} lifters of base_width = {} m overlap at the base; use base_width < "
                      "2 radius tan(pi / lifter_count) = {:.6g} m or fewer lifters",
                      mill.lifter_count, p.base_width, widest));
}

MillPose mill_pose(const MillShell& mill, double theta) {
  MillPose pose;
  pose.theta = reduced_angle(theta);
  if (mill.lifter_count == 0) return pose;
  pose.face_sin = std::sin(face_angle(mill));
  pose.face_cos = std::cos(face_angle(mill));
  // With theta and the centre's direction both within half a turn, and a reach below half a
  // turn, reachable slots lie within 1.5 turns of slot 0.
  const long n = mill.lifter_count;
  pose.first_slot = -(3 * n) / 2 - 1;
  for (long m = pose.first_slot; m <= (3 * n) / 2 + 1; ++m)
    pose.slot_radial.push_back(slot_direction(mill, pose.theta, m));
  return pose;
}

void sphere_mill_contacts(const MillShell& mill, const MillPose& pose, const Vec3& centre,
                          double radius, std::vector<SurfaceContact>& out) {
  visit_mill_contacts(mill, pose, centre, radius, [&out](const SurfaceContact& c) {
    out.push_back(c);
    return true;
  });
}

void sphere_mill_contacts(const MillShell& mill, double theta, const Vec3& centre, double radius,
                          std::vector<SurfaceContact>& out) {
  sphere_mill_contacts(mill, mill_pose(mill, theta), centre, radius, out);
}

double mill_free_cross_section_area(const MillShell& mill) {
  const double disk = kPi * mill.radius * mill.radius;
  if (mill.lifter_count == 0) return disk;
  // The trapezoid on the tangent line; its part outside the disk is buried in the shell.
  const LifterPolygon poly =
      lifter_polygon(mill, std::sin(face_angle(mill)), std::cos(face_angle(mill)), 0.0);
  double lifter_area = 0.0;
  for (std::size_t i = 0; i < 4; ++i) {
    lifter_area += triangle_disk_area(poly.vertex[i], poly.vertex[(i + 1) % 4], mill.radius);
  }
  return disk - mill.lifter_count * lifter_area;
}

bool sphere_clear_of_mill(const MillShell& mill, double theta, const Vec3& centre, double radius) {
  return visit_mill_contacts(mill, mill_pose(mill, theta), centre, radius,
                             [](const SurfaceContact&) { return false; });
}

}  // namespace millflow::dem
