#pragma once
// Analytic wall surfaces: planes and a rotating cylindrical mill shell with lifter bars and
// optional flat end walls. Pure functions, no state: the caller owns the wall's motion (theta).
//
// Conventions shared by every function here:
// - A contact's `normal` is a unit vector from the surface towards the sphere centre: the force
//   on the sphere from a repulsive contact acts along +normal.
// - `overlap` > 0 means touching. Walls are solid half-spaces (shell: everything at distance >= R
//   from the axis; plane: the side opposite its normal), so a sphere whose centre has crossed the
//   surface still gets a contact, with overlap = radius + depth of the centre, pushing it back.
// - `point` is the point of the surface closest to the sphere centre (the contact point).
// - `feature` tells which sub-surface was hit, so that contact histories can be keyed on
//   (particle, feature). At most one contact per feature is reported.
#include <optional>
#include <vector>

#include "dem/vec.hpp"

namespace millflow::dem {

struct SurfaceContact {
  Vec3 normal;     // unit, from the surface towards the sphere centre
  double overlap;  // > 0 when touching
  Vec3 point;      // contact point on the surface
  int feature;     // which sub-surface (for contact history keys)
};

// Plane through `plane_origin` with unit `plane_normal` pointing into the particle side.
// Contact when the signed distance of the centre from the plane is below `radius`.
std::optional<SurfaceContact> sphere_plane_contact(const Vec3& centre, double radius,
                                                   const Vec3& plane_origin,
                                                   const Vec3& plane_normal);

// A lifter bar: a symmetric trapezoid in the mill's cross-section, extruded along the axis.
// `height` is measured radially inwards from the shell at the lifter's centreline; the base of
// width `base_width` sits on the shell; the two side faces lean towards each other by
// `face_angle_deg` from the radial direction (0 = rectangular bar), so the top face has width
// base_width - 2 * height * tan(face_angle), which must be > 0.
struct LifterProfile {
  double height = 0.0;
  double base_width = 0.0;
  double face_angle_deg = 0.0;
};

// The mill's axis is +z through the origin. With end walls the mill occupies z in [0, length]
// and the end walls are the planes z = 0 and z = length; without them z is unbounded (the caller
// makes it periodic). The shell is rotated by `theta` (rad, counter-clockwise seen from +z);
// lifter k's centreline sits at angle theta + 2 pi k / lifter_count. Lifters extend over the
// whole z range.
struct MillShell {
  double radius = 0.0;  // inner radius of the shell (liner surface between lifters), m
  double length = 0.0;  // axial length, m (the periodic length when end_walls is false)
  int lifter_count = 0;
  LifterProfile lifter;
  bool end_walls = true;
};

// Throws std::invalid_argument naming the bad value and how to fix it: radius or length not
// positive, negative lifter count, lifter height not in (0, radius/2], base width not positive,
// face angle not in [0, 90), top width not positive, adjacent lifters overlapping at the base.
void validate(const MillShell& mill);

// Contact features of a mill: shell 0, lifter k 1 + k, end wall z = 0 at 1 + n and end wall
// z = length at 2 + n (n = lifter_count).
inline int shell_feature() {
  return 0;
}
inline int lifter_feature(int lifter) {
  return 1 + lifter;
}
inline int end_wall_feature(const MillShell& mill, int end /*0: z = 0, 1: z = length*/) {
  return 1 + mill.lifter_count + end;
}

// Appends every contact of the sphere with the shell, the lifters and the end walls to `out`
// (at most one per feature). The mill must be valid (see validate()).
//
// A lifter is the convex polygon of its trapezoid, extruded along z. Its side faces are extended
// outwards beyond the shell (by height + radius) so that the bar sits flush on the curved shell
// with no gap under its base corners; the buried part is more than `radius` away from every point
// inside the shell, so spheres inside the mill never touch it. Outside the polygon the contact is
// with its closest point; with the centre inside the polygon, it is with the nearest face
// (normal = that face's outward normal, overlap = radius + depth).
void sphere_mill_contacts(const MillShell& mill, double theta, const Vec3& centre, double radius,
                          std::vector<SurfaceContact>& out);

// atan2(y, x) in [-pi, pi] without the library call (about 145 instructions there), within
// kAngleWithinBound of std::atan2 (the lifter search widens its angular reach by the bound, so
// that the slots it visits hold every slot std::atan2 would give: the same contacts in the same
// order). The sign of y picks the half-plane as std::atan2 does, signed zeros included; zeros,
// infinities, NaNs and coordinates beyond 1e300 get std::atan2's own answer.
inline constexpr double kAngleWithinBound = 1e-6;
double angle_within_bound(double y, double x);

// A mill at one rotation angle with what every sphere's query needs worked out once: the angle
// reduced to one turn, the lifters' face angle and the directions of the lifter slots a sphere
// can reach. For the many spheres of one time step; the same bits as passing theta.
struct MillPose {
  double theta = 0.0;  // reduced to (-pi, pi]
  double face_sin = 0.0, face_cos = 1.0;
  long first_slot = 0;            // slot_radial[s] is the direction of slot first_slot + s
  std::vector<Vec3> slot_radial;  // (cos phi, sin phi, 0), phi = theta + slot * 2 pi / n
};
MillPose mill_pose(const MillShell& mill, double theta);
void sphere_mill_contacts(const MillShell& mill, const MillPose& pose, const Vec3& centre,
                          double radius, std::vector<SurfaceContact>& out);

// Free area of the mill's cross-section: the disk of the shell minus the exposed lifter areas
// (m^2). Times the length, the volume available to the charge.
double mill_free_cross_section_area(const MillShell& mill);

// A sphere nearer the axis than the lifter tops (the shell's, without lifters) by its radius
// touches neither the shell nor a lifter.
inline bool sphere_within_lifter_tops(const MillShell& mill, const Vec3& centre, double radius) {
  const double innermost = mill.radius - (mill.lifter_count > 0 ? mill.lifter.height : 0.0);
  const double clear = innermost - radius;
  return clear > 0.0 && centre.x() * centre.x() + centre.y() * centre.y() < clear * clear;
}

// A test cheaper than a mill query, inline for callers that meet every sphere of a charge at every
// step: one within the lifter tops and farther than its radius from the end walls (if any)
// touches nothing.
inline bool sphere_in_mill_interior(const MillShell& mill, const Vec3& centre, double radius) {
  return sphere_within_lifter_tops(mill, centre, radius) &&
         (!mill.end_walls || (centre.z() > radius && mill.length - centre.z() > radius));
}

// True when a sphere at `centre` lies inside the mill without touching the shell, the lifters or
// the end walls (used when filling the mill).
bool sphere_clear_of_mill(const MillShell& mill, double theta, const Vec3& centre, double radius);

}  // namespace millflow::dem
