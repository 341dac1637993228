// A collision sink takes each finished contact as it finishes: the events the buffer of
// take_collision_events would hold, in its order, bit for bit, and nothing is buffered.
#include <gtest/gtest.h>

#include <vector>

#include "dem/mill_setup.hpp"
#include "tests/dem/same_bits.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

using testing::same_bits;

class CollectingSink final : public CollisionSink {
 public:
  void add(const CollisionEvent& event) override { events.push_back(event); }
  std::vector<CollisionEvent> events;
};

void expect_same_events(const std::vector<CollisionEvent>& a,
                        const std::vector<CollisionEvent>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].category, b[k].category) << "event " << k;
    EXPECT_EQ(a[k].a, b[k].a) << "event " << k;
    EXPECT_EQ(a[k].b, b[k].b) << "event " << k;
    EXPECT_EQ(a[k].with_wall, b[k].with_wall) << "event " << k;
    for (const auto field :
         {&CollisionEvent::start_time, &CollisionEvent::duration, &CollisionEvent::impact_speed,
          &CollisionEvent::impact_energy, &CollisionEvent::dissipated})
      EXPECT_TRUE(same_bits(a[k].*field, b[k].*field)) << "event " << k;
    for (int axis = 0; axis < 3; ++axis)
      EXPECT_TRUE(same_bits(a[k].point[axis], b[k].point[axis])) << "event " << k;
  }
}

// A running mill (pair and liner contacts finishing every step) recording its collisions.
System recording_mill() {
  System system = build_mill(testing::small_mill(0.2, 0.75));
  system.set_time_step_from_collisions(20);
  set_mill_speed(system, 0.75 * critical_speed(0.2, 0.01));
  system.set_record_collisions(true);
  return system;
}

TEST(CollisionSink, TakesTheEventsTheBufferWouldHoldInItsOrderAndNothingIsBuffered) {
  for (const int threads : {1, 2}) {
    testing::with_threads(threads, [&] {
      System buffered = recording_mill(), sunk = recording_mill();
      CollectingSink sink;
      std::vector<CollisionEvent> taken;
      for (int chunk = 0; chunk < 4; ++chunk) {
        buffered.step(100);
        for (const CollisionEvent& event : buffered.take_collision_events()) taken.push_back(event);
        const ScopedCollisionSink installed(sunk, sink);
        sunk.step(100);
        EXPECT_EQ(sunk.memory_use().collision_events, 0u);
      }
      bool pair = false, wall = false;
      for (const CollisionEvent& event : taken) (event.with_wall ? wall : pair) = true;
      ASSERT_TRUE(pair && wall) << "the mill finishes both kinds of contact";
      expect_same_events(taken, sink.events);
      EXPECT_TRUE(sunk.take_collision_events().empty());
    });
  }
}

TEST(CollisionSink, InstallingOneHandsItTheBufferedEventsFirstAndRemovingItBuffersAgain) {
  System buffered = recording_mill(), sunk = recording_mill();
  buffered.step(500);
  const std::vector<CollisionEvent> taken = buffered.take_collision_events();
  ASSERT_FALSE(taken.empty());

  sunk.step(300);
  ASSERT_GT(sunk.memory_use().collision_events, 0u);
  CollectingSink sink;
  {
    const ScopedCollisionSink installed(sunk, sink);
    EXPECT_EQ(sunk.memory_use().collision_events, 0u) << "the buffer is handed over and freed";
  }
  sunk.step(200);
  ASSERT_GT(sunk.memory_use().collision_events, 0u) << "buffered again";
  std::vector<CollisionEvent> all = sink.events;
  for (const CollisionEvent& event : sunk.take_collision_events()) all.push_back(event);
  expect_same_events(taken, all);
}

TEST(CollisionSink, ASystemNotRecordingHandsItNothing) {
  System recording = recording_mill(), silent = recording_mill();
  silent.set_record_collisions(false);
  CollectingSink sink;
  const ScopedCollisionSink installed(silent, sink);
  recording.step(300);
  silent.step(300);
  ASSERT_FALSE(recording.take_collision_events().empty());
  EXPECT_TRUE(sink.events.empty());
}

}  // namespace
}  // namespace millflow::dem
