// The shear cell's stress control: its constants, compaction, and the law each control interval
// applies (rough-wall servo, Lees-Edwards barostat).
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

}  // namespace

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

}  // namespace millflow::dem
