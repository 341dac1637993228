// Flow samples round-trip through their file and carry what coarse-graining needs.
#include <gtest/gtest.h>

#include <filesystem>

#include "dem/binary_io.hpp"
#include "dem/flow_sample.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

TEST(FlowSample, FramesOfARunningMillRoundTrip) {
  System system = build_mill(testing::small_mill(0.2, 0.75));
  system.set_time_step_from_collisions(20);
  system.set_record_collisions(true);
  set_mill_speed(system, 0.75 * critical_speed(0.2, 0.01));
  std::vector<FlowFrame> frames;
  for (int f = 0; f < 3; ++f) {
    system.step(400);
    const auto events = system.take_collision_events();
    frames.push_back(capture_frame(system, std::get<MillWall>(system.wall(0).shape).angle, events));
  }
  ASSERT_EQ(frames[2].position.size(), system.size());
  ASSERT_FALSE(frames[2].contact_a.empty());
  ASSERT_FALSE(frames[2].event_time.empty());
  // Every contact force is what the system reports in force, and the wall contacts name wall 0.
  EXPECT_EQ(frames[2].contact_a.size(), system.active_contact_count());

  const auto path = std::filesystem::temp_directory_path() / "millflow_test_flow.mfs";
  write_flow_segment(path, frames);
  const auto back = read_flow_segment(path);
  ASSERT_EQ(back.size(), 3u);
  for (std::size_t f = 0; f < 3; ++f) {
    EXPECT_EQ(back[f].time, frames[f].time);
    EXPECT_EQ(back[f].position, frames[f].position);
    EXPECT_EQ(back[f].contact_force, frames[f].contact_force);
    EXPECT_EQ(back[f].event_dissipated, frames[f].event_dissipated);
    EXPECT_EQ(back[f].event_category, frames[f].event_category);
  }
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  EXPECT_THROW(read_flow_segment(path), CorruptData);
  std::filesystem::remove(path);
}

TEST(FlowSample, ContactForcesAddUpToEachBallsContactForce) {
  // The sample holds every contact: per ball, its contact forces sum to the total force on it
  // minus its weight (to single precision).
  System system = build_mill(testing::small_mill(0.2, 0.0));
  system.set_time_step_from_collisions(20);
  system.step(4000);
  const FlowFrame frame = capture_frame(system, 0.0, {});
  std::vector<Vec3> contact_force(system.size(), Vec3::Zero());
  for (std::size_t c = 0; c < frame.contact_a.size(); ++c) {
    const Vec3 f(frame.contact_force[c][0], frame.contact_force[c][1], frame.contact_force[c][2]);
    contact_force[frame.contact_a[c]] += f;
    if (!frame.contact_with_wall[c]) contact_force[frame.contact_b[c]] -= f;
  }
  for (std::size_t p = 0; p < system.size(); ++p) {
    const Vec3 expected = system.forces()[p] - system.masses()[p] * system.gravity();
    EXPECT_LT((contact_force[p] - expected).norm(), 1e-5 * (1.0 + expected.norm())) << "ball " << p;
  }
}

}  // namespace
}  // namespace millflow::dem
