#pragma once
// What a `macro` run measures over its measurement window, as accumulators that a checkpoint
// saves and restores bit for bit (write/read), so an interrupted run reports the same numbers.
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "dem/binary_io.hpp"
#include "dem/flow_sample.hpp"
#include "dem/spectrum.hpp"
#include "dem/system.hpp"
#include "dem/wall_geometry.hpp"
#include "method/macro_result.hpp"

namespace millflow::method {

// Power drawn by the shell, P = -torque_z(shell) x omega, every step. The mean is over every
// step of the window; the time series holds block means of `block_steps` steps (about 200 per
// revolution), and its standard deviation is the reported fluctuation. Beside each block mean
// the torque-arm power M g x_com omega at the block's end.
class PowerMeter {
 public:
  explicit PowerMeter(std::uint64_t block_steps) : block_steps_(block_steps) {}

  // Adds one step's power; true when the step completes a block (then call close_block).
  bool add_step(double power);
  // Closes the block (or the partial last one) at time t with the torque-arm power now.
  void close_block(double time, double torque_arm_power);
  bool block_open() const { return block_steps_done_ > 0; }

  double mean() const;
  double standard_deviation() const;  // of the block means
  double torque_arm_mean() const;
  std::span<const double> times() const { return times_; }
  std::span<const double> powers() const { return powers_; }
  std::span<const double> torque_arm_powers() const { return torque_arm_; }

  void write(dem::BinaryWriter& out) const;
  void read(dem::BinaryReader& in);

 private:
  std::uint64_t block_steps_;
  double sum_ = 0.0;
  std::uint64_t steps_ = 0;
  double block_sum_ = 0.0;
  std::uint64_t block_steps_done_ = 0;
  std::vector<double> times_, powers_, torque_arm_;
};

// M g x_com omega: the power that holds the charge's centre of mass at horizontal offset x_com
// from the axis against gravity (along -y) while the mill turns at omega (counter-clockwise).
double torque_arm_power(const dem::System& system, double omega);

// Charge shape from where the balls touch the shell and the lifters, in every flow frame.
// Angles are in degrees, measured counter-clockwise from the 3 o'clock position (+x) seen from
// +z, the mill turning counter-clockwise and gravity along -y, so the charge is lifted on the
// right. The contact points (end-wall contacts left out) are counted in 3 degree bins around the
// axis; the charge's arc is the longest run of bins holding at least 10% of the fullest bin's
// count. The toe is where that arc starts (its clockwise end, lower left, usually 180-270) and
// the shoulder where it ends (its counter-clockwise end, right, usually -90..90): reported in
// [-90, 270). None when the arc is the whole circle (centrifuging) or no contact was seen.
class ChargeShape {
 public:
  static constexpr int kBins = 120;
  static constexpr double kThreshold = 0.1;

  void add_frame(const dem::FlowFrame& frame, std::uint32_t shell_wall);
  struct Angles {
    double toe_deg;
    double shoulder_deg;
  };
  std::optional<Angles> angles() const;
  std::span<const double> counts() const { return counts_; }

  void write(dem::BinaryWriter& out) const;
  void read(dem::BinaryReader& in);

 private:
  std::vector<double> counts_ = std::vector<double>(kBins, 0.0);
};

// Collision counts, energies and spectra (impact energy and dissipated energy per collision, on
// log bins from 1e-12 to 1e4 J, 5 per decade) of the tracked categories.
class CollisionStats {
 public:
  struct Tracked {
    std::string label;       // e.g. "ball_ball"
    std::uint32_t category;  // dem::System category
  };
  explicit CollisionStats(std::vector<Tracked> tracked);

  void add(std::span<const dem::CollisionEvent> events);
  // By label: counts, rates per second over `duration`, mean energies, dissipated power and
  // spectra; the spectra's shared bin edges (none without a tracked category).
  std::map<std::string, MacroCollisions> collisions(double duration,
                                                    const dem::System& system) const;
  std::vector<double> bin_edges() const;

  void write(dem::BinaryWriter& out) const;
  void read(dem::BinaryReader& in);

 private:
  struct Category {
    Tracked tracked;
    dem::LogHistogram impact, dissipated;
    std::uint64_t count = 0;
    double impact_sum = 0.0, dissipated_sum = 0.0;
  };
  std::vector<Category> categories_;
};

// Means over the measurement's flow frames (sampled every sample interval, so they fluctuate
// more than the every-step power): the charge's kinetic energy, translational sum m v^2 / 2 and
// rotational sum I w^2 / 2 (I = 2 m r^2 / 5), its centre of mass in the cross-section, and the
// torque about the axis the drive supplies against the balls' contacts, split by where they
// touch: the liner (contact points within a tenth of the smallest ball radius of the shell
// radius), the end walls (as close to z = 0 or z = length) and the lifters (every other wall
// contact). Torque z = sum (p x F)_z over the wall contacts, F the force on the ball, positive
// when the drive works against the charge (the power it draws is torque x omega).
class FrameMeans {
 public:
  FrameMeans(const dem::MillShell& shell, std::span<const double> masses, double smallest_radius)
      : shell_(shell), masses_(masses.begin(), masses.end()), tolerance_(0.1 * smallest_radius) {}

  // Throws std::invalid_argument for a frame whose balls are not the masses' balls.
  void add_frame(const dem::FlowFrame& frame);
  // The means over the frames added, and the power omega x total torque.
  MacroFrameMeans means(double omega) const;

 private:
  dem::MillShell shell_;
  std::vector<double> masses_;
  double tolerance_;
  std::uint64_t frames_ = 0;
  double translational_ = 0.0, rotational_ = 0.0, com_x_ = 0.0, com_y_ = 0.0;
  double liner_ = 0.0, lifters_ = 0.0, end_walls_ = 0.0;
};

// Collision events as the checkpoint state stores them (taken before a checkpoint, handed to the
// next flow frame after it).
void write_events(dem::BinaryWriter& out, std::span<const dem::CollisionEvent> events);
std::vector<dem::CollisionEvent> read_events(dem::BinaryReader& in);

}  // namespace millflow::method
