#include <fmt/format.h>
#include <unistd.h>

#include <cmath>
#include <fstream>

#include "dem/mill_setup.hpp"
#include "tests/dem/scenes.hpp"
#include "tests/tasks/mill_frames.hpp"

namespace millflow::tasks::testing {
namespace {

constexpr double kFill = 0.4, kSpeedFraction = 0.2, kSpinUp = 0.5, kInterval = 0.02;
constexpr int kSegments = 3, kFramesPerSegment = 8;
constexpr const char* kCacheVersion = "v2";

std::filesystem::path cache_dir() {
  return std::filesystem::path(MILLFLOW_BINARY_DIR) / "test_data" / fmt::format("small_mill_{}", kCacheVersion);
}

// Settles, spins up, then writes kSegments segments of frames kInterval apart; each frame carries
// the collisions of the interval before it.
nlohmann::json run_and_write(const std::vector<std::filesystem::path>& segments) {
  const dem::MillSetup setup = dem::testing::small_mill(kFill, kSpeedFraction);
  dem::System system = dem::build_mill(setup);
  system.set_time_step_from_collisions(20);
  dem::settle_charge(system, 1.0, 1e-6);
  const double omega = kSpeedFraction * dem::critical_speed(0.2, 0.01);
  dem::set_mill_speed(system, omega);
  system.step(static_cast<std::size_t>(kSpinUp / system.time_step()));
  system.set_record_collisions(true);
  system.take_collision_events();
  const double start = system.time();
  const auto steps = static_cast<std::size_t>(std::lround(kInterval / system.time_step()));
  for (const auto& segment : segments) {
    std::vector<dem::FlowFrame> frames;
    for (int f = 0; f < kFramesPerSegment; ++f) {
      system.step(steps);
      const auto events = system.take_collision_events();
      frames.push_back(dem::capture_frame(system, std::get<dem::MillWall>(system.wall(0).shape).angle, events));
    }
    dem::write_flow_segment(segment, frames);
  }
  double mass = 0.0;
  for (double m : system.masses()) mass += m;
  std::vector<std::string> categories;
  for (std::uint32_t k = 0; k < system.category_count(); ++k) categories.push_back(system.category_name(k));
  return {{"mill", {{"radius_m", setup.shell.radius}, {"length_m", setup.shell.length}, {"axial_ends", "periodic"},
                    {"lifter_count", setup.shell.lifter_count}}},
          {"gravity_m_s2", setup.gravity},
          {"angular_velocity_rad_s", omega},
          {"measure_start_s", start},
          {"measure_end_s", system.time()},
          {"sample_interval_s", steps * system.time_step()},
          {"frame_count", kSegments * kFramesPerSegment},
          {"segment_count", kSegments},
          {"categories", categories},
          {"n_balls", system.size()},
          {"ball_mass_kg", mass},
          {"media_diameter_m", setup.ball_diameter},
          {"dt_s", system.time_step()}};
}

MillSample make_sample() {
  MillSample sample;
  const auto dir = cache_dir();
  std::filesystem::create_directories(dir);
  for (int s = 0; s < kSegments; ++s) sample.segments.push_back(dir / fmt::format("segment_{:04d}.mfs", s));
  const auto result_file = dir / "macro_result.json";
  if (std::filesystem::exists(result_file)) {
    std::ifstream in(result_file);
    sample.macro_result = nlohmann::json::parse(in);
    return sample;
  }
  sample.macro_result = run_and_write(sample.segments);
  const auto temp = dir / fmt::format("macro_result.json.{}", ::getpid());
  std::ofstream(temp) << sample.macro_result.dump(1);
  std::filesystem::rename(temp, result_file);  // last: marks the cache complete
  return sample;
}

}  // namespace

const MillSample& small_mill_sample() {
  static const MillSample sample = make_sample();
  return sample;
}

}  // namespace millflow::tasks::testing
