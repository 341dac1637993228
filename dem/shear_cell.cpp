#include "dem/shear_cell.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dem/checkpoint.hpp"
#include "dem/touching_pairs.hpp"

namespace millflow::dem {
namespace {

// Sum over the pair contacts in force of F[row] b[col]: F the force on the first particle, b the
// minimum-image vector from it to the second (the contact part of -V sigma), summed by the
// force pass.
double contact_virial(const System& system, int row, int col) {
  return system.contact_virial()(row, col);
}

// Solid fraction at which the walled cell is first filled: random sequential addition jams near
// 0.38, so particles go into a taller, looser cell that the servo then compresses.
constexpr double kPlacementSolidFraction = 0.3;
// Wall balls sit on a square lattice of this spacing (in diameters), each raised or lowered by a
// random amount up to kWallBallJitter diameters: a random bumpy surface that does not template a
// crystal in the bed. Four neighbours' centres then lie within sqrt(0.5^2/2 + 0.25^2) = 0.43 d
// of their middle, inside every ball: the layer has no hole for powder to leak through.
constexpr double kWallBallSpacing = 0.5;
constexpr double kWallBallJitter = 0.25;
// First guess of bulk / nominal shear rate (rough walls slip, the bulk at ~40% of nominal:
// docs/method.md).
constexpr double kInitialBulkFraction = 0.5;
// The wall-speed controller changes the speed by at most this factor per window.
constexpr double kMaxSpeedChange = 2.0;
// The barostat samples the normal stress every this many steps and averages it over its
// interval: single collisions of stiff balls make the instantaneous stress spike.
constexpr std::uint64_t kBarostatSamplesEvery = 4;
// A flowing bed answers a change of its volume over a shear strain of about this much; a
// barostat faster than that pumps energy into the cell instead of holding its stress.
constexpr double kBarostatRelaxationStrain = 0.1;
// The modulus of a flowing bed, dp/de ~ 2 p phi / (phi_c - phi) ~ 10 p near phi ~ 0.55 (the
// pressure of dense flow grows as (phi_c - phi)^-2); the instantaneous contact stiffness would
// be far too stiff, since the contacts of a flowing bed last only a collision.
constexpr double kBarostatModulus = 10.0;
// Once compacted, the box changes by at most this strain per relaxation time, so a bed that
// jams for a moment (its modulus far above 10 p) cannot throw the barostat into oscillation.
constexpr double kBarostatMaxDilation = 0.05;
// The barostat's integral term integrates the unclamped stress error over T_i = this many
// relaxation times. With the proportional term the loop (box strain answering p through the bed
// modulus M) is s^2 + s / tau + 1 / (tau T_i): damping ratio sqrt(T_i / tau) / 2 = 0.71 at
// modulus M, more for a stiffer bed. (4 tau: critically damped but twice as slow; in the 5 d
// cells of tests/dem/test_physics_barostat_mean_stress.cpp at I = 0.5, k_n / (p d) = 1e5 the mean
// p_yy of 8 seeds was 1.025 of the target against 1.004 with 2 tau.)
constexpr double kBarostatIntegralTimes = 2.0;
// Below this fraction of the target normal stress the barostat closes the box at its speed limit.
constexpr double kClosingStressFraction = 0.5;
// The particles are renumbered along a space-filling curve this often (System::
// reorder_particles): inserted at random, then mixed by the shear, a dense cell's contacts
// would otherwise touch memory all over, at a third of the speed.
constexpr std::uint64_t kReorderEverySteps = 1000;
// Random sequential addition gives up after this many failed tries per particle.
constexpr int kInsertionTries = 20000;

double sphere_volume(double diameter) {
  return std::numbers::pi / 6.0 * diameter * diameter * diameter;
}

void require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument("shear cell: " + message);
}

// Random sequential addition against a cell grid of equal spheres: periodic axes wrap, the others
// clamp. Cells are one member diameter wide.
class InsertionGrid {
 public:
  InsertionGrid(const Domain& domain, double member_radius)
      : domain_(domain), radius_(member_radius) {
    for (int a = 0; a < 3; ++a) {
      cells_[a] =
          std::max(1, static_cast<int>(std::floor(domain.length()[a] / (2.0 * member_radius))));
      cell_size_[a] = domain.length()[a] / cells_[a];
    }
    members_.resize(static_cast<std::size_t>(cells_[0]) * cells_[1] * cells_[2]);
  }

  void insert(const Vec3& x) {
    members_[cell_id(cell_of(x))].push_back(static_cast<std::uint32_t>(positions_.size()));
    positions_.push_back(x);
  }

  // Whether a sphere of `radius` at x would overlap a member.
  bool overlaps(const Vec3& x, double radius) const {
    const double reach = radius + radius_;
    const std::array<int, 3> centre = cell_of(x);
    std::array<std::vector<int>, 3> rows;
    for (int a = 0; a < 3; ++a) rows[a] = cells_near(a, centre[a], reach);
    for (int i : rows[0]) {
      for (int j : rows[1]) {
        for (int k : rows[2]) {
          for (std::uint32_t m : members_[cell_id({i, j, k})]) {
            if (domain_.separation(x, positions_[m]).squaredNorm() < reach * reach) return true;
          }
        }
      }
    }
    return false;
  }

 private:
  std::array<int, 3> cell_of(const Vec3& x) const {
    std::array<int, 3> c{};
    for (int a = 0; a < 3; ++a) {
      const int u = static_cast<int>(std::floor((x[a] - domain_.lo[a]) / cell_size_[a]));
      c[a] = domain_.periodic[a] ? ((u % cells_[a]) + cells_[a]) % cells_[a]
                                 : std::clamp(u, 0, cells_[a] - 1);
    }
    return c;
  }

  // Distinct cells along axis a within `reach` of cell c.
  std::vector<int> cells_near(int a, int c, double reach) const {
    const int span = static_cast<int>(std::ceil(reach / cell_size_[a]));
    std::vector<int> cells;
    if (domain_.periodic[a] && 2 * span + 1 >= cells_[a]) {
      for (int u = 0; u < cells_[a]; ++u) cells.push_back(u);
      return cells;
    }
    for (int u = c - span; u <= c + span; ++u) {
      if (domain_.periodic[a]) {
        cells.push_back(((u % cells_[a]) + cells_[a]) % cells_[a]);
      } else if (u >= 0 && u < cells_[a]) {
        cells.push_back(u);
      }
    }
    return cells;
  }

  std::size_t cell_id(const std::array<int, 3>& c) const {
    return (static_cast<std::size_t>(c[0]) * cells_[1] + c[1]) * cells_[2] + c[2];
  }

  Domain domain_;
  double radius_;
  std::array<int, 3> cells_{};
  Vec3 cell_size_ = Vec3::Ones();
  std::vector<std::vector<std::uint32_t>> members_;
  std::vector<Vec3> positions_;
};

double nominal_gap(const ShearCellSetup& s) {
  return s.size_diameters.y() * s.media_diameter;
}
double cell_area(const ShearCellSetup& s) {
  return s.size_diameters.x() * s.size_diameters.z() * s.media_diameter * s.media_diameter;
}
double powder_diameter(const ShearCellSetup& s) {
  return s.powder_diameter_ratio * s.media_diameter;
}

std::size_t media_count_for(const ShearCellSetup& s) {
  return static_cast<std::size_t>(std::llround(s.media_solid_fraction * cell_area(s) *
                                               nominal_gap(s) / sphere_volume(s.media_diameter)));
}

std::size_t powder_count_for(const ShearCellSetup& s) {
  const double solid = s.powder_load * (1.0 - s.media_solid_fraction) * cell_area(s) *
                       nominal_gap(s) * s.powder_bed_solid_fraction;
  return static_cast<std::size_t>(std::llround(solid / sphere_volume(powder_diameter(s))));
}

// Height of the particle bed when it is filled at kPlacementSolidFraction.
double placement_height(const ShearCellSetup& s) {
  const double solid = s.media_solid_fraction +
                       s.powder_load * (1.0 - s.media_solid_fraction) * s.powder_bed_solid_fraction;
  return std::max(1.0, solid / kPlacementSolidFraction) * nominal_gap(s);
}

// Height between the wall ball centre planes at which the walled cell is filled.
double placement_gap(const ShearCellSetup& s) {
  return (1.0 + 2.0 * kWallBallJitter) * s.media_diameter + placement_height(s);
}

MaterialTable make_materials(const ShearCellSetup& s) {
  MaterialTable table;
  const MaterialId media = table.add(s.media);
  const MaterialId powder = table.add(s.powder);
  const MaterialId wall = table.add({s.media.name + "_wall", s.media.density});
  table.set_interaction(media, media, s.media_media);
  table.set_interaction(media, powder, s.media_powder);
  table.set_interaction(powder, powder, s.powder_powder);
  table.set_interaction(wall, media, s.media_media);
  table.set_interaction(wall, powder, s.media_powder);
  table.set_interaction(wall, wall, s.media_media);
  return table;
}

Domain make_domain(const ShearCellSetup& s) {
  const double d = s.media_diameter;
  Domain domain;
  if (s.boundary == ShearCellSetup::Boundary::LeesEdwards) {
    // Filled tall and loose; the barostat compresses it.
    domain.hi = Vec3(s.size_diameters.x() * d, placement_height(s), s.size_diameters.z() * d);
    domain.periodic = {true, true, true};
    domain.lees_edwards = LeesEdwards{.enabled = true,
                                      .flow_axis = 0,
                                      .gradient_axis = 1,
                                      .offset = 0.0,
                                      .velocity = s.shear_rate * domain.hi.y()};
    return domain;
  }
  // Room above the top wall for the cell to dilate.
  domain.lo = Vec3(0.0, -d, 0.0);
  domain.hi = Vec3(s.size_diameters.x() * d, placement_gap(s) + 2.0 * d, s.size_diameters.z() * d);
  domain.periodic = {true, false, true};
  return domain;
}

const ShearCellSetup& checked(const ShearCellSetup& s) {
  validate(s);
  return s;
}

}  // namespace

void validate(const ShearCellSetup& s) {
  require(s.media_diameter > 0.0 && std::isfinite(s.media_diameter),
          fmt::format("media diameter = {} m must be > 0", s.media_diameter));
  require(s.powder_diameter_ratio > 0.0 && s.powder_diameter_ratio <= 1.0,
          fmt::format("powder diameter ratio = {} must be in (0, 1]", s.powder_diameter_ratio));
  require(s.powder_load >= 0.0 && s.powder_load <= 3.0,
          fmt::format("powder load = {} must be in [0, 3] (fraction of the media bed's voids)",
                      s.powder_load));
  require(s.powder_bed_solid_fraction > 0.0 && s.powder_bed_solid_fraction < 0.75,
          fmt::format("powder bed solid fraction = {} must be in (0, 0.75)",
                      s.powder_bed_solid_fraction));
  for (int a = 0; a < 3; ++a) {
    require(s.size_diameters[a] >= 3.0 && std::isfinite(s.size_diameters[a]),
            fmt::format("cell size along axis {} = {} media diameters must be >= 3", a,
                        s.size_diameters[a]));
  }
  require(s.shear_rate > 0.0 && std::isfinite(s.shear_rate),
          fmt::format("shear rate = {} 1/s must be > 0", s.shear_rate));
  require(s.normal_stress > 0.0 && std::isfinite(s.normal_stress),
          fmt::format("normal stress = {} Pa must be > 0", s.normal_stress));
  require(s.servo_gain > 0.0 && s.servo_gain <= 1.0,
          fmt::format("servo gain = {} must be in (0, 1]; 0.5 is a good start", s.servo_gain));
  require(s.media_solid_fraction > 0.05 && s.media_solid_fraction < 0.64,
          fmt::format("media solid fraction = {} must be in (0.05, 0.64)", s.media_solid_fraction));
  require(
      s.steps_per_collision >= 10,
      fmt::format("steps per collision = {} must be >= 10 (20 is usual)", s.steps_per_collision));
  require(s.overlap_bound.mean_fraction > 0.0 && s.overlap_bound.mean_fraction <= 0.1 &&
              s.overlap_bound.p95_fraction >= s.overlap_bound.mean_fraction &&
              s.overlap_bound.p95_fraction <= 0.5,
          fmt::format("overlap bound: mean {} and p95 {} of the smaller diameter must satisfy 0 < "
                      "mean <= 0.1 and mean <= p95 <= 0.5 (0.01 and 0.03 are usual)",
                      s.overlap_bound.mean_fraction, s.overlap_bound.p95_fraction));
  require(!(s.gravity && s.boundary == ShearCellSetup::Boundary::LeesEdwards),
          "gravity needs walls: a Lees-Edwards cell is periodic along the gradient axis; turn "
          "gravity off");
}

double size_scaled_stiffness(double reference_stiffness, double reference_diameter,
                             double diameter_a, double diameter_b) {
  if (!(reference_stiffness > 0.0) || !(reference_diameter > 0.0) || !(diameter_a > 0.0) ||
      !(diameter_b > 0.0)) {
    throw std::invalid_argument(fmt::format(
        "size_scaled_stiffness: stiffness {} N/m and diameters {}, {}, {} m must all be > 0",
        reference_stiffness, reference_diameter, diameter_a, diameter_b));
  }
  const double effective_diameter = 2.0 * diameter_a * diameter_b / (diameter_a + diameter_b);
  return reference_stiffness * effective_diameter / reference_diameter;
}

std::string contact_type_name(ContactType type) {
  switch (type) {
    case ContactType::MediaMedia:
      return "media-media";
    case ContactType::MediaPowder:
      return "media-powder";
    case ContactType::PowderPowder:
      return "powder-powder";
    case ContactType::WallMedia:
      return "wall-media";
    case ContactType::WallPowder:
      return "wall-powder";
  }
  return "unknown";
}

ShearCell::ShearCell(const ShearCellSetup& setup)
    : setup_(checked(setup)),
      system_(make_materials(setup), make_domain(setup),
              setup.gravity ? Vec3(0.0, -9.81, 0.0) : Vec3::Zero()) {
  const double d = setup_.media_diameter;
  media_count_ = media_count_for(setup_);
  powder_count_ = powder_count_for(setup_);
  system_.rng().reseed(setup_.seed);
  if (walls()) {
    const double gap0 = placement_gap(setup_);
    bottom_ = system_.add_group({.name = "bottom wall"});
    top_ = system_.add_group({.name = "top wall"});
    place_wall_layer(bottom_, 0.0);
    place_wall_layer(top_, gap0);
    place_media_dilute(gap0);
    const double wall_top = (0.5 + kWallBallJitter) * d;  // highest point of the bottom layer
    place_powder(wall_top, gap0 - wall_top);
  } else {
    place_media_lattice();
    place_powder(system_.domain().lo.y(), system_.domain().hi.y());
  }
  system_.set_time_step_from_collisions(setup_.steps_per_collision);
  system_.set_reorder_interval(kReorderEverySteps);
  set_wall_speed(walls() ? setup_.shear_rate * nominal_gap(setup_) / kInitialBulkFraction
                         : setup_.shear_rate * system_.domain().length().y());
  configure_stress_control();
}

ShearCell::ShearCell(const ShearCellSetup& setup, System system)
    : setup_(checked(setup)), system_(std::move(system)) {
  if (walls()) {
    bottom_ = 1;  // the groups the fresh cell added first
    top_ = 2;
  }
  derive_stress_control_constants();
}

void ShearCell::place_wall_layer(GroupId group, double y) {
  const double d = setup_.media_diameter;
  const Vec3 length = system_.domain().length();
  const int nx = static_cast<int>(std::ceil(length.x() / (kWallBallSpacing * d)));
  const int nz = static_cast<int>(std::ceil(length.z() / (kWallBallSpacing * d)));
  for (int i = 0; i < nx; ++i) {
    for (int k = 0; k < nz; ++k) {
      const double height = y + kWallBallJitter * d * system_.rng().uniform(-1.0, 1.0);
      const Vec3 x((i + 0.5) * length.x() / nx, height, (k + 0.5) * length.z() / nz);
      system_.add_particle(
          {.position = x, .radius = 0.5 * d, .material = wall_material_, .group = group});
      ++wall_ball_count_;
    }
  }
}

void ShearCell::place_media_dilute(double gap0) {
  const double r = 0.5 * setup_.media_diameter;
  InsertionGrid grid(system_.domain(), r);
  const Vec3 lo = system_.domain().lo, hi = system_.domain().hi;
  Rng& rng = system_.rng();
  for (std::size_t n = 0; n < media_count_; ++n) {
    for (int attempt = 0;; ++attempt) {
      require(
          attempt < kInsertionTries,
          fmt::format(
              "could not place media ball {} of {} without overlaps; lower media_solid_fraction", n,
              media_count_));
      // Centres at least r above the highest wall ball's top and below the lowest of the top layer.
      const double clear = (0.5 + kWallBallJitter) * setup_.media_diameter + r;
      const Vec3 x(rng.uniform(lo.x(), hi.x()), rng.uniform(clear, gap0 - clear),
                   rng.uniform(lo.z(), hi.z()));
      if (grid.overlaps(x, r)) continue;
      grid.insert(x);
      system_.add_particle({.position = x, .radius = r, .material = media_});
      break;
    }
  }
}

void ShearCell::place_media_lattice() {
  // FCC conventional cells of side >= sqrt(2) d (touching neighbours), stretched to fit the box;
  // the media take a random subset of the sites.
  const double d = setup_.media_diameter;
  const Vec3 length = system_.domain().length();
  std::array<int, 3> cells{};
  for (int a = 0; a < 3; ++a)
    cells[a] = static_cast<int>(std::floor(length[a] / (std::numbers::sqrt2 * d * 1.001)));
  std::vector<Vec3> sites;
  const std::array<Vec3, 4> basis{Vec3(0, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 0.5),
                                  Vec3(0, 0.5, 0.5)};
  for (int i = 0; i < cells[0]; ++i) {
    for (int j = 0; j < cells[1]; ++j) {
      for (int k = 0; k < cells[2]; ++k) {
        for (const Vec3& b : basis) {
          const Vec3 unit = (Vec3(i, j, k) + b + Vec3::Constant(0.25));
          sites.push_back(system_.domain().lo + Vec3(unit.x() * length.x() / cells[0],
                                                     unit.y() * length.y() / cells[1],
                                                     unit.z() * length.z() / cells[2]));
        }
      }
    }
  }
  require(sites.size() >= media_count_,
          fmt::format(
              "a Lees-Edwards cell of {} x {} x {} media diameters holds at most {} media balls on "
              "its FCC "
              "lattice, {} are needed for media_solid_fraction {}; lower it or enlarge the cell",
              setup_.size_diameters.x(), setup_.size_diameters.y(), setup_.size_diameters.z(),
              sites.size(), media_count_, setup_.media_solid_fraction));
  Rng& rng = system_.rng();
  for (std::size_t n = 0; n < media_count_; ++n) {  // partial Fisher-Yates shuffle
    const std::size_t pick =
        n + static_cast<std::size_t>(rng.uniform() * static_cast<double>(sites.size() - n));
    std::swap(sites[n], sites[pick]);
    const double y_mid = system_.domain().lo.y() + 0.5 * length.y();
    const Vec3 velocity(setup_.shear_rate * (sites[n].y() - y_mid), 0.0,
                        0.0);  // the imposed profile
    system_.add_particle(
        {.position = sites[n], .velocity = velocity, .radius = 0.5 * d, .material = media_});
  }
}

void ShearCell::place_powder(double y_lo, double y_hi) {
  if (powder_count_ == 0) return;
  const double r = 0.5 * powder_diameter(setup_);
  const double r_media = 0.5 * setup_.media_diameter;
  InsertionGrid media_grid(system_.domain(), r_media), powder_grid(system_.domain(), r);
  for (std::size_t p = 0; p < system_.size(); ++p) {
    if (system_.particle_groups()[p] == kFreeParticle) media_grid.insert(system_.positions()[p]);
  }
  const Vec3 lo = system_.domain().lo, hi = system_.domain().hi;
  const bool periodic_y = system_.domain().periodic[1];
  Rng& rng = system_.rng();
  for (std::size_t n = 0; n < powder_count_; ++n) {
    for (int attempt = 0;; ++attempt) {
      require(attempt < kInsertionTries,
              fmt::format(
                  "could not place powder particle {} of {} without overlaps; lower powder_load", n,
                  powder_count_));
      const double y = periodic_y ? rng.uniform(y_lo, y_hi) : rng.uniform(y_lo + r, y_hi - r);
      const Vec3 x(rng.uniform(lo.x(), hi.x()), y, rng.uniform(lo.z(), hi.z()));
      if (media_grid.overlaps(x, r) || powder_grid.overlaps(x, r)) continue;
      powder_grid.insert(x);
      Vec3 velocity = Vec3::Zero();
      if (!walls()) velocity.x() = setup_.shear_rate * (y - (lo.y() + 0.5 * (hi.y() - lo.y())));
      system_.add_particle({.position = x, .velocity = velocity, .radius = r, .material = powder_});
      break;
    }
  }
}

void ShearCell::derive_stress_control_constants() {
  const double d = setup_.media_diameter, gap = nominal_gap(setup_);
  const PairParams& media = system_.materials().pair(media_, media_);
  const double media_mass = setup_.media.density * sphere_volume(d);
  const double t_c =
      collision_duration(media.normal_stiffness, 0.5 * media_mass, media.damping_ratio);
  crossing_time_ = (gap / d) * t_c;
  servo_max_speed_ = setup_.servo_gain * d / crossing_time_;
  barostat_every_ = static_cast<std::size_t>(setup_.steps_per_collision);
  relaxation_time_ =
      std::max(crossing_time_, kBarostatRelaxationStrain / setup_.shear_rate) / setup_.servo_gain;
  // The wall answers the flowing bed's modulus K p over the gap, not its contacts' stiffness:
  // v = M (F_target - F) with M = H / (K p A tau) relaxes the force in tau.
  servo_mobility_ =
      gap / (kBarostatModulus * setup_.normal_stress * wall_area() * relaxation_time_);
}

void ShearCell::configure_stress_control() {
  derive_stress_control_constants();
  if (!walls()) {
    spdlog::debug("shear cell: barostat every {} steps, time constant {:.4g} s, at most {:.4g} m/s",
                  barostat_every_, relaxation_time_, servo_max_speed_);
    return;
  }
  KinematicGroup& top = system_.group(top_);
  top.servo_axis = 1;
  spdlog::debug(
      "shear cell: servo mobility {:.4g} m/(N s), time constant {:.4g} s, at most {:.4g} m/s",
      servo_mobility_, relaxation_time_, servo_max_speed_);
  top.servo_target_force = -setup_.normal_stress * wall_area();  // the wall pushes the bed along -y
  top.servo_mobility = servo_mobility_;
  top.servo_max_speed = servo_max_speed_;
}

void ShearCell::compact() {
  if (compacted_) return;
  compacted_ = true;
  // The linear law would close the loose fill far too slowly (it moves a boundary that touches
  // nothing only by the small strain that carries the target per relaxation time), so the
  // boundary closes at the speed limit until the bed carries half the target over a control
  // interval (an LE box closes again whenever it loses contact: ShearCell::control_stress).
  const double limit = 4.0 * placement_gap(setup_) / servo_max_speed_;
  barostat_at_speed_limit_ = true;
  while (system_.time() < limit) {
    step_controlled(barostat_every_);
    if (last_barostat_stress_ >= kClosingStressFraction * setup_.normal_stress) break;
  }
  barostat_at_speed_limit_ = false;
  smoothed_stress_ = last_barostat_stress_;
  spdlog::debug("shear cell: compacted in {:.4g} s to a gap of {:.4g} m", system_.time(), gap());
}

void ShearCell::set_wall_speed(double speed) {
  wall_speed_ = speed;
  if (walls()) {
    system_.group(bottom_).velocity.x() = -0.5 * speed;
    system_.group(top_).velocity.x() = 0.5 * speed;
  }
}

double ShearCell::wall_area() const {
  return cell_area(setup_);
}

double ShearCell::gap() const {
  if (!walls()) return system_.domain().length().y();
  // Wall balls come first: the bottom layer, then the top one (both at their layer's height).
  return system_.positions()[wall_ball_count_ - 1].y() - system_.positions()[0].y();
}

double ShearCell::wall_normal_stress() const {
  // The particles push the top wall up (+y) and the bottom one down.
  return 0.5 * (system_.group_load(top_).force.y() - system_.group_load(bottom_).force.y()) /
         wall_area();
}

ContactType ShearCell::contact_type(std::uint32_t category) const {
  const std::size_t n = system_.materials().size();
  const auto a = static_cast<MaterialId>(category / n), b = static_cast<MaterialId>(category % n);
  if (a == wall_material_ || b == wall_material_) {
    return (a == powder_ || b == powder_) ? ContactType::WallPowder : ContactType::WallMedia;
  }
  if (a == powder_ && b == powder_) return ContactType::PowderPowder;
  if (a == powder_ || b == powder_) return ContactType::MediaPowder;
  return ContactType::MediaMedia;
}

std::size_t ShearCell::steps_for_strain(double strain) const {
  if (!(strain >= 0.0) || !std::isfinite(strain)) {
    throw std::invalid_argument(fmt::format("shear cell: strain = {} must be >= 0", strain));
  }
  return static_cast<std::size_t>(std::ceil(strain / (setup_.shear_rate * system_.time_step())));
}

double ShearCell::shear_stress_now() const {
  if (walls()) {
    // The particles drag the top wall back (-x) and the bottom one forward (+x).
    return 0.5 * (system_.group_load(bottom_).force.x() - system_.group_load(top_).force.x()) /
           wall_area();
  }
  return lees_edwards_power() / (setup_.shear_rate * system_.domain().length().prod());
}

double ShearCell::normal_stress_now() const {
  if (walls()) return wall_normal_stress();
  // p_yy of the virial: contacts plus the kinetic part of the peculiar motion.
  double sum = -contact_virial(system_, 1, 1);
  const auto v = system_.velocities();
  const auto m = system_.masses();
  for (std::size_t p = 0; p < system_.size(); ++p) sum += m[p] * v[p].y() * v[p].y();
  return sum / system_.domain().length().prod();
}

double ShearCell::lees_edwards_power() const {
  // P = gdot V tau, V tau = sum over contacts of F_x (on i) b_y (i to j) - sum m c_x c_y: the
  // exact rate at which the sheared images feed (peculiar kinetic + elastic) energy and
  // dissipation.
  double shear = contact_virial(system_, 0, 1);
  const auto x = system_.positions();
  const auto v = system_.velocities();
  const auto m = system_.masses();
  const double y_mid = system_.domain().lo.y() + 0.5 * system_.domain().length().y();
  for (std::size_t p = 0; p < system_.size(); ++p) {
    shear -= m[p] * (v[p].x() - setup_.shear_rate * (x[p].y() - y_mid)) * v[p].y();
  }
  return setup_.shear_rate * shear;
}

double ShearCell::peculiar_kinetic_energy() const {
  const auto x = system_.positions();
  const auto v = system_.velocities();
  const auto w = system_.angular_velocities();
  const auto m = system_.masses();
  const auto r = system_.radii();
  const double y_mid = system_.domain().lo.y() + 0.5 * system_.domain().length().y();
  double energy = 0.0;
  for (std::size_t p = 0; p < system_.size(); ++p) {
    const Vec3 c = v[p] - Vec3(setup_.shear_rate * (x[p].y() - y_mid), 0.0, 0.0);
    energy += 0.5 * m[p] * c.squaredNorm() + 0.2 * m[p] * r[p] * r[p] * w[p].squaredNorm();
  }
  return energy;
}

void ShearCell::advance(std::size_t steps) {
  compact();
  step_controlled(steps);
}

void ShearCell::step_controlled(std::size_t steps) {
  // The LE boundary's work, by the trapezoidal rule over every step (the walls' work is the
  // system's own wall work).
  double power = walls() ? 0.0 : lees_edwards_power();
  for (std::size_t s = 0; s < steps; ++s) {
    system_.step();
    if (!walls()) {
      const double next = lees_edwards_power();
      le_work_ += 0.5 * (power + next) * system_.time_step();
      power = next;
    }
    // The wall load is free every step; the LE virial costs a pass over the contacts.
    if (walls() || system_.step_count() % kBarostatSamplesEvery == 0) {
      barostat_stress_sum_ += normal_stress_now();
      barostat_stress_samples_ += 1.0;
    }
    if (system_.step_count() % barostat_every_ == 0) {
      control_stress();
      if (!walls()) power = lees_edwards_power();
    }
  }
}

void ShearCell::control_stress() {
  const double stress = barostat_stress_samples_ > 0.0
                            ? barostat_stress_sum_ / barostat_stress_samples_
                            : normal_stress_now();
  barostat_stress_sum_ = barostat_stress_samples_ = 0.0;
  last_barostat_stress_ = stress;
  // Compaction closes the boundary at the speed limit. Later, an LE bed whose stress, averaged
  // over the relaxation time, is below kClosingStressFraction of the target has lost contact (it
  // dilated): the box closes at the speed limit again, affinely, so no particle is hit. A wall
  // closing that fast would hit the bed and throw the servo into oscillation: it keeps its law.
  // (Over a single interval a flowing bed of stiff balls often carries nothing for a moment.)
  const double interval = static_cast<double>(barostat_every_) * system_.time_step();
  smoothed_stress_ += (stress - smoothed_stress_) * std::min(1.0, interval / relaxation_time_);
  const bool closing =
      barostat_at_speed_limit_ ||
      (!walls() && smoothed_stress_ < kClosingStressFraction * setup_.normal_stress);
  if (walls()) {
    KinematicGroup& top = system_.group(top_);
    top.servo_mobility =
        closing ? servo_max_speed_ / std::abs(top.servo_target_force) : servo_mobility_;
    return;
  }
  apply_barostat(stress, closing);
}

void ShearCell::apply_barostat(double stress, bool closing) {
  const double control_interval = static_cast<double>(barostat_every_) * system_.time_step();
  const double height = system_.domain().length().y();
  const double error = (stress - setup_.normal_stress) / (kBarostatModulus * setup_.normal_stress);
  // The integral term sees the unclamped error, so it stays put only when the MEAN stress is on
  // target; it is frozen while closing and bounded by the clamp (anti-windup).
  if (!closing) {
    barostat_bias_ = std::clamp(
        barostat_bias_ + error * control_interval / (kBarostatIntegralTimes * relaxation_time_),
        -kBarostatMaxDilation, kBarostatMaxDilation);
  }
  const double proportional = std::clamp(error, -kBarostatMaxDilation, kBarostatMaxDilation);
  const double strain = closing
                            ? -servo_max_speed_ * control_interval / height
                            : (proportional + barostat_bias_) * control_interval / relaxation_time_;
  // Particles keep their velocity relative to the imposed profile gdot (y - y_mid), which
  // stretches with the box about its lower face like the positions.
  const double y_mid = system_.domain().lo.y() + 0.5 * height;
  const auto x = system_.positions();
  const auto v = system_.velocities();
  std::vector<Vec3> velocities(v.begin(), v.end());
  for (std::size_t p = 0; p < system_.size(); ++p)
    velocities[p].x() += setup_.shear_rate * strain * (x[p].y() - y_mid);
  const double springs_before = normal_spring_energy();
  system_.deform_affinely(1, 1.0 + strain);
  for (std::size_t p = 0; p < system_.size(); ++p)
    system_.set_velocity(static_cast<ParticleId>(p), velocities[p]);
  barostat_work_ += normal_spring_energy() - springs_before;
  wall_speed_ = system_.domain().lees_edwards.velocity;
}

double ShearCell::normal_spring_energy() const {
  const auto pairs = system_.candidate_pairs();
  const auto x = system_.positions();
  const auto r = system_.radii();
  const auto materials = system_.particle_materials();
  double energy = 0.0;
  for (const NeighborPair& pair : pairs) {
    const double overlap =
        r[pair.i] + r[pair.j] - system_.domain().separation(x[pair.i], x[pair.j]).norm();
    if (overlap <= 0.0) continue;
    energy += 0.5 *
              system_.materials().pair(materials[pair.i], materials[pair.j]).normal_stiffness *
              overlap * overlap;
  }
  return energy;
}

double ShearCell::work_in() const {
  return walls() ? system_.energy().wall_work : le_work_ + barostat_work_;
}

double ShearCell::shear_work() const {
  return walls() ? system_.energy().wall_work : le_work_;
}

double ShearCell::motion_energy() const {
  if (!walls()) return peculiar_kinetic_energy();
  const EnergyBudget budget = system_.energy();
  return budget.kinetic + budget.potential;
}

void ShearCell::run_strain(double strain) {
  advance(steps_for_strain(strain));
}

void ShearCell::sample_profile(Profile& profile) const {
  const double y0 = walls() ? system_.positions()[0].y() : system_.domain().lo.y();
  const double lo = y0 + 0.25 * gap(), hi = y0 + 0.75 * gap();
  const auto x = system_.positions();
  const auto v = system_.velocities();
  const auto m = system_.masses();
  const auto r = system_.radii();
  const auto groups = system_.particle_groups();
  const auto materials = system_.particle_materials();
  for (std::size_t p = 0; p < system_.size(); ++p) {
    if (groups[p] != kFreeParticle || x[p].y() < lo || x[p].y() >= hi) continue;
    const double y = x[p].y() - y0;
    profile.w += m[p];
    profile.wy += m[p] * y;
    profile.wyy += m[p] * y * y;
    profile.wv += m[p] * v[p].x();
    profile.wyv += m[p] * y * v[p].x();
    const double volume = 4.0 / 3.0 * std::numbers::pi * r[p] * r[p] * r[p];
    (materials[p] == powder_ ? profile.powder_volume : profile.media_volume) += volume;
  }
  profile.slab_volume += wall_area() * (hi - lo);
}

double ShearCell::bulk_shear_rate(const Profile& profile) {
  const double denominator = profile.w * profile.wyy - profile.wy * profile.wy;
  return denominator > 0.0 ? (profile.w * profile.wyv - profile.wy * profile.wv) / denominator
                           : 0.0;
}

void ShearCell::warm_up(double strain, int windows) {
  if (windows < 1)
    throw std::invalid_argument(
        fmt::format("shear cell: warm-up windows = {} must be >= 1", windows));
  for (int w = 0; w < windows; ++w) {
    WarmUpWindow window = start_window(strain / windows);
    advance_window(window, window.steps);
    finish_window(window, w);
  }
}

ShearCell::WarmUpWindow ShearCell::start_window(double strain) const {
  WarmUpWindow window;
  window.steps = steps_for_strain(strain);
  // The profile takes a while to answer a new wall speed: measure over the second half only.
  window.half = window.steps / 2;
  window.every = std::max<std::uint64_t>(1, (window.steps - window.half) / 50);
  return window;
}

void ShearCell::advance_window(WarmUpWindow& window, std::uint64_t max_steps) {
  compact();
  const std::uint64_t end = std::min(window.steps, window.done + max_steps);
  while (window.done < end) {
    // Up to the next sample: every `every` steps after `half`, and at the window's end.
    const std::uint64_t next_sample =
        window.done < window.half
            ? window.half
            : std::min(window.steps,
                       window.done + window.every - (window.done - window.half) % window.every);
    const std::uint64_t until = std::min(end, next_sample);
    advance(until - window.done);
    window.done = until;
    if (window.done > window.half && (window.done == next_sample)) {
      sample_profile(window.profile);
      window.shear_sum += shear_stress_now();
      window.normal_sum += normal_stress_now();
      window.samples += 1.0;
    }
  }
}

ShearCell::WindowSummary ShearCell::finish_window(const WarmUpWindow& window, int index) {
  const double measured = bulk_shear_rate(window.profile);
  const WindowSummary summary{
      .solid_fraction =
          (window.profile.media_volume + window.profile.powder_volume) / window.profile.slab_volume,
      .shear_stress = window.shear_sum / window.samples,
      .normal_stress = window.normal_sum / window.samples,
      .bulk_shear_rate = measured};
  spdlog::debug(
      "shear cell: warm-up window {}: solid fraction {:.4g}, shear stress {:.4g} Pa, normal stress "
      "{:.4g} Pa (target {:.4g})",
      index, summary.solid_fraction, summary.shear_stress, summary.normal_stress,
      setup_.normal_stress);
  // The bulk of a bed that has lost contact with the walls does not follow them: leave the speed
  // until the servo has closed the gap (otherwise it doubles every window).
  if (!walls() || summary.normal_stress < kClosingStressFraction * setup_.normal_stress)
    return summary;
  const double factor = measured > 0.0 ? std::clamp(setup_.shear_rate / measured,
                                                    1.0 / kMaxSpeedChange, kMaxSpeedChange)
                                       : kMaxSpeedChange;
  spdlog::debug(
      "shear cell: warm-up window {}: bulk rate {:.4g} 1/s (target {:.4g}), wall speed {:.4g} -> "
      "{:.4g} m/s",
      index, measured, setup_.shear_rate, wall_speed_, wall_speed_ * factor);
  set_wall_speed(wall_speed_ * factor);
  return summary;
}

bool ShearCell::stationary(const WindowSummary& previous, const WindowSummary& last) const {
  const auto near = [](double value, double target, double tolerance) {
    return std::abs(value - target) <= tolerance * std::abs(target);
  };
  const bool rate_ok =
      !walls() || near(last.bulk_shear_rate, setup_.shear_rate, kStationaryStressTolerance);
  return rate_ok && near(last.normal_stress, setup_.normal_stress, kStationaryStressTolerance) &&
         std::abs(last.solid_fraction - previous.solid_fraction) <= kStationarySolidFractionDrift &&
         near(last.shear_stress, 0.5 * (last.shear_stress + previous.shear_stress),
              0.5 * kStationaryShearDrift);
}

namespace {

constexpr std::string_view kRunMagic = "MFSHRCKP";

void put(BinaryWriter& out, const Vec3& v) {
  for (int a = 0; a < 3; ++a) out.put(v[a]);
}

void put(BinaryWriter& out, const Material& material) {
  out.put_string(material.name);
  out.put(material.density);
}

void put(BinaryWriter& out, const InteractionSpec& spec) {
  out.put(spec.restitution);
  out.put(spec.friction);
  out.put(spec.normal_stiffness);
  out.put(spec.tangential_stiffness_ratio);
  out.put(spec.tangential_damping_ratio);
}

// Every setting that shapes the run, so a checkpoint is never continued by another cell.
std::string run_identity(const ShearCellSetup& s, const ShearCellProtocol& protocol) {
  BinaryWriter out;
  out.put(s.media_diameter);
  put(out, s.media);
  put(out, s.powder);
  for (const InteractionSpec* spec : {&s.media_media, &s.media_powder, &s.powder_powder})
    put(out, *spec);
  out.put(s.powder_diameter_ratio);
  out.put(s.powder_load);
  out.put(s.powder_bed_solid_fraction);
  put(out, s.size_diameters);
  out.put<std::uint8_t>(static_cast<std::uint8_t>(s.boundary));
  out.put(s.shear_rate);
  out.put(s.normal_stress);
  out.put<std::uint8_t>(s.gravity);
  out.put(s.servo_gain);
  out.put(s.seed);
  out.put(s.media_solid_fraction);
  out.put<std::int32_t>(s.steps_per_collision);
  out.put(s.overlap_bound.mean_fraction);
  out.put(s.overlap_bound.p95_fraction);
  out.put(protocol.warmup_strain);
  out.put<std::int32_t>(protocol.warmup_windows);
  out.put(protocol.max_warmup_strain);
  out.put(protocol.measure_strain);
  out.put<std::int32_t>(protocol.measure.samples);
  out.put(protocol.measure.steady_tolerance);
  out.put<std::uint8_t>(protocol.measure.record_collisions);
  out.put(protocol.measure.standard_error_target);
  out.put(protocol.measure.max_strain);
  return out.bytes();
}

}  // namespace

void ShearCell::Profile::write(BinaryWriter& out) const {
  for (double v : {w, wy, wyy, wv, wyv, media_volume, powder_volume, slab_volume}) out.put(v);
}

void ShearCell::Profile::read(BinaryReader& in) {
  for (double* v : {&w, &wy, &wyy, &wv, &wyv, &media_volume, &powder_volume, &slab_volume})
    *v = in.get<double>();
}

void ShearCell::WarmUpWindow::write(BinaryWriter& out) const {
  for (std::uint64_t v : {steps, half, every, done}) out.put(v);
  profile.write(out);
  for (double v : {shear_sum, normal_sum, samples}) out.put(v);
}

void ShearCell::WarmUpWindow::read(BinaryReader& in) {
  for (std::uint64_t* v : {&steps, &half, &every, &done}) *v = in.get<std::uint64_t>();
  profile.read(in);
  for (double* v : {&shear_sum, &normal_sum, &samples}) *v = in.get<double>();
  if (every == 0 || half > steps || done > steps)
    throw CorruptData("shear cell checkpoint: the warm-up window is out of range");
}

void ShearCell::OverlapHistogram::write(BinaryWriter& out) const {
  out.put<std::uint64_t>(counts.size());
  for (double c : counts) out.put(c);
  out.put(sum);
  out.put(max);
}

void ShearCell::OverlapHistogram::read(BinaryReader& in) {
  const auto size = in.get<std::uint64_t>();
  if (size != 0 && size != kOverlapBins)
    throw CorruptData("shear cell checkpoint: an overlap histogram has the wrong size");
  counts.resize(size);
  for (double& c : counts) c = in.get<double>();
  sum = in.get<double>();
  max = in.get<double>();
}

void MeasuredBlock::write(BinaryWriter& out) const {
  for (double v : {shear_sum, normal_sum, gap_sum, stress_samples, pressure_sum, pressure_samples,
                   shear_work, duration})
    out.put(v);
  for (double v : dissipated) out.put(v);
}

void MeasuredBlock::read(BinaryReader& in) {
  for (double* v : {&shear_sum, &normal_sum, &gap_sum, &stress_samples, &pressure_sum,
                    &pressure_samples, &shear_work, &duration})
    *v = in.get<double>();
  for (double& v : dissipated) v = in.get<double>();
}

void ShearCell::Measurement::write(BinaryWriter& out) const {
  for (std::uint64_t v : {steps, min_steps, block_steps, every, stress_every, done}) out.put(v);
  for (double v : {work0, shear_work0, motion0, budget0.kinetic, budget0.potential, budget0.elastic,
                   budget0.dissipated, budget0.wall_work}) {
    out.put(v);
  }
  out.put<std::uint64_t>(dissipation0.size());
  for (const Dissipation& d : dissipation0) {
    for (double v : {d.normal, d.tangential, d.friction}) out.put(v);
  }
  profile.write(out);
  for (double v : tensor_sum) out.put(v);
  out.put(tensor_samples);
  out.put<std::uint64_t>(blocks.size());
  for (const MeasuredBlock& b : blocks) b.write(out);
  current.write(out);
  out.put(block_shear_work0);
  out.put<std::uint64_t>(block_dissipation0.size());
  for (double v : block_dissipation0) out.put(v);
  for (const OverlapHistogram& h : overlaps) h.write(out);
  for (const CollisionStats& stats : collisions) {
    out.put(stats.count);
    stats.dissipated_energy.write(out);
  }
  out.put(wall_seconds);
  out.put<std::uint8_t>(converged);
}

void ShearCell::Measurement::read(BinaryReader& in) {
  for (std::uint64_t* v : {&steps, &min_steps, &block_steps, &every, &stress_every, &done})
    *v = in.get<std::uint64_t>();
  for (double* v : {&work0, &shear_work0, &motion0, &budget0.kinetic, &budget0.potential,
                    &budget0.elastic, &budget0.dissipated, &budget0.wall_work}) {
    *v = in.get<double>();
  }
  dissipation0.resize(in.get<std::uint64_t>());
  for (Dissipation& d : dissipation0) {
    for (double* v : {&d.normal, &d.tangential, &d.friction}) *v = in.get<double>();
  }
  profile.read(in);
  for (double& v : tensor_sum) v = in.get<double>();
  tensor_samples = in.get<double>();
  const auto block_count = in.get<std::uint64_t>();
  if (block_count > steps)
    throw CorruptData("shear cell checkpoint: more measured blocks than steps");
  blocks.resize(block_count);
  for (MeasuredBlock& b : blocks) b.read(in);
  current.read(in);
  block_shear_work0 = in.get<double>();
  const auto categories = in.get<std::uint64_t>();
  if (categories != dissipation0.size())
    throw CorruptData("shear cell checkpoint: the block's dissipation has the wrong size");
  block_dissipation0.resize(categories);
  for (double& v : block_dissipation0) v = in.get<double>();
  for (OverlapHistogram& h : overlaps) h.read(in);
  for (CollisionStats& stats : collisions) {
    stats.count = in.get<double>();
    stats.dissipated_energy = LogHistogram::read(in);
  }
  wall_seconds = in.get<double>();
  converged = in.get<std::uint8_t>() != 0;
  if (every == 0 || stress_every == 0 || block_steps == 0 || done > steps || min_steps > steps) {
    throw CorruptData("shear cell checkpoint: the measurement is out of range");
  }
}

void ShearCell::write_state(BinaryWriter& out) const {
  for (std::uint64_t count : {media_count_, powder_count_, wall_ball_count_}) out.put(count);
  for (double v :
       {wall_speed_, le_work_, barostat_work_, barostat_stress_sum_, barostat_stress_samples_,
        last_barostat_stress_, smoothed_stress_, barostat_bias_}) {
    out.put(v);
  }
  out.put<std::uint8_t>(compacted_);
}

void ShearCell::read_state(BinaryReader& in) {
  for (std::size_t* count : {&media_count_, &powder_count_, &wall_ball_count_})
    *count = in.get<std::uint64_t>();
  for (double* v :
       {&wall_speed_, &le_work_, &barostat_work_, &barostat_stress_sum_, &barostat_stress_samples_,
        &last_barostat_stress_, &smoothed_stress_, &barostat_bias_}) {
    *v = in.get<double>();
  }
  compacted_ = in.get<std::uint8_t>() != 0;
  if (media_count_ + powder_count_ + wall_ball_count_ != system_.size()) {
    throw CorruptData("shear cell checkpoint: the particle counts do not add up to the system's");
  }
}

ShearCellRun::ShearCellRun(const ShearCellSetup& setup, const ShearCellProtocol& protocol)
    : ShearCellRun(ShearCell(setup), protocol) {}

ShearCellRun::ShearCellRun(ShearCell cell, const ShearCellProtocol& protocol)
    : cell_(std::move(cell)), protocol_(protocol) {
  if (protocol_.warmup_windows < 1 || !(protocol_.warmup_strain >= 0.0)) {
    throw std::invalid_argument(
        fmt::format("shear cell: warm-up of {} strain in {} windows; need strain >= 0 and "
                    "windows >= 1",
                    protocol_.warmup_strain, protocol_.warmup_windows));
  }
  if (!(protocol_.max_warmup_strain >= protocol_.warmup_strain)) {
    throw std::invalid_argument(
        fmt::format("shear cell: the warm-up's cap of {} strain is below its {} strain; raise the "
                    "cap to at least the warm-up",
                    protocol_.max_warmup_strain, protocol_.warmup_strain));
  }
  const double window_strain = protocol_.warmup_strain / protocol_.warmup_windows;
  window_steps_ = protocol_.warmup_strain > 0.0 ? cell_.steps_for_strain(window_strain) : 0;
  max_windows_ =
      protocol_.warmup_strain > 0.0
          ? std::max(
                protocol_.warmup_windows,
                static_cast<int>(std::floor(protocol_.max_warmup_strain / window_strain + 1e-9)))
          : 0;
  measure_steps_ =
      cell_.steps_for_strain(std::max(protocol_.measure_strain, protocol_.measure.max_strain));
}

ShearCellRun ShearCellRun::resume(const ShearCellSetup& setup, const ShearCellProtocol& protocol,
                                  const std::filesystem::path& path) {
  const std::string payload = read_checksummed_file(path, kRunMagic, kShearCellCheckpointVersion);
  BinaryReader in(payload);
  if (in.get_string() != run_identity(setup, protocol)) {
    throw CorruptData(
        fmt::format("{}: the checkpoint is of another shear cell or protocol", path.string()));
  }
  const auto system_version = in.get<std::uint32_t>();
  ShearCellRun run(
      ShearCell(setup, system_from_checkpoint_payload(in.get_string(), system_version)), protocol);
  run.cell_.read_state(in);
  const auto phase = in.get<std::uint8_t>();
  if (phase > static_cast<std::uint8_t>(Phase::Measuring)) {
    throw CorruptData(fmt::format("{}: unknown shear cell run phase {}", path.string(), phase));
  }
  run.phase_ = static_cast<Phase>(phase);
  run.window_index_ = in.get<std::int32_t>();
  run.window_.read(in);
  for (double* v :
       {&run.previous_.solid_fraction, &run.previous_.shear_stress, &run.previous_.normal_stress,
        &run.previous_.bulk_shear_rate, &run.stationary_strain_})
    *v = in.get<double>();
  run.stationary_ = in.get<std::uint8_t>() != 0;
  run.measurement_.read(in);
  run.measurement_.options = protocol.measure;
  if (!in.at_end())
    throw CorruptData(fmt::format("{}: trailing bytes after the shear cell run", path.string()));
  return run;
}

void ShearCellRun::save(const std::filesystem::path& path) {
  if (done()) throw std::logic_error("shear cell run: a finished run has nothing to checkpoint");
  if (phase_ == Phase::Measuring) cell_.tally_collisions(measurement_);
  BinaryWriter out;
  out.put_string(run_identity(cell_.setup(), protocol_));
  out.put(kCheckpointVersion);
  out.put_string(checkpoint_payload(cell_.system()));
  cell_.write_state(out);
  out.put(static_cast<std::uint8_t>(phase_));
  out.put<std::int32_t>(window_index_);
  window_.write(out);
  for (double v : {previous_.solid_fraction, previous_.shear_stress, previous_.normal_stress,
                   previous_.bulk_shear_rate, stationary_strain_})
    out.put(v);
  out.put<std::uint8_t>(stationary_);
  measurement_.write(out);
  write_checksummed_file(path, kRunMagic, kShearCellCheckpointVersion, out.bytes());
}

bool ShearCellRun::advance(std::uint64_t max_steps) {
  std::uint64_t left = max_steps;
  while (!done()) {
    const std::uint64_t before = cell_.system().step_count();
    if (phase_ == Phase::Compacting) {
      cell_.compact();
    } else if (phase_ == Phase::WarmUp) {
      cell_.advance_window(window_, left);
    } else {
      cell_.advance_measurement(measurement_, left);
    }
    left -= std::min(left, cell_.system().step_count() - before);
    const bool piece_finished = phase_ == Phase::Compacting ||
                                (phase_ == Phase::WarmUp && window_.finished()) ||
                                (phase_ == Phase::Measuring && measurement_.finished());
    if (!piece_finished) break;
    start_next_piece();
    if (left == 0) break;
  }
  return done();
}

void ShearCellRun::start_next_piece() {
  if (phase_ == Phase::WarmUp) {
    const ShearCell::WindowSummary last = cell_.finish_window(window_, window_index_++);
    stationary_ = window_index_ >= protocol_.warmup_windows && window_index_ >= 2 &&
                  cell_.stationary(previous_, last);
    if (stationary_) {
      stationary_strain_ = cell_.setup().shear_rate * cell_.system().time();
      spdlog::debug("shear cell: stationary after {} warm-up windows, strain {:.3g}", window_index_,
                    stationary_strain_);
    }
    previous_ = last;
  }
  if (phase_ == Phase::Measuring) {
    result_ = cell_.finish_measurement(measurement_);
    result_.stationary = stationary_;
    result_.stationary_strain = stationary_strain_;
    result_.steady = result_.steady && stationary_;
    phase_ = Phase::Done;
    return;
  }
  if (window_steps_ > 0 && !stationary_ && window_index_ < max_windows_) {
    phase_ = Phase::WarmUp;
    window_ = cell_.start_window(protocol_.warmup_strain / protocol_.warmup_windows);
    return;
  }
  phase_ = Phase::Measuring;
  measurement_ = cell_.start_measurement(protocol_.measure_strain, protocol_.measure);
}

double ShearCellRun::progress() const {
  // Against the caps: a cell that becomes stationary or converges early jumps ahead.
  const std::uint64_t total =
      window_steps_ * static_cast<std::uint64_t>(max_windows_) + measure_steps_;
  std::uint64_t done_steps = 0;
  if (phase_ == Phase::WarmUp)
    done_steps = window_steps_ * static_cast<std::uint64_t>(window_index_) + window_.done;
  if (phase_ == Phase::Measuring) done_steps = total - measure_steps_ + measurement_.done;
  done_steps = std::min(done_steps, total);
  if (phase_ == Phase::Done) done_steps = total;
  return static_cast<double>(done_steps) / static_cast<double>(total);
}

std::string ShearCellRun::phase_name() const {
  switch (phase_) {
    case Phase::Compacting:
      return "compacting";
    case Phase::WarmUp:
      return fmt::format("warm-up window {} (at most {})", window_index_ + 1, max_windows_);
    case Phase::Measuring:
      return "measuring";
    case Phase::Done:
      return "measured";
  }
  return "unknown";
}

const ShearCellMeasurements& ShearCellRun::measurements() const {
  if (!done()) throw std::logic_error("shear cell run: no measurements before the run is done");
  return result_;
}

}  // namespace millflow::dem
