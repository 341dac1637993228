// What a system holds for its contacts: the bytes it reports, and the checkpoint of a contact.
#include <gtest/gtest.h>

#include <string>

#include "dem/checkpoint.hpp"
#include "dem/system.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

using testing::open_box;
using testing::steel_table;

// Two steel balls of 10 mm radius, `gap` apart (negative: overlapping), no gravity.
System two_balls(double gap) {
  System system(steel_table(0.5, 0.5), open_box(1.0), Vec3::Zero());
  const double r = 0.01;
  system.add_particle({.position = Vec3(-r - 0.5 * gap, 0, 0), .radius = r});
  system.add_particle({.position = Vec3(r + 0.5 * gap, 0, 0), .radius = r});
  return system;
}

TEST(SystemMemory, TheContactStoreGrowsWithTheContactsAndAWallLessSystemHasNoWallSlots) {
  System apart = two_balls(0.001), touching = two_balls(-0.0002);
  apart.step();
  touching.step();
  ASSERT_EQ(apart.active_contact_count(), 0u);
  ASSERT_EQ(touching.active_contact_count(), 1u);
  const System::MemoryUse without = apart.memory_use(), with = touching.memory_use();
  EXPECT_EQ(without.contacts, 0u);
  EXPECT_GT(with.contacts, 0u);
  EXPECT_EQ(with.wall_contacts, 0u);
  EXPECT_EQ(with.particles, without.particles);
  EXPECT_EQ(touching.memory_bytes(), with.particles + with.candidate_pairs + with.contacts +
                                         with.wall_contacts + with.step_queues +
                                         with.collision_events);
}

// The neighbour rebuild lays the contact store out again in place, keeping its capacity: once the
// contacts are gone, it must give the memory back (a store kept at its largest would hold a
// dilating cell's bytes long after its contacts ended).
TEST(SystemMemory, ARebuildGivesBackTheStoreOfContactsThatEnded) {
  System system = two_balls(-0.0004);  // pushed apart from the first step
  system.step();
  ASSERT_EQ(system.active_contact_count(), 1u);
  const std::size_t touching = system.memory_use().contacts;
  EXPECT_GT(touching, 0u);
  const std::uint64_t rebuilds = system.neighbor_rebuild_count();
  for (int i = 0; i < 100000 && system.neighbor_rebuild_count() == rebuilds; ++i) system.step();
  ASSERT_GT(system.neighbor_rebuild_count(), rebuilds) << "the balls never moved half a skin";
  EXPECT_EQ(system.active_contact_count(), 0u);
  // What stays is the free-slot list's one entry, not a record.
  EXPECT_LT(system.memory_use().contacts, touching / 2);
}

TEST(SystemCheckpoint, AContactHistoryNotInForceIsRefused) {
  System system = two_balls(-0.0002);
  system.step();
  ASSERT_EQ(system.active_contact_count(), 1u);
  std::string payload = checkpoint_payload(system);
  // After the pair contact's touching byte: the force on i, a wall contact count per particle,
  // the finished dissipation (count, 3 doubles per category), the virial and the reorder interval.
  const std::size_t after = 3 * 8 + system.size() + 8 + 3 * 8 * system.category_count() + 9 * 8 + 8;
  const std::size_t touching_byte = payload.size() - after - 1;
  ASSERT_EQ(payload[touching_byte], 1);
  EXPECT_NO_THROW(system_from_checkpoint_payload(payload, kCheckpointVersion));
  payload[touching_byte] = 0;
  try {
    system_from_checkpoint_payload(payload, kCheckpointVersion);
    ADD_FAILURE() << "no error";
  } catch (const CorruptData& e) {
    EXPECT_STREQ(e.what(), "checkpoint: a contact history not in force");
  }
}

}  // namespace
}  // namespace millflow::dem
