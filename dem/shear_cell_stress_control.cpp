// The shear cell's side of its stress control (dem/stress_control.hpp): the constants it derives
// from the setup, compaction, the steps that run the control and the LE boundary's work, and the
// relief of a stiffened cell's stress.
#include "dem/shear_cell.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dem/shear_cell_geometry.hpp"

namespace millflow::dem {
using namespace shear_cell_detail;

namespace {

// A flowing bed answers a change of its volume over a shear strain of about this much; a
// control faster than that pumps energy into the cell instead of holding its stress.
constexpr double kRelaxationStrain = 0.1;

// Mean overlap of the pair contacts in force as a fraction of their centre distance at touch
// (r_i + r_j); 0 without any.
double mean_overlap_fraction(const System& system) {
  const auto x = system.positions();
  const auto r = system.radii();
  const PeriodicImages images(system.domain());
  double sum = 0.0, count = 0.0;
  for (const NeighborPair& pair : system.candidate_pairs()) {
    const double reach = r[pair.i] + r[pair.j];
    const double overlap = reach - images.separation(x[pair.i], x[pair.j]).norm();
    if (overlap <= 0.0) continue;
    sum += overlap / reach;
    count += 1.0;
  }
  return count > 0.0 ? sum / count : 0.0;
}

}  // namespace

std::unique_ptr<StressControl> ShearCell::make_stress_control() const {
  const double d = setup_.media_diameter, gap = nominal_gap(setup_);
  const PairParams& media = system_.materials().pair(media_, media_);
  const double media_mass = setup_.media.density * sphere_volume_of_diameter(d);
  const double t_c =
      collision_duration(media.normal_stiffness, 0.5 * media_mass, media.damping_ratio);
  const double crossing_time = (gap / d) * t_c;
  StressControlSettings settings{
      .target_stress = setup_.normal_stress,
      .shear_rate = setup_.shear_rate,
      .relaxation_time =
          std::max(crossing_time, kRelaxationStrain / setup_.shear_rate) / setup_.servo_gain,
      .max_speed = boundary_speed_limit(setup_, t_c),
      .interval_steps = static_cast<std::uint64_t>(setup_.steps_per_collision),
      .part_strain =
          kPartStrainOfStressOverlap * setup_.normal_stress * d / media.normal_stiffness};
  // The wall answers the flowing bed's modulus K p over the gap, not its contacts' stiffness:
  // v = M (F_target - F) with M = H / (K p A tau) relaxes the force in tau.
  settings.mobility =
      gap / (kFlowingBedModulus * setup_.normal_stress * wall_area() * settings.relaxation_time);
  spdlog::debug(
      "shear cell: {} every {} steps, mobility {:.4g} m/(N s), time constant {:.4g} s, at most "
      "{:.4g} m/s",
      walls() ? "servo" : "barostat", settings.interval_steps, settings.mobility,
      settings.relaxation_time, settings.max_speed);
  if (walls()) return std::make_unique<RoughWallServo>(settings, bottom_, top_, wall_area());
  return std::make_unique<LeesEdwardsBarostat>(settings);
}

double ShearCell::compaction_time_limit() const {
  return 4.0 * placement_gap(setup_) / control_->settings().max_speed;
}

std::uint64_t ShearCell::expected_compaction_steps() const {
  return static_cast<std::uint64_t>(std::llround(shear_cell_population(setup_).compaction_distance /
                                                 control_->settings().max_speed /
                                                 system_.time_step()));
}

std::uint64_t ShearCell::compaction_step_cap() const {
  const auto interval = control_->settings().interval_steps;
  const auto intervals = static_cast<std::uint64_t>(
      std::ceil(compaction_time_limit() / system_.time_step() / interval));
  return intervals * interval;
}

bool ShearCell::compact(std::uint64_t max_steps) {
  if (compaction_ == Compaction::Done) return true;
  // The linear law would close the loose fill far too slowly (it moves a boundary that touches
  // nothing only by the small strain that carries the target per relaxation time), so the
  // boundary closes at the speed limit while the bed carries less than half the target over a
  // control interval, and compaction ends on a state: several intervals in a row carrying it
  // (CompactionEnd; an LE box closes again whenever it loses contact: dem/stress_control.hpp).
  const StressControlSettings& control = control_->settings();
  if (compaction_ == Compaction::NotStarted) {
    compaction_ = Compaction::Running;
    control_->set_closing(true);
  }
  const double limit = compaction_time_limit();
  const auto more_to_do = [&] { return system_.time() < limit && !compaction_end_.compacted(); };
  for (std::uint64_t steps = 0; steps < max_steps && more_to_do();
       steps += control.interval_steps) {
    step_controlled(control.interval_steps);
    const bool was_closing = compaction_end_.closing();
    compaction_end_.answer(control_->last_interval_stress());
    if (compaction_end_.closing() != was_closing) control_->set_closing(compaction_end_.closing());
  }
  if (more_to_do()) return false;
  control_->set_closing(false);
  compaction_ = Compaction::Done;
  spdlog::debug(
      "shear cell: compacted in {:.4g} s to a gap of {:.4g} m{}", system_.time(), gap(),
      compaction_end_.compacted() ? "" : " (time limit: the bed never carried half its target)");
  return true;
}

template <class AfterStep>
void ShearCell::step_integrating_work(std::size_t steps, AfterStep&& after_step) {
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
    if (after_step()) {  // the box was stretched
      power = lees_edwards_power();
      wall_speed_ = system_.domain().lees_edwards.velocity;
    }
  }
}

void ShearCell::refine_time_step(int factor) {
  if (factor < 1)
    throw std::invalid_argument(fmt::format("shear cell: time step refinement {} < 1", factor));
  setup_.steps_per_collision *= factor;
  system_.set_time_step(system_.time_step() / factor);
  control_->lengthen_interval(static_cast<std::uint64_t>(factor));
}

void ShearCell::step_controlled(std::size_t steps) {
  step_integrating_work(steps, [&] { return control_->after_step(system_); });
}

StressReliefResult ShearCell::relieve_normal_stress(const StressRelief& relief) {
  if (walls()) throw std::logic_error("shear cell: relieve_normal_stress needs Lees-Edwards");
  if (!compacted()) throw std::logic_error("shear cell: relieve_normal_stress before compaction");
  const double target = setup_.normal_stress;
  const double height0 = system_.domain().length().y();
  const auto interval = static_cast<std::uint64_t>(setup_.steps_per_collision);
  StressReliefResult result;
  int settled = 0;
  std::optional<std::uint64_t> on_target_at;  // steps when an interval was first within
  while (result.steps + interval <= relief.max_steps) {
    double stress = 0.0;
    step_integrating_work(interval, [&] {
      stress += control_->normal_stress(system_);  // the barostat held: sampled here only
      return false;
    });
    result.steps += interval;
    ++result.intervals;
    result.normal_stress = stress / static_cast<double>(interval);
    if (result.intervals == 1) result.first_stress = result.normal_stress;
    const bool within = std::abs(result.normal_stress / target - 1.0) <= relief.tolerance;
    if (within && !on_target_at) on_target_at = result.steps;
    const bool holding = on_target_at && result.steps - *on_target_at < relief.hold_steps;
    settled = within ? settled + 1 : 0;
    if (within && !holding) {
      if (settled >= relief.settled_intervals) {
        result.relieved = true;
        break;
      }
      continue;
    }
    const double strain = std::clamp(
        relief.gain * (1.0 - target / result.normal_stress) * mean_overlap_fraction(system_),
        -relief.max_strain_per_interval, relief.max_strain_per_interval);
    // The barostat's stretch; the springs' energy it lets out is in no ledger (StressRelief).
    stretch_along_y_keeping_profile(system_, setup_.shear_rate, strain);
    wall_speed_ = system_.domain().lees_edwards.velocity;
  }
  result.strain = std::log(system_.domain().length().y() / height0);
  control_->reset_answer();
  return result;
}

}  // namespace millflow::dem
