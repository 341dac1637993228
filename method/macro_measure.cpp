#include "method/macro_measure.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>

namespace millflow::method {
namespace {

constexpr double kSpectrumMin = 1e-12, kSpectrumMax = 1e4;
constexpr int kSpectrumBinsPerDecade = 5;

template <class T>
void put_vector(dem::BinaryWriter& out, const std::vector<T>& values) {
  out.put_span(std::span<const T>(values));
}

// [-90, 270): the toe (lower left) and the shoulder (right) never straddle the cut.
double reported_angle(double degrees) {
  double a = std::fmod(degrees, 360.0);
  if (a < 0.0) a += 360.0;
  return a >= 270.0 ? a - 360.0 : a;
}

}  // namespace

bool PowerMeter::add_step(double power) {
  sum_ += power;
  ++steps_;
  block_sum_ += power;
  ++block_steps_done_;
  return block_steps_done_ == block_steps_;
}

void PowerMeter::close_block(double time, double torque_arm_power) {
  times_.push_back(time);
  powers_.push_back(block_sum_ / static_cast<double>(block_steps_done_));
  torque_arm_.push_back(torque_arm_power);
  block_sum_ = 0.0;
  block_steps_done_ = 0;
}

double PowerMeter::mean() const {
  return steps_ > 0 ? sum_ / static_cast<double>(steps_) : 0.0;
}

double PowerMeter::standard_deviation() const {
  if (powers_.size() < 2) return 0.0;
  double mean = 0.0;
  for (double p : powers_) mean += p;
  mean /= static_cast<double>(powers_.size());
  double squares = 0.0;
  for (double p : powers_) squares += (p - mean) * (p - mean);
  return std::sqrt(squares / static_cast<double>(powers_.size() - 1));
}

double PowerMeter::torque_arm_mean() const {
  if (torque_arm_.empty()) return 0.0;
  double sum = 0.0;
  for (double p : torque_arm_) sum += p;
  return sum / static_cast<double>(torque_arm_.size());
}

void PowerMeter::write(dem::BinaryWriter& out) const {
  out.put(block_steps_);
  out.put(sum_);
  out.put(steps_);
  out.put(block_sum_);
  out.put(block_steps_done_);
  put_vector(out, times_);
  put_vector(out, powers_);
  put_vector(out, torque_arm_);
}

void PowerMeter::read(dem::BinaryReader& in) {
  if (in.get<std::uint64_t>() != block_steps_)
    throw dem::CorruptData("macro state: the power block length changed");
  sum_ = in.get<double>();
  steps_ = in.get<std::uint64_t>();
  block_sum_ = in.get<double>();
  block_steps_done_ = in.get<std::uint64_t>();
  times_ = in.get_vector<double>();
  powers_ = in.get_vector<double>();
  torque_arm_ = in.get_vector<double>();
}

double torque_arm_power(const dem::System& system, double omega) {
  double mass = 0.0, moment = 0.0;
  const auto groups = system.particle_groups();
  for (std::size_t p = 0; p < system.size(); ++p) {
    if (groups[p] != dem::kFreeParticle) continue;
    mass += system.masses()[p];
    moment += system.masses()[p] * system.positions()[p].x();
  }
  // The charge's weight -M g (along y) at arm x_com: the shell must supply torque +M g x_com.
  return -system.gravity().y() * moment * omega;
}

void ChargeShape::add_frame(const dem::FlowFrame& frame, std::uint32_t shell_wall) {
  for (std::size_t c = 0; c < frame.contact_a.size(); ++c) {
    if (!frame.contact_with_wall[c] || frame.contact_b[c] != shell_wall) continue;
    const auto& branch = frame.contact_branch[c];
    const double axial = std::abs(branch[2]), across = std::hypot(branch[0], branch[1]);
    if (axial > across) continue;  // an end wall
    const auto& point = frame.contact_point[c];
    double degrees = std::atan2(point[1], point[0]) * 180.0 / std::numbers::pi;
    if (degrees < 0.0) degrees += 360.0;
    const int bin = std::clamp(static_cast<int>(degrees / (360.0 / kBins)), 0, kBins - 1);
    counts_[static_cast<std::size_t>(bin)] += 1.0;
  }
}

std::optional<ChargeShape::Angles> ChargeShape::angles() const {
  const double fullest = *std::max_element(counts_.begin(), counts_.end());
  if (fullest <= 0.0) return std::nullopt;
  auto in_charge = [&](int bin) {
    return counts_[static_cast<std::size_t>(bin % kBins)] >= kThreshold * fullest;
  };
  int gap = 0;
  while (gap < kBins && in_charge(gap)) ++gap;
  if (gap == kBins) return std::nullopt;  // contacts all round: centrifuging
  // Walk once round the circle from the gap, keeping the longest run (the first on a tie).
  int best_start = 0, best_length = 0, start = 0, length = 0;
  for (int k = gap + 1; k <= gap + kBins; ++k) {
    if (in_charge(k)) {
      if (length == 0) start = k;
      ++length;
      if (length > best_length) best_start = start, best_length = length;
    } else {
      length = 0;
    }
  }
  const double width = 360.0 / kBins;
  return Angles{reported_angle(best_start * width),
                reported_angle((best_start + best_length) * width)};
}

void ChargeShape::write(dem::BinaryWriter& out) const {
  put_vector(out, counts_);
}

void ChargeShape::read(dem::BinaryReader& in) {
  counts_ = in.get_vector<double>();
  if (counts_.size() != static_cast<std::size_t>(kBins))
    throw dem::CorruptData("macro state: bad charge-shape bins");
}

CollisionStats::CollisionStats(std::vector<Tracked> tracked) {
  for (Tracked& t : tracked) {
    categories_.push_back(Category{
        std::move(t), dem::LogHistogram(kSpectrumMin, kSpectrumMax, kSpectrumBinsPerDecade),
        dem::LogHistogram(kSpectrumMin, kSpectrumMax, kSpectrumBinsPerDecade)});
  }
}

void CollisionStats::add(std::span<const dem::CollisionEvent> events) {
  for (const dem::CollisionEvent& event : events) {
    for (Category& c : categories_) {
      if (c.tracked.category != event.category) continue;
      c.impact.add(event.impact_energy);
      c.dissipated.add(event.dissipated);
      ++c.count;
      c.impact_sum += event.impact_energy;
      c.dissipated_sum += event.dissipated;
    }
  }
}

std::vector<double> CollisionStats::bin_edges() const {
  return categories_.empty() ? std::vector<double>{}
                             : method::bin_edges(categories_.front().impact);
}

std::map<std::string, MacroCollisions> CollisionStats::collisions(double duration,
                                                                  const dem::System& system) const {
  std::map<std::string, MacroCollisions> out;
  for (const Category& c : categories_) {
    const double n = static_cast<double>(c.count);
    out[c.tracked.label] = {.category = system.category_name(c.tracked.category),
                            .count = c.count,
                            .rate_per_s = n / duration,
                            .mean_impact_energy_j = c.count ? c.impact_sum / n : 0.0,
                            .mean_dissipated_j = c.count ? c.dissipated_sum / n : 0.0,
                            .dissipated_power_w = c.dissipated_sum / duration,
                            .impact_energy = energy_histogram(c.impact),
                            .dissipated_energy = energy_histogram(c.dissipated)};
  }
  return out;
}

void CollisionStats::write(dem::BinaryWriter& out) const {
  out.put<std::uint64_t>(categories_.size());
  for (const Category& c : categories_) {
    out.put(c.tracked.category);
    c.impact.write(out);
    c.dissipated.write(out);
    out.put(c.count);
    out.put(c.impact_sum);
    out.put(c.dissipated_sum);
  }
}

void CollisionStats::read(dem::BinaryReader& in) {
  if (in.get<std::uint64_t>() != categories_.size())
    throw dem::CorruptData("macro state: tracked categories changed");
  for (Category& c : categories_) {
    if (in.get<std::uint32_t>() != c.tracked.category)
      throw dem::CorruptData("macro state: tracked categories changed");
    c.impact = dem::LogHistogram::read(in);
    c.dissipated = dem::LogHistogram::read(in);
    c.count = in.get<std::uint64_t>();
    c.impact_sum = in.get<double>();
    c.dissipated_sum = in.get<double>();
  }
}

void write_events(dem::BinaryWriter& out, std::span<const dem::CollisionEvent> events) {
  out.put<std::uint64_t>(events.size());
  for (const dem::CollisionEvent& e : events) {
    out.put(e.category);
    out.put(e.a);
    out.put(e.b);
    out.put<std::uint8_t>(e.with_wall ? 1 : 0);
    for (double v : {e.start_time, e.duration, e.impact_speed, e.impact_energy, e.dissipated,
                     e.point.x(), e.point.y(), e.point.z()}) {
      out.put(v);
    }
  }
}

std::vector<dem::CollisionEvent> read_events(dem::BinaryReader& in) {
  std::vector<dem::CollisionEvent> events(in.get<std::uint64_t>());
  for (dem::CollisionEvent& e : events) {
    e.category = in.get<std::uint32_t>();
    e.a = in.get<std::uint32_t>();
    e.b = in.get<std::uint32_t>();
    e.with_wall = in.get<std::uint8_t>() != 0;
    for (double* v : {&e.start_time, &e.duration, &e.impact_speed, &e.impact_energy, &e.dissipated})
      *v = in.get<double>();
    for (int axis = 0; axis < 3; ++axis) e.point[axis] = in.get<double>();
  }
  return events;
}

void FrameMeans::add_frame(const dem::FlowFrame& frame) {
  if (frame.position.size() != masses_.size()) {
    throw std::invalid_argument(fmt::format("flow frame at t = {} holds {} balls, the run {}",
                                            frame.time, frame.position.size(), masses_.size()));
  }
  double mass = 0.0, x = 0.0, y = 0.0, translational = 0.0, rotational = 0.0;
  for (std::size_t p = 0; p < masses_.size(); ++p) {
    const double m = masses_[p], r = frame.radius[p];
    const auto& v = frame.velocity[p];
    const auto& w = frame.angular_velocity[p];
    mass += m;
    x += m * frame.position[p][0];
    y += m * frame.position[p][1];
    translational += 0.5 * m * (double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]);
    rotational +=
        0.5 * 0.4 * m * r * r * (double(w[0]) * w[0] + double(w[1]) * w[1] + double(w[2]) * w[2]);
  }
  for (std::size_t c = 0; c < frame.contact_a.size(); ++c) {
    if (frame.contact_with_wall[c] == 0) continue;
    const auto& point = frame.contact_point[c];
    const auto& force = frame.contact_force[c];
    const double torque = double(point[0]) * force[1] - double(point[1]) * force[0];
    const double radius = std::hypot(double(point[0]), double(point[1]));
    if (point[2] <= tolerance_ || point[2] >= shell_.length - tolerance_) {
      if (shell_.end_walls) {
        end_walls_ += torque;
        continue;
      }
    }
    (radius >= shell_.radius - tolerance_ ? liner_ : lifters_) += torque;
  }
  translational_ += translational;
  rotational_ += rotational;
  com_x_ += x / mass;
  com_y_ += y / mass;
  ++frames_;
}

MacroFrameMeans FrameMeans::means(double omega) const {
  const double n = frames_ > 0 ? static_cast<double>(frames_) : 1.0;
  const double total = (liner_ + lifters_ + end_walls_) / n;
  return {.frames = frames_,
          .kinetic_translational_j = translational_ / n,
          .kinetic_rotational_j = rotational_ / n,
          .centre_of_mass_x_m = com_x_ / n,
          .centre_of_mass_y_m = com_y_ / n,
          .liner_torque_n_m = liner_ / n,
          .lifter_torque_n_m = lifters_ / n,
          .end_wall_torque_n_m = end_walls_ / n,
          .drive_torque_n_m = total,
          .drive_power_w = total * omega};
}

}  // namespace millflow::method
