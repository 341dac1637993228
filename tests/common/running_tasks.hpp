#pragma once
// How many tasks a database records as running, for tests that watch a coordinator from outside.
#include <cstdint>
#include <filesystem>

#include "engine/store.hpp"

namespace millflow::testing {

inline std::int64_t running_tasks(const std::filesystem::path& db) {
  try {
    auto connection = engine::open_read_only(db);
    auto row = connection.prepare("SELECT count(*) FROM tasks WHERE status = 'running'");
    row.step();
    return row.integer(0);
  } catch (const std::exception&) {
    return 0;  // not created yet
  }
}

}  // namespace millflow::testing
