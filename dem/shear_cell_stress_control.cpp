// The shear cell's side of its stress control (dem/stress_control.hpp): the constants it derives
// from the setup, compaction, and the steps that run the control and the LE boundary's work.
#include "dem/shear_cell.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <spdlog/spdlog.h>

#include "dem/shear_cell_geometry.hpp"

namespace millflow::dem {
using namespace shear_cell_detail;

namespace {

// A flowing bed answers a change of its volume over a shear strain of about this much; a
// control faster than that pumps energy into the cell instead of holding its stress.
constexpr double kRelaxationStrain = 0.1;

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
      .max_speed = setup_.servo_gain * d / crossing_time,
      .interval_steps = static_cast<std::uint64_t>(setup_.steps_per_collision)};
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

void ShearCell::compact() {
  if (compacted_) return;
  compacted_ = true;
  // The linear law would close the loose fill far too slowly (it moves a boundary that touches
  // nothing only by the small strain that carries the target per relaxation time), so the
  // boundary closes at the speed limit while the bed carries less than half the target over a
  // control interval, and compaction ends on a state: several intervals in a row carrying it
  // (CompactionEnd; an LE box closes again whenever it loses contact: dem/stress_control.hpp).
  const StressControlSettings& control = control_->settings();
  const double limit = 4.0 * placement_gap(setup_) / control.max_speed;
  CompactionEnd end(setup_.normal_stress);
  control_->set_closing(true);
  while (system_.time() < limit && !end.compacted()) {
    step_controlled(control.interval_steps);
    const bool was_closing = end.closing();
    end.answer(control_->last_interval_stress());
    if (end.closing() != was_closing) control_->set_closing(end.closing());
  }
  control_->set_closing(false);
  spdlog::debug("shear cell: compacted in {:.4g} s to a gap of {:.4g} m{}", system_.time(), gap(),
                end.compacted() ? "" : " (time limit: the bed never carried half its target)");
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
    if (control_->after_step(system_)) {  // the barostat stretched the box
      power = lees_edwards_power();
      wall_speed_ = system_.domain().lees_edwards.velocity;
    }
  }
}

}  // namespace millflow::dem
