// The shear cell: its setup, materials and domain, and the stresses, work and energy it reads off
// the system (the jobs around it: placement, stress control, warm-up, stationarity, checkpoint and
// run, in dem/shear_cell_*.cpp).
#include "dem/shear_cell.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

#include "dem/deterministic_sum.hpp"
#include "dem/skin_choice.hpp"
#include "dem/touching_pairs.hpp"

#include "dem/shear_cell_geometry.hpp"

namespace millflow::dem {
using namespace shear_cell_detail;

namespace {

// Sum over the pair contacts in force of F[row] b[col]: F the force on the first particle, b the
// minimum-image vector from it to the second (the contact part of -V sigma), summed by the
// force pass.
double contact_virial(const System& system, int row, int col) {
  return system.contact_virial()(row, col);
}

// The most steps a strain may take (steps_for_strain): 2^53, where doubles stop counting exactly.
constexpr double kMostStepsForAStrain =
    static_cast<double>(std::uint64_t{1} << std::numeric_limits<double>::digits);

// Per-particle sums run in blocks of this many particles (deterministic_sum).
constexpr std::size_t kParticleSumGrain = 512;

// The particles are renumbered along a space-filling curve this often (System::
// reorder_particles): inserted at random, then mixed by the shear, a dense cell's contacts
// would otherwise touch memory all over, at a third of the speed.
constexpr std::uint64_t kReorderEverySteps = 1000;

std::size_t media_count_for(const ShearCellSetup& s) {
  return static_cast<std::size_t>(
      std::llround(s.media_solid_fraction * cell_area(s) * nominal_gap(s) /
                   sphere_volume_of_diameter(s.media_diameter)));
}

std::size_t powder_count_for(const ShearCellSetup& s) {
  const double solid = s.powder_load * (1.0 - s.media_solid_fraction) * cell_area(s) *
                       nominal_gap(s) * s.powder_bed_solid_fraction;
  return static_cast<std::size_t>(
      std::llround(solid / sphere_volume_of_diameter(powder_diameter(s))));
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

MaterialTable shear_cell_detail::make_materials(const ShearCellSetup& s) {
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

ShearCellPopulation shear_cell_population(const ShearCellSetup& s) {
  const double solid_fraction = nominal_solid_fraction(s);
  const double compacted_height =
      std::max(1.0, solid_fraction / kCompactedSolidFraction) * nominal_gap(s);
  ShearCellPopulation population{
      .media = media_count_for(s),
      .powder = powder_count_for(s),
      .solid_fraction = solid_fraction,
      .placement_height = placement_height(s),
      .compaction_distance = std::max(0.0, placement_height(s) - compacted_height)};
  if (s.boundary == ShearCellSetup::Boundary::RoughWalls) {
    const Vec3 length = make_domain(s).length();
    population.wall_balls = 2 * wall_layer_columns(length.x(), s.media_diameter) *
                            wall_layer_columns(length.z(), s.media_diameter);
  }
  return population;
}

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
  if (s.neighbor_skin_fraction) {
    require(*s.neighbor_skin_fraction > 0.0 && *s.neighbor_skin_fraction <= 2.0,
            fmt::format("neighbour skin fraction = {} must be in (0, 2] (0.3 is usual), or empty "
                        "to choose it by trial",
                        *s.neighbor_skin_fraction));
  }
  require(!(s.gravity && s.boundary == ShearCellSetup::Boundary::LeesEdwards),
          "gravity needs walls: a Lees-Edwards cell is periodic along the gradient axis; turn "
          "gravity off");
}

double boundary_speed_limit(const ShearCellSetup& s, double media_contact_time) {
  const double d = s.media_diameter;
  return s.servo_gain * d / ((nominal_gap(s) / d) * media_contact_time);
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
  system_.set_neighbor_skin(setup_.neighbor_skin_fraction.value_or(kDefaultSkinFraction) *
                            smallest_diameter(system_));
  system_.set_reorder_interval(kReorderEverySteps);
  set_wall_speed(walls() ? setup_.shear_rate * nominal_gap(setup_) / kInitialBulkFraction
                         : setup_.shear_rate * system_.domain().length().y());
  control_ = StressControlPtr(make_stress_control());
}

ShearCell::ShearCell(const ShearCellSetup& setup, System system)
    : setup_(checked(setup)), system_(std::move(system)) {
  if (walls()) {
    bottom_ = 1;  // the groups the fresh cell added first
    top_ = 2;
  }
  control_ = StressControlPtr(make_stress_control());
}

double ShearCell::neighbor_skin_fraction() const {
  return system_.neighbor_skin() / smallest_diameter(system_);
}

void ShearCell::choose_neighbor_skin() {
  if (setup_.neighbor_skin_fraction) return;
  adopt_skin_by_trials(system_);
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
  // Between the layers' mean centre planes (the balls' heights are jittered by up to
  // kWallBallJitter d, so two single balls could be a diameter off).
  const std::size_t layer = wall_ball_count_ / 2;
  return wall_layer_plane(system_, layer, layer) - wall_layer_plane(system_, 0, layer);
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
  const double steps = std::ceil(strain / (setup_.shear_rate * system_.time_step()));
  // Beyond 2^53 steps a count is no longer exact (and beyond 2^64 not even a number of steps): a
  // shear rate or time step far off, not a run anyone could wait for.
  if (!(steps <= kMostStepsForAStrain)) {
    throw std::invalid_argument(fmt::format(
        "shear cell: strain = {} at {} 1/s is {:.3g} steps of {:.3g} s, more than {:.3g}; "
        "raise the shear rate or lower the strain",
        strain, setup_.shear_rate, steps, system_.time_step(), kMostStepsForAStrain));
  }
  return static_cast<std::size_t>(steps);
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
  return control_->normal_stress(system_);
}

double ShearCell::lees_edwards_power() const {
  // P = gdot V tau, V tau = sum over contacts of F_x (on i) b_y (i to j) - sum m c_x c_y: the
  // exact rate at which the sheared images feed (peculiar kinetic + elastic) energy and
  // dissipation.
  const auto x = system_.positions();
  const auto v = system_.velocities();
  const auto m = system_.masses();
  const double y_mid = system_.domain().lo.y() + 0.5 * system_.domain().length().y();
  // Summed by all the cell's threads: it runs every step.
  const double momentum_flux = deterministic_sum(system_.size(), kParticleSumGrain, [&](auto p) {
    return m[p] * (v[p].x() - setup_.shear_rate * (x[p].y() - y_mid)) * v[p].y();
  });
  return setup_.shear_rate * (contact_virial(system_, 0, 1) - momentum_flux);
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

double ShearCell::work_in() const {
  return shear_work() + control_->work();
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

}  // namespace millflow::dem
