#pragma once
// Flow-sample frames of a slowly turning mill for the analysis tests (tests/dem/scenes.hpp's 0.2 m
// slice, J = 0.4, 20% of critical speed) and for bench/bench_slow_mill_flow.cpp (bigger mills), and
// a macro result describing them.
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "dem/flow_sample.hpp"
#include "dem/mill_setup.hpp"
#include "method/macro_result.hpp"

namespace millflow::tasks::testing {

struct MillSample {
  std::vector<std::filesystem::path> segments;  // flow/segment_NNNN.mfs, in order
  nlohmann::json macro_result;                  // what the macro task reports about the run
};

// Builds and settles `setup`'s mill, turns it at its speed fraction for `spin_up` s, then writes
// one segment of `frames_per_segment` frames `interval` s apart to each of `segments`; each frame
// carries the collisions of the interval before it. Returns what the macro task would report.
inline nlohmann::json run_and_write_mill_frames(const dem::MillSetup& setup, double spin_up,
                                                double interval,
                                                const std::vector<std::filesystem::path>& segments,
                                                int frames_per_segment) {
  dem::System system = dem::build_mill(setup);
  system.set_time_step_from_collisions(20);
  dem::settle_charge(system, 1.0, 1e-6);
  const double omega =
      setup.speed_fraction * dem::critical_speed(2 * setup.shell.radius, setup.ball_diameter);
  dem::set_mill_speed(system, omega);
  system.step(static_cast<std::size_t>(spin_up / system.time_step()));
  system.set_record_collisions(true);
  system.take_collision_events();
  const double start = system.time();
  const auto steps = static_cast<std::size_t>(std::lround(interval / system.time_step()));
  for (const auto& segment : segments) {
    std::vector<dem::FlowFrame> frames;
    for (int f = 0; f < frames_per_segment; ++f) {
      system.step(steps);
      const auto events = system.take_collision_events();
      frames.push_back(
          dem::capture_frame(system, std::get<dem::MillWall>(system.wall(0).shape).angle, events));
    }
    dem::write_flow_segment(segment, frames);
  }
  double mass = 0.0;
  for (double m : system.masses()) mass += m;
  std::vector<std::string> categories;
  for (std::uint32_t k = 0; k < system.category_count(); ++k)
    categories.push_back(system.category_name(k));
  // What the analysis tasks read; the measurements they do not read are left at zero.
  method::MacroResult r;
  r.n_balls = system.size();
  r.ball_mass_kg = mass;
  r.media_diameter_m = setup.ball_diameter;
  r.dt_s = system.time_step();
  r.angular_velocity_rad_s = omega;
  r.speed_fraction = setup.speed_fraction;
  r.fill = setup.fill;
  r.gravity_m_s2 = setup.gravity;
  r.mill = {.radius_m = setup.shell.radius,
            .length_m = setup.shell.length,
            .axial_ends = "periodic",
            .lifter_count = setup.shell.lifter_count};
  r.measure_start_s = start;
  r.measure_end_s = system.time();
  r.sample_interval_s = static_cast<double>(steps) * system.time_step();
  r.frame_count = segments.size() * static_cast<std::size_t>(frames_per_segment);
  r.segment_count = segments.size();
  r.categories = categories;
  return r;
}

// The analysis tests' sample. Built once per build directory (cached under
// MILLFLOW_BINARY_DIR/test_data; deterministic).
const MillSample& small_mill_sample();

}  // namespace millflow::tasks::testing
