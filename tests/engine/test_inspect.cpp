// `millflow explain`: why a stored task would run (parameters changed, with the diff against the
// nearest cached task; upstream changed; previous attempt failed; interrupted by a crash;
// artifact corrupt) or would not (cached). The words come from the cache decision
// (engine/cache.hpp) that the runtime and the dry run share (test_cache_decision.cpp).
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "engine/inspect.hpp"
#include "engine/store.hpp"
#include "support_engine.hpp"

namespace millflow::engine::testing {
namespace {

using nlohmann::json;

// Registers the campaign's tasks without running any of them.
void register_only(const Campaign& campaign, const std::filesystem::path& db) {
  SubmitOptions options;
  options.run.stop_requested = [] { return true; };
  submit_campaign(testing_registry(), campaign, db, options);
}

std::string key_where(const std::filesystem::path& db, const std::string& condition) {
  auto connection = open_read_only(db);
  auto row = connection.prepare("SELECT key FROM tasks WHERE " + condition);
  EXPECT_TRUE(row.step()) << condition;
  return row.text(0);
}

std::string explain(const std::filesystem::path& db, const std::string& key) {
  std::ostringstream out;
  print_explain(db, key, out);
  return out.str();
}

// What explain prints first for every task: its key and the exact hashed text.
std::string header(const std::filesystem::path& db, const std::string& key) {
  auto connection = open_read_only(db);
  return "task " + key + "\nhashed text (SHA-256 of exactly these bytes):\n" +
         find_task(connection, key)->spec.key_text;
}

class Explain : public ::testing::Test {
 protected:
  void SetUp() override {
    submit(test_campaign("diamond", noted_diamond(3)), dir_.db());
    register_only(test_campaign("diamond", noted_diamond(30)), dir_.db());
    c_ = key_where(dir_.db(), "json_extract(params, '$.value') = 3");
    d_ = key_where(dir_.db(), "json_extract(params, '$.value') = 4 AND status = 'done'");
    new_c_ = key_where(dir_.db(), "json_extract(params, '$.value') = 30");
    new_d_ = key_where(dir_.db(), "json_extract(params, '$.value') = 4 AND status = 'pending'");
  }

  ScratchDir dir_;
  std::string c_, d_, new_c_, new_d_;
};

TEST_F(Explain, NewTaskShowsTheParameterDiffAgainstTheNearestCachedTask) {
  EXPECT_EQ(explain(dir_.db(), new_c_), header(dir_.db(), new_c_) +
                                            "would run: parameters changed since sum task " + c_ +
                                            "\n"
                                            "  /value: 3 -> 30\n");
}

TEST_F(Explain, TaskBelowAChangedOneShowsWhichInputChanged) {
  EXPECT_EQ(explain(dir_.db(), new_d_), header(dir_.db(), new_d_) +
                                            "would run: upstream changed since sum task " + d_ +
                                            "\n"
                                            "  input 1: " +
                                            c_ + " -> " + new_c_ + "\n");
}

TEST_F(Explain, CachedTaskWouldNotRunUntilItsArtifactIsCorrupt) {
  const std::string a = key_where(dir_.db(), "json_extract(params, '$.value') = 1");
  EXPECT_EQ(explain(dir_.db(), a.substr(0, 12)),
            header(dir_.db(), a) + "would not run: done, result and artifacts intact (cached)\n");
  auto connection = open_read_only(dir_.db());
  const auto artifact = find_artifacts(connection, a).at(0);
  std::ofstream(artifacts_dir(dir_.db()) / artifact.sha256.substr(0, 2) / artifact.sha256) << "9\n";
  EXPECT_EQ(explain(dir_.db(), a), header(dir_.db(), a) +
                                       "would run: artifact missing or corrupt: sum.txt (" +
                                       artifact.sha256 + ")\n");
}

TEST_F(Explain, FailedAttemptIsNamedWithItsError) {
  submit(
      test_campaign("broken",
                    json::array({{{"id", "f"}, {"kind", "fail"}, {"params", {{"failures", 9}}}}})),
      dir_.db());
  const std::string f = key_where(dir_.db(), "kind = 'fail'");
  EXPECT_EQ(explain(dir_.db(), f),
            header(dir_.db(), f) +
                "would run: not finished: the previous attempt failed: planned failure: attempt "
                "1 of a task that fails its first 9\n");
}

TEST_F(Explain, TaskLeftRunningByACrashIsReportedAsInterrupted) {
  {
    const SystemClock clock;
    Store store(dir_.db(), {}, clock);
    store.mark_running(new_c_);  // the coordinator recorded the launch, then died
  }
  EXPECT_EQ(explain(dir_.db(), new_c_),
            header(dir_.db(), new_c_) +
                "would run: not finished: its last attempt never finished (coordinator stopped or "
                "still running)\n");
}

}  // namespace
}  // namespace millflow::engine::testing
