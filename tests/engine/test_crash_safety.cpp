// Crash safety: the millflow binary runs a campaign of test tasks and is killed with SIGKILL at
// 24 random moments (fixed seed), resuming each time. At the end every result equals that of an
// uninterrupted run, no task committed done was ever started again, and the database is intact.
#include <gtest/gtest.h>
#include <signal.h>

#include <fstream>
#include <map>
#include <random>
#include <set>
#include <thread>

#include "engine/store.hpp"
#include "support_engine.hpp"
#include "tests/common/child_process.hpp"

namespace millflow::engine::testing {
namespace {

namespace fs = std::filesystem;
using millflow::testing::wait_exit_code;
using nlohmann::json;

// Layers of sum tasks, each task after two tasks of the layer above, some writing artifacts,
// and a fanout that expands into five more tasks.
json layered_campaign() {
  json tasks = json::array();
  constexpr int kLayers = 10;
  constexpr int kWidth = 10;
  for (int layer = 0; layer < kLayers; ++layer) {
    for (int i = 0; i < kWidth; ++i) {
      json task = {
          {"id", fmt::format("{}-{}", layer, i)},
          {"kind", "sum"},
          {"params", {{"value", layer * 100 + i}, {"sleep_ms", 80}, {"artifact", i % 3 == 0}}}};
      if (layer > 0)
        task["after"] = {fmt::format("{}-{}", layer - 1, i),
                         fmt::format("{}-{}", layer - 1, (i + 1) % kWidth)};
      tasks.push_back(task);
    }
  }
  tasks.push_back({{"id", "fan"},
                   {"kind", "fanout"},
                   {"params", {{"children", 5}, {"value", 1}}},
                   {"after", {"4-0"}}});
  return {{"format", "millflow-test"}, {"name", "crash"}, {"tasks", tasks}};
}

pid_t spawn_millflow(const std::vector<std::string>& arguments, const fs::path& trace) {
  return millflow::testing::spawn_millflow(arguments, "/dev/null", "/dev/null",
                                           {{"MILLFLOW_TEST_TRACE", trace.string()}});
}

std::map<std::string, std::string> done_results(const fs::path& db) {
  std::map<std::string, std::string> results;
  if (!fs::exists(db)) return results;
  try {
    auto connection = open_read_only(db);
    auto rows = connection.prepare(
        "SELECT t.key, r.result FROM tasks t JOIN results r ON r.task_key = t.key WHERE t.status = "
        "'done'");
    while (rows.step()) results[rows.text(0)] = rows.text(1);
  } catch (const std::runtime_error&) {
    // killed before the schema was created: nothing committed yet
  }
  return results;
}

bool campaign_recorded(const fs::path& db) {
  if (!fs::exists(db)) return false;
  try {
    auto connection = open_read_only(db);
    return connection.prepare("SELECT 1 FROM campaigns").step();
  } catch (const std::runtime_error&) {
    return false;  // killed before the schema was created
  }
}

// Resume the campaign; on a busy machine a kill can come before the first submit has recorded
// it, and then there is nothing to resume yet: it is submitted again.
std::vector<std::string> go_on(const fs::path& file, const fs::path& db) {
  if (campaign_recorded(db)) return {"resume", "--db", db.string(), "--jobs", "4"};
  return {"submit", file.string(), "--db", db.string(), "--jobs", "4"};
}

std::vector<std::string> trace_lines(const fs::path& trace) {
  std::vector<std::string> lines;
  std::ifstream in(trace);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

TEST(CrashSafety, KillNineAtRandomMomentsLosesNothingCommitted) {
  ScratchDir dir;
  const fs::path file = dir.path() / "crash.json";
  std::ofstream(file) << layered_campaign().dump();

  const fs::path reference_db = dir.path() / "reference.db";
  ASSERT_EQ(wait_exit_code(spawn_millflow(
                {"submit", file.string(), "--db", reference_db.string(), "--jobs", "4"},
                dir.path() / "reference.trace")),
            0);
  const auto expected = done_results(reference_db);
  ASSERT_EQ(expected.size(), 106u);

  const fs::path db = dir.path() / "crashed.db";
  const fs::path trace = dir.path() / "crashed.trace";
  std::mt19937 random(20240611);
  std::uniform_int_distribution<int> delay_ms(5, 150);
  int kills = 0;  // kills that interrupted unfinished work
  for (int round = 0; round < 24; ++round) {
    const auto committed = done_results(db);
    const size_t trace_offset = trace_lines(trace).size();
    const pid_t child = spawn_millflow(go_on(file, db), trace);
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms(random)));
    const bool killed = ::kill(child, SIGKILL) == 0;
    wait_exit_code(child);
    kills += killed && done_results(db).size() < expected.size();  // killed mid-campaign
    const auto lines = trace_lines(trace);
    for (size_t i = trace_offset; i < lines.size(); ++i) {
      EXPECT_EQ(committed.count(lines[i]), 0u)
          << "round " << round << ": task " << lines[i] << " ran again after its commit";
    }
    for (const auto& [key, result] : committed) {
      EXPECT_EQ(done_results(db).at(key), result) << "a committed result changed";
    }
  }
  EXPECT_GE(kills, 20);

  const auto committed = done_results(db);
  const size_t trace_offset = trace_lines(trace).size();
  ASSERT_EQ(wait_exit_code(spawn_millflow(go_on(file, db), trace)), 0);
  const auto lines = trace_lines(trace);
  for (size_t i = trace_offset; i < lines.size(); ++i)
    EXPECT_EQ(committed.count(lines[i]), 0u) << lines[i];

  EXPECT_EQ(done_results(db), expected);
  auto connection = open_read_only(db);
  auto check = connection.prepare("PRAGMA integrity_check");
  ASSERT_TRUE(check.step());
  EXPECT_EQ(check.text(0), "ok");
}

}  // namespace
}  // namespace millflow::engine::testing
