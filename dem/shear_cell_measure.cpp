// The shear cell's measured window: samples, blocks, overlaps, stresses and standard errors.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dem/shear_cell.hpp"
#include "dem/touching_pairs.hpp"

namespace millflow::dem {
namespace {

// Blocks between the measured window's wall-speed control points.
const std::size_t kMeasuredControlBlocks = static_cast<std::size_t>(
    std::lround(WallSpeedController::kMeasuredControlStrain / kBlockStrain));

// Tallies a measurement's collisions by contact type as they finish: the count and the spectrum
// of the energy each dissipated.
class CollisionTally final : public CollisionSink {
 public:
  CollisionTally(const ShearCell& cell, std::array<CollisionStats, kContactTypeCount>& stats)
      : cell_(cell), stats_(stats) {}
  void add(const CollisionEvent& event) override {
    CollisionStats& s = stats_[static_cast<std::size_t>(cell_.contact_type(event.category))];
    s.count += 1.0;
    s.dissipated_energy.add(event.dissipated);
  }

 private:
  const ShearCell& cell_;
  std::array<CollisionStats, kContactTypeCount>& stats_;
};

CollisionStats merged(const std::array<CollisionStats, kContactTypeCount>& stats,
                      std::initializer_list<ContactType> types) {
  CollisionStats total;
  for (ContactType type : types) {
    const CollisionStats& s = stats[static_cast<std::size_t>(type)];
    total.count += s.count;
    total.rate_per_volume += s.rate_per_volume;
    total.dissipated_energy.merge(s.dissipated_energy);
  }
  return total;
}

// The smallest multiple of `every` above `done`.
std::uint64_t next_multiple(std::uint64_t done, std::uint64_t every) {
  return (done / every + 1) * every;
}

bool involves_powder(ContactType type) {
  return type == ContactType::MediaPowder || type == ContactType::PowderPowder ||
         type == ContactType::WallPowder;
}

// Per-block series of the quantities with standard errors.
struct BlockSeries {
  std::vector<double> shear, normal, pressure, friction, friction_mean_pressure, power, powder,
      total;
  std::array<std::vector<double>, kContactTypeCount> dissipation;
};

}  // namespace

void ShearCell::OverlapHistogram::add(double fraction) {
  if (counts.empty()) counts.assign(kOverlapBins, 0.0);
  const auto bin = static_cast<std::size_t>(std::max(0.0, fraction) / kOverlapBinWidth);
  counts[std::min(bin, kOverlapBins - 1)] += 1.0;
  sum += fraction;
  max = std::max(max, fraction);
}

OverlapStats ShearCell::OverlapHistogram::stats() const {
  OverlapStats out;
  for (double c : counts) out.contacts += c;
  if (out.contacts == 0.0) return out;
  out.mean_fraction = sum / out.contacts;
  out.max_fraction = max;
  // The upper edge of the bin in which 95% of the samples are reached.
  double below = 0.0;
  for (std::size_t b = 0; b < counts.size(); ++b) {
    below += counts[b];
    if (below >= 0.95 * out.contacts) {
      out.p95_fraction = std::min(max, static_cast<double>(b + 1) * kOverlapBinWidth);
      break;
    }
  }
  return out;
}

ShearCellMeasurements ShearCell::measure(double strain, const MeasureOptions& options) {
  Measurement measurement = start_measurement(strain, options);
  advance_measurement(measurement, measurement.steps);
  return finish_measurement(measurement);
}

ShearCell::Measurement ShearCell::start_measurement(double strain, const MeasureOptions& options) {
  if (options.samples < 2 || !(options.steady_tolerance > 0.0) ||
      !(options.standard_error_target > 0.0)) {
    throw std::invalid_argument(
        fmt::format("shear cell: measure needs samples = {} >= 2, steady tolerance = {} > 0 and "
                    "standard error target = {} > 0",
                    options.samples, options.steady_tolerance, options.standard_error_target));
  }
  Measurement m;
  m.options = options;
  m.min_steps = steps_for_strain(strain);
  if (m.min_steps < 2)
    throw std::invalid_argument(
        fmt::format("shear cell: strain = {} is less than two time steps", strain));
  m.steps = std::max(m.min_steps, steps_for_strain(options.max_strain));
  // At every phase of the stress control's interval (the barostat's stretches make the stress
  // ring: sample_interval_across_control_phases).
  m.every = sample_interval_across_control_phases(
      m.min_steps / static_cast<std::uint64_t>(options.samples),
      control_->settings().interval_steps);
  // Wall loads are free to read every step; the LE virial costs a pass over the contacts.
  m.stress_every = walls() ? 1 : m.every;
  m.block_steps = std::max<std::uint64_t>(1, steps_for_strain(kBlockStrain));
  compact();  // before the window opens: compaction is no part of the measurement
  m.work0 = work_in();
  m.shear_work0 = shear_work();
  m.motion0 = motion_energy();
  m.budget0 = system_.energy();
  m.dissipation0 = system_.dissipation_by_category();
  start_block(m);
  if (walls()) speed_controller_.start_measured_window();
  if (options.record_collisions) {
    system_.take_collision_events();
    system_.set_record_collisions(true);
  }
  return m;
}

void ShearCell::start_block(Measurement& m) {
  m.current = MeasuredBlock{};
  m.block_shear_work0 = shear_work();
  m.block_dissipation0.clear();
  for (const Dissipation& d : system_.dissipation_by_category())
    m.block_dissipation0.push_back(d.total());
}

void ShearCell::close_block(Measurement& m) {
  MeasuredBlock& b = m.current;
  b.shear_work = shear_work() - m.block_shear_work0;
  const std::vector<Dissipation> now = system_.dissipation_by_category();
  for (std::size_t c = 0; c < now.size(); ++c) {
    b.dissipated[static_cast<std::size_t>(contact_type(static_cast<std::uint32_t>(c)))] +=
        now[c].total() - m.block_dissipation0[c];
  }
  m.blocks.push_back(b);
  start_block(m);
}

void ShearCell::advance_measurement(Measurement& m, std::uint64_t max_steps) {
  const auto started = std::chrono::steady_clock::now();
  // The window's collisions are tallied as they finish (while it records them): none is kept.
  CollisionTally tally(*this, m.collisions);
  const ScopedCollisionSink tallying(system_, tally);
  const std::uint64_t end = std::min(m.steps, m.done + max_steps);
  while (m.done < end && !m.converged) {
    // The steps up to the next sample or block end in one call: each call works out the LE
    // boundary's power at its start, which the call before ended on (nothing between the steps
    // changes the state, so the bits are those of one call per step, at half the power passes).
    const std::uint64_t s =
        std::min({end, next_multiple(m.done, m.stress_every), next_multiple(m.done, m.every),
                  next_multiple(m.done, m.block_steps)});
    advance(s - m.done);
    for (; m.done < s; ++m.done) m.current.duration += system_.time_step();
    if (s % m.stress_every == 0) {
      m.current.shear_sum += shear_stress_now();
      m.current.normal_sum += normal_stress_now();
      m.current.gap_sum += gap();
      m.current.stress_samples += 1.0;
    }
    if (s % m.every == 0) sample_measurement(m);
    if (s % m.block_steps == 0 && m.current.stress_samples > 0.0) {
      close_block(m);
      m.converged = s >= m.min_steps && errors_within_target(m);
      if (walls() && !m.converged && s < m.steps && m.blocks.size() % kMeasuredControlBlocks == 0)
        control_measured_wall_speed(m);
    }
  }
  m.wall_seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
}

void ShearCell::control_measured_wall_speed(const Measurement& m) {
  const double time = static_cast<double>(m.done) * system_.time_step();
  const double rate = bulk_shear_rate(m.profile);
  const double speed = speed_controller_.update_measured(rate, time, wall_speed_, gap());
  spdlog::debug(
      "shear cell: measured strain {:.3g}: the window's bulk rate {:.4g} 1/s (target {:.4g}), "
      "wall speed {:.4g} -> {:.4g} m/s",
      setup_.shear_rate * time, rate, setup_.shear_rate, wall_speed_, speed);
  set_wall_speed(speed);
}

void ShearCell::sample_measurement(Measurement& m) {
  sample_profile(m.profile);
  const std::array<double, 6> tensor = stress_tensor_now();
  for (std::size_t k = 0; k < 6; ++k) m.tensor_sum[k] += tensor[k];
  m.tensor_samples += 1.0;
  m.current.pressure_sum += (tensor[0] + tensor[1] + tensor[2]) / 3.0;
  m.current.pressure_samples += 1.0;
  sample_overlaps(m);
}

void ShearCell::sample_overlaps(Measurement& m) const {
  const auto pairs = system_.candidate_pairs();
  const auto r = system_.radii();
  const auto materials = system_.particle_materials();
  const std::size_t n = system_.materials().size();
  for_each_touching_pair(system_, [&](std::size_t k, const Vec3&, const Vec3& branch) {
    const std::uint32_t i = pairs[k].i, j = pairs[k].j;
    const double overlap = r[i] + r[j] - branch.norm();
    const auto category = static_cast<std::uint32_t>(materials[i] * n + materials[j]);
    m.overlaps[static_cast<std::size_t>(contact_type(category))].add(overlap /
                                                                     (2.0 * std::min(r[i], r[j])));
  });
}

std::array<double, 6> ShearCell::stress_tensor_now() const {
  static constexpr std::array<std::array<int, 2>, 6> kComponents{
      {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}}};
  std::array<double, 6> sum{};
  for_each_touching_pair(system_, [&](std::size_t, const Vec3& f, const Vec3& b) {
    for (std::size_t c = 0; c < 6; ++c) {
      const auto [a, e] = kComponents[c];
      sum[c] -= 0.5 * (f[a] * b[e] + f[e] * b[a]);
    }
  });
  // Kinetic part of the motion relative to the linear profile (free particles only).
  const auto x = system_.positions();
  const auto v = system_.velocities();
  const auto mass = system_.masses();
  const auto groups = system_.particle_groups();
  const double y0 = walls() ? x[0].y() : system_.domain().lo.y();
  const double height = gap();
  const double rate = walls() ? wall_speed_ / height : setup_.shear_rate;
  for (std::size_t p = 0; p < system_.size(); ++p) {
    if (groups[p] != kFreeParticle) continue;
    const Vec3 c = v[p] - Vec3(rate * (x[p].y() - y0 - 0.5 * height), 0.0, 0.0);
    for (std::size_t k = 0; k < 6; ++k) {
      const auto [a, e] = kComponents[k];
      sum[k] += mass[p] * c[a] * c[e];
    }
  }
  const double volume = wall_area() * height;
  for (double& s : sum) s /= volume;
  return sum;
}

void ShearCell::tally_collisions(Measurement& m) {
  CollisionTally tally(*this, m.collisions);
  const ScopedCollisionSink draining(system_, tally);  // installing it hands it what is buffered
}

namespace {

BlockSeries block_series(const std::vector<MeasuredBlock>& blocks, double area) {
  BlockSeries s;
  for (const MeasuredBlock& b : blocks) {
    const double shear = b.shear_sum / b.stress_samples, normal = b.normal_sum / b.stress_samples;
    const double pressure = b.pressure_samples > 0.0 ? b.pressure_sum / b.pressure_samples : normal;
    const double volume_time = area * b.gap_sum / b.stress_samples * b.duration;
    s.shear.push_back(shear);
    s.normal.push_back(normal);
    s.pressure.push_back(pressure);
    s.friction.push_back(shear / normal);
    s.friction_mean_pressure.push_back(shear / pressure);
    s.power.push_back(b.shear_work / volume_time);
    double powder = 0.0, total = 0.0;
    for (std::size_t t = 0; t < kContactTypeCount; ++t) {
      const double rate = b.dissipated[t] / volume_time;
      s.dissipation[t].push_back(rate);
      total += rate;
      if (involves_powder(static_cast<ContactType>(t))) powder += rate;
    }
    s.powder.push_back(powder);
    s.total.push_back(total);
  }
  return s;
}

// Relative standard error, or 0 for a quantity that is zero throughout (no powder).
double relative_error(const MeanWithError& e) {
  return e.mean != 0.0 ? e.standard_error / std::abs(e.mean) : 0.0;
}

std::size_t batch_length(const BlockSeries& s) {
  return std::max(uncorrelated_batch_blocks(s.friction), uncorrelated_batch_blocks(s.powder));
}

}  // namespace

bool ShearCell::errors_within_target(const Measurement& m) const {
  if (m.blocks.size() < 2 * kMinBatches) return false;
  const BlockSeries s = block_series(m.blocks, wall_area());
  const std::size_t batch = batch_length(s);
  const double target = m.options.standard_error_target;
  return relative_error(batch_mean(s.friction, batch)) <= target &&
         relative_error(batch_mean(s.powder, batch)) <= target;
}

void ShearCell::fill_standard_errors(const Measurement& in, ShearCellMeasurements& m) const {
  m.blocks = in.blocks.size();
  if (in.blocks.empty()) return;
  const BlockSeries s = block_series(in.blocks, wall_area());
  const std::size_t batch = batch_length(s);
  m.batch_blocks = batch;
  m.friction_error = batch_mean(s.friction, batch);
  m.friction_mean_pressure_error = batch_mean(s.friction_mean_pressure, batch);
  m.shear_stress_error = batch_mean(s.shear, batch);
  m.normal_stress_error = batch_mean(s.normal, batch);
  m.power_density_error = batch_mean(s.power, batch);
  m.powder_dissipation_error = batch_mean(s.powder, batch);
  m.dissipation_total_error = batch_mean(s.total, batch);
  for (std::size_t t = 0; t < kContactTypeCount; ++t)
    m.dissipation_standard_error[t] = batch_mean(s.dissipation[t], batch).standard_error;
  const double target = in.options.standard_error_target;
  m.converged = relative_error(m.friction_error) <= target &&
                relative_error(m.powder_dissipation_error) <= target &&
                in.blocks.size() >= 2 * kMinBatches;
}

ShearCellMeasurements ShearCell::finish_measurement(Measurement& in) {
  tally_collisions(in);  // a relief's, if one ran after the last steps of the window
  if (in.options.record_collisions) system_.set_record_collisions(false);
  ShearCellMeasurements m;
  m.collisions = in.collisions;
  m.wall_seconds = in.wall_seconds;
  m.steps = in.done;
  m.duration = static_cast<double>(in.done) * system_.time_step();
  m.strain = setup_.shear_rate * m.duration;
  m.particle_steps_per_second = static_cast<double>(in.done * system_.size()) / m.wall_seconds;
  m.target_shear_rate = setup_.shear_rate;
  m.bulk_shear_rate = bulk_shear_rate(in.profile);
  // With walls the walls' mean speed over the window (the catch-up law moves it).
  m.wall_speed = walls() ? speed_controller_.measured_mean_speed(
                               static_cast<double>(in.done) * system_.time_step(), wall_speed_)
                         : wall_speed_;

  // Whole-window sums over the blocks and the one in progress; halves by block.
  std::vector<MeasuredBlock> blocks = in.blocks;
  if (in.current.stress_samples > 0.0) blocks.push_back(in.current);
  double shear = 0.0, normal = 0.0, gap_sum = 0.0, samples = 0.0;
  std::array<double, 2> half_shear{}, half_samples{};
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const MeasuredBlock& b = blocks[k];
    shear += b.shear_sum;
    normal += b.normal_sum;
    gap_sum += b.gap_sum;
    samples += b.stress_samples;
    const std::size_t half = 2 * k < blocks.size() ? 0 : 1;
    half_shear[half] += b.shear_sum;
    half_samples[half] += b.stress_samples;
  }
  m.gap = gap_sum / samples;
  m.nominal_shear_rate = m.wall_speed / m.gap;
  m.wall_slip = 0.5 * (m.wall_speed - m.bulk_shear_rate * m.gap);
  m.volume = wall_area() * m.gap;
  m.shear_stress_first_half = half_shear[0] / half_samples[0];
  m.shear_stress_second_half =
      half_samples[1] > 0.0 ? half_shear[1] / half_samples[1] : m.shear_stress_first_half;
  m.shear_stress = shear / samples;
  m.normal_stress = normal / samples;
  m.friction = m.shear_stress / m.normal_stress;
  for (std::size_t k = 0; k < 6; ++k) m.stress_tensor[k] = in.tensor_sum[k] / in.tensor_samples;
  m.mean_pressure = (m.stress_tensor[0] + m.stress_tensor[1] + m.stress_tensor[2]) / 3.0;
  m.friction_mean_pressure = m.shear_stress / m.mean_pressure;
  const double pressure_scale =
      setup_.media_diameter / std::sqrt(m.normal_stress / setup_.media.density);
  m.inertial_number_measured_rate = m.bulk_shear_rate * pressure_scale;
  m.inertial_number = (walls() ? m.bulk_shear_rate : setup_.shear_rate) * pressure_scale;
  m.media_solid_fraction = in.profile.media_volume / in.profile.slab_volume;
  m.powder_solid_fraction = in.profile.powder_volume / in.profile.slab_volume;
  m.steady_state_deviation =
      std::abs(m.shear_stress_first_half - m.shear_stress_second_half) /
      (0.5 * std::abs(m.shear_stress_first_half + m.shear_stress_second_half));
  m.steady = m.steady_state_deviation <= in.options.steady_tolerance;

  for (std::size_t t = 0; t < kContactTypeCount; ++t) {
    m.overlaps[t] = in.overlaps[t].stats();
    if (m.overlaps[t].p95_fraction > setup_.overlap_bound.p95_fraction) m.overlap_ok = false;
  }

  const double volume_time = m.volume * m.duration;
  const std::vector<Dissipation> dissipation1 = system_.dissipation_by_category();
  for (std::size_t c = 0; c < dissipation1.size(); ++c) {
    const double joules = dissipation1[c].total() - in.dissipation0[c].total();
    m.dissipation_density[static_cast<std::size_t>(contact_type(static_cast<std::uint32_t>(c)))] +=
        joules / volume_time;
  }
  for (double d : m.dissipation_density) m.dissipation_density_total += d;
  for (CollisionStats& s : m.collisions) s.rate_per_volume = s.count / volume_time;
  m.media_collisions = merged(m.collisions, {ContactType::MediaMedia, ContactType::WallMedia});
  m.powder_collisions = merged(
      m.collisions, {ContactType::MediaPowder, ContactType::PowderPowder, ContactType::WallPowder});

  const EnergyBudget budget1 = system_.energy();
  m.work_in = work_in() - in.work0;
  m.power_density = (shear_work() - in.shear_work0) / volume_time;
  m.stress_control_work = m.work_in - (shear_work() - in.shear_work0);
  m.kinetic_change = motion_energy() - in.motion0;
  m.elastic_change = budget1.elastic - in.budget0.elastic;
  m.dissipated = budget1.dissipated - in.budget0.dissipated;
  m.energy_balance_error =
      std::abs(m.work_in - (m.kinetic_change + m.elastic_change + m.dissipated)) /
      std::abs(m.work_in);
  fill_standard_errors(in, m);
  return m;
}

}  // namespace millflow::dem
