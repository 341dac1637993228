#include "dem/stress_control.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "dem/deterministic_sum.hpp"

namespace millflow::dem {
namespace {

// The stretches' work sums over the candidate pairs in blocks of this many, on every thread of
// the cell (deterministic_sum).
constexpr std::size_t kPairSumGrain = 2048;

// The change of the normal springs' elastic energy when the box and the particles are stretched
// along y by `factor` about its lower face, J: over the pairs in contact at the last step, from
// their separations before and after (the stretch scales a separation's y by the factor, image
// included). A pair the stretch brings into contact is not counted: its overlap is at most
// (factor - 1) times its separation's y, against a contact's own. (Until 6 December a stretch
// took the springs' energy of every candidate pair before and after it: two passes over about
// three times as many pairs, once per interval; now there may be five stretches.)
double normal_spring_energy_change(const System& system, double factor) {
  const auto x = system.positions();
  const auto r = system.radii();
  const auto materials = system.particle_materials();
  const auto pairs = system.candidate_pairs();
  // The box's constants once per pass, not per pair (Domain::separation's own, same bits).
  const PeriodicImages images(system.domain());
  return deterministic_sum(pairs.size(), kPairSumGrain, [&](std::size_t k) {
    if (!system.pair_touching(k)) return 0.0;
    const auto [i, j] = pairs[k];
    Vec3 separation = images.separation(x[i], x[j]);
    const double reach = r[i] + r[j];
    const double before = std::max(reach - separation.norm(), 0.0);
    separation.y() *= factor;
    const double after = std::max(reach - separation.norm(), 0.0);
    return 0.5 * system.materials().pair(materials[i], materials[j]).normal_stiffness *
           (after * after - before * before);
  });
}

}  // namespace

double stretch_along_y_keeping_profile(System& system, double shear_rate, double strain) {
  // Particles keep their velocity relative to the imposed profile gdot (y - y_mid), which
  // stretches with the box about its lower face like the positions.
  const double y_mid = system.domain().lo.y() + 0.5 * system.domain().length().y();
  const auto x = system.positions();
  const auto v = system.velocities();
  std::vector<Vec3> velocities(v.begin(), v.end());
  for (std::size_t p = 0; p < system.size(); ++p)
    velocities[p].x() += shear_rate * strain * (x[p].y() - y_mid);
  const double work = normal_spring_energy_change(system, 1.0 + strain);
  system.deform_affinely(1, 1.0 + strain);
  for (std::size_t p = 0; p < system.size(); ++p)
    system.set_velocity(static_cast<ParticleId>(p), velocities[p]);
  return work;
}

std::uint64_t sample_interval_across_control_phases(std::uint64_t every,
                                                    std::uint64_t control_interval) {
  every = std::max<std::uint64_t>(every, 1);
  if (control_interval <= 1) return every;
  while (std::gcd(every, control_interval) > 1) ++every;
  return every;
}

// Every step is sampled and the interval answers the mean: for the Lees-Edwards barostat
// single collisions of stiff balls make the instantaneous stress spike, and it rings after each
// stretch. (Samples every 4 steps of a 20-step interval, always at the same phases of it, held
// the collisional test cells' mean p_yy at 1071 Pa against a target of 1000, 16 seeds, 19 Pa
// standard error; every step: 971 +- 24 Pa, and 993 +- 25 Pa once the contact velocity's
// rounding changed. The kinetic part's pass over the particles costs nothing measurable:
// bench_cells' cement_load15 ran at 3.96 M particle-steps per CPU second sampled either way.)
bool StressControl::after_step(System& system) {
  stress_sum_ += normal_stress(system);
  stress_samples_ += 1.0;
  if (system.step_count() % settings_.interval_steps != 0) return between_answers(system);
  const double stress = stress_sum_ / stress_samples_;  // this step's sample included
  stress_sum_ = stress_samples_ = 0.0;
  last_stress_ = stress;
  // Over a single interval a flowing bed of stiff balls often carries nothing for a moment, so
  // whether it lost contact is judged on the running mean over tau.
  const double interval = static_cast<double>(settings_.interval_steps) * system.time_step();
  smoothed_stress_ +=
      (stress - smoothed_stress_) * std::min(1.0, interval / settings_.relaxation_time);
  const bool closing =
      at_speed_limit_ ||
      (recloses() && smoothed_stress_ < kClosingStressFraction * settings_.target_stress);
  return answer(system, stress, closing);
}

void StressControl::set_closing(bool closing) {
  at_speed_limit_ = closing;
  if (!closing) smoothed_stress_ = last_stress_;
}

void StressControl::write(BinaryWriter& out) const {
  for (double v : {stress_sum_, stress_samples_, last_stress_, smoothed_stress_}) out.put(v);
  out.put<std::uint8_t>(at_speed_limit_);
  write_own(out);
}

void StressControl::read(BinaryReader& in) {
  for (double* v : {&stress_sum_, &stress_samples_, &last_stress_, &smoothed_stress_})
    *v = in.get<double>();
  at_speed_limit_ = in.get<std::uint8_t>() != 0;
  read_own(in);
}

double RoughWallServo::normal_stress(const System& system) const {
  // The particles push the top wall up (+y) and the bottom one down.
  return 0.5 * (system.group_load(top_).force.y() - system.group_load(bottom_).force.y()) / area_;
}

bool RoughWallServo::answer(System& system, double stress, bool closing) {
  const StressControlSettings& s = settings();
  const double bed_pressure = std::min(smoothed_stress(), s.target_stress);
  if (closing || bed_pressure <= 0.0) {
    system.group(top_).velocity.y() = -s.max_speed;  // the integral term frozen
    return false;
  }
  // The interval's mean load F = stress A against F_t: v = (P + b) H / tau along +y (a wall
  // carrying too much moves up), H / tau = M K p_target A. The proportional part P = x p_target /
  // p_bed is M (F - F_t) at the bed's modulus at its own pressure (at most the target's); the
  // integral term b sees the plain x, so it settles only when the MEAN load is on target
  // (without it the mean sat 10-13% above the target in 5 x 10 x 5 d cells: docs/shear_cells.md).
  const double error = (stress - s.target_stress) / (kFlowingBedModulus * s.target_stress);
  const double interval = static_cast<double>(s.interval_steps) * system.time_step();
  const double gap_per_tau = s.mobility * kFlowingBedModulus * s.target_stress * area_;
  const double speed = gap_per_tau * ((s.target_stress / bed_pressure) * error +
                                      integral_.add(error, interval, s.relaxation_time));
  system.group(top_).velocity.y() = std::clamp(speed, -s.max_speed, s.max_speed);
  return false;
}

double LeesEdwardsBarostat::normal_stress(const System& system) const {
  // p_yy of the virial: contacts plus the kinetic part of the peculiar motion.
  double sum = -system.contact_virial()(1, 1);
  const auto v = system.velocities();
  const auto m = system.masses();
  for (std::size_t p = 0; p < system.size(); ++p) sum += m[p] * v[p].y() * v[p].y();
  return sum / system.domain().length().prod();
}

bool LeesEdwardsBarostat::answer(System& system, double stress, bool closing) {
  const StressControlSettings& s = settings();
  const double control_interval = static_cast<double>(s.interval_steps) * system.time_step();
  const double height = system.domain().length().y();
  const double error = (stress - s.target_stress) / (kFlowingBedModulus * s.target_stress);
  // The integral term sees the unclamped error, so it stays put only when the MEAN stress is on
  // target; it is frozen while closing and bounded by the clamp (anti-windup).
  if (!closing) integral_.add(error, control_interval, s.relaxation_time);
  const double proportional = std::clamp(error, -kBarostatMaxDilation, kBarostatMaxDilation);
  const double strain =
      closing ? -s.max_speed * control_interval / height
              : (proportional + integral_.value()) * control_interval / s.relaxation_time;
  // Spread over the interval, this step first; what the last interval left (one whose length is
  // no multiple of kBarostatStretchEvery) comes with it.
  pending_strain_ += strain;
  const auto most_parts = std::max<std::uint64_t>(1, s.interval_steps / kBarostatStretchEvery);
  const double parts =
      s.part_strain > 0.0 ? std::ceil(std::abs(pending_strain_) / s.part_strain) : 1.0;
  parts_left_ = static_cast<std::uint64_t>(std::clamp(parts, 1.0, static_cast<double>(most_parts)));
  return stretch_part(system);
}

bool LeesEdwardsBarostat::between_answers(System& system) {
  return system.step_count() % kBarostatStretchEvery == 0 && stretch_part(system);
}

bool LeesEdwardsBarostat::stretch_part(System& system) {
  if (parts_left_ == 0) return false;
  const double part = pending_strain_ / static_cast<double>(parts_left_);
  pending_strain_ -= part;
  --parts_left_;
  work_ += stretch_along_y_keeping_profile(system, settings().shear_rate, part);
  return true;
}

void LeesEdwardsBarostat::write_own(BinaryWriter& out) const {
  out.put(work_);
  integral_.write(out);
  out.put(pending_strain_);
  out.put(parts_left_);
}

void LeesEdwardsBarostat::read_own(BinaryReader& in) {
  work_ = in.get<double>();
  integral_.read(in);
  pending_strain_ = in.get<double>();
  parts_left_ = in.get<std::uint64_t>();
}

}  // namespace millflow::dem
