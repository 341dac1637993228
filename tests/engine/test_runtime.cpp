// The DAG runtime end to end on test kinds: order, concurrency, failures, retries, caching,
// re-keying, shared tasks, dynamic expansion, artifact corruption, interruption.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <functional>
#include <stdexcept>

#include "engine/progress.hpp"
#include "engine/store.hpp"
#include "support_engine.hpp"

namespace millflow::engine::testing {
namespace {

using nlohmann::json;

// a(1) -> b(2) -> d(4); a -> c(3) -> d: sums are 1, 3, 4, 1+3+4+4 = 12.
json diamond(int a_value = 1) {
  return json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", a_value}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}}}, {"after", {"a"}}},
       {{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 3}}}, {"after", {"a"}}},
       {{"id", "d"}, {"kind", "sum"}, {"params", {{"value", 4}}}, {"after", {"b", "c"}}}});
}

std::int64_t sum_of(const std::filesystem::path& db, std::int64_t value) {
  return count(
      db,
      "SELECT json_extract(r.result, '$.sum') FROM tasks t JOIN results r ON r.task_key = t.key "
      "WHERE json_extract(t.params, '$.value') = " +
          std::to_string(value));
}

std::string only_result(const std::filesystem::path& db) {
  auto connection = open_read_only(db);
  auto row = connection.prepare("SELECT result FROM results");
  return row.step() ? row.text(0) : std::string();
}

std::int64_t launches(const std::filesystem::path& db) {
  return count(db, "SELECT count(*) FROM status_history WHERE status = 'running'");
}

TEST(Runtime, RunsTheDagInDependencyOrderWithCorrectInputs) {
  ScratchDir dir;
  const auto summary = submit(test_campaign("diamond", diamond()), dir.db(), 3);
  EXPECT_EQ(summary.done, 4);
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(sum_of(dir.db(), 2), 1 + 2);
  EXPECT_EQ(sum_of(dir.db(), 3), 1 + 3);
  EXPECT_EQ(sum_of(dir.db(), 4), 4 + (1 + 2) + (1 + 3));
  // Every downstream launch comes after its upstream task was committed done.
  EXPECT_EQ(
      count(dir.db(),
            "SELECT count(*) FROM edges e "
            "JOIN status_history up ON up.task_key = e.upstream AND up.status = 'done' "
            "JOIN status_history down ON down.task_key = e.downstream AND down.status = 'running' "
            "WHERE down.id < up.id"),
      0);
}

TEST(Runtime, NeverRunsMoreThanJobsTasksAtOnce) {
  ScratchDir dir;
  json tasks = json::array();
  for (int i = 0; i < 9; ++i)
    tasks.push_back({{"id", std::to_string(i)}, {"kind", "sleep"}, {"params", {{"ms", 60 + i}}}});
  take_max_concurrent_sleeps();
  EXPECT_EQ(submit(test_campaign("sleepers", tasks), dir.db(), 3).done, 9);
  EXPECT_EQ(take_max_concurrent_sleeps(), 3);
}

TEST(Runtime, FailureSkipsDescendantsButNotSiblings) {
  ScratchDir dir;
  const json tasks = json::array(
      {{{"id", "bad"}, {"kind", "fail"}, {"params", {{"failures", 5}}}},
       {{"id", "child"}, {"kind", "sum"}, {"params", {{"value", 1}}}, {"after", {"bad"}}},
       {{"id", "grandchild"}, {"kind", "sum"}, {"params", {{"value", 2}}}, {"after", {"child"}}},
       {{"id", "sibling"}, {"kind", "sum"}, {"params", {{"value", 3}}}}});
  const auto summary = submit(test_campaign("failing", tasks), dir.db());
  EXPECT_EQ(summary.failed, 1);
  EXPECT_EQ(summary.skipped, 2);
  EXPECT_EQ(summary.done, 1);
  EXPECT_EQ(summary.exit_code(), 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'skipped'"), 2);
  EXPECT_EQ(sum_of(dir.db(), 3), 3);
}

TEST(Runtime, RetriesWithinARunAndCountsAttemptsAcrossRuns) {
  ScratchDir dir;
  const auto campaign = test_campaign(
      "flaky", json::array({{{"id", "f"}, {"kind", "fail"}, {"params", {{"failures", 2}}}}}));
  EXPECT_EQ(submit(campaign, dir.db(), 1, 1).failed, 1);  // attempts 1 and 2 fail
  EXPECT_EQ(count(dir.db(), "SELECT attempts FROM tasks"), 2);
  EXPECT_EQ(submit(campaign, dir.db(), 1, 0).done, 1);  // attempt 3 succeeds
  ScratchDir fresh;
  EXPECT_EQ(submit(campaign, fresh.db(), 1, 2).done, 1);  // two retries are enough in one run
  EXPECT_EQ(count(fresh.db(), "SELECT attempts FROM tasks"), 3);
}

TEST(Runtime, ResubmissionIsFullyCached) {
  ScratchDir dir;
  const auto campaign = test_campaign("diamond", diamond());
  submit(campaign, dir.db());
  const auto before = launches(dir.db());
  const auto again = submit(campaign, dir.db());
  EXPECT_EQ(again.cached, 4);
  EXPECT_EQ(again.done, 0);
  EXPECT_EQ(launches(dir.db()), before);
}

// A coordinator killed between a task's commit and the removal of its work directory left the
// directory for good: the task is cached and never runs again. The next run removes it, and only
// the work directories of cached tasks.
TEST(Runtime, AWorkDirectoryADoneTaskLeftBehindGoesAtTheNextRun) {
  ScratchDir dir;
  const auto campaign = test_campaign("diamond", diamond());
  ASSERT_EQ(submit(campaign, dir.db()).exit_code(), 0);
  std::string key;
  {
    auto connection = open_read_only(dir.db());
    auto row = connection.prepare("SELECT key FROM tasks LIMIT 1");
    ASSERT_TRUE(row.step());
    key = row.text(0);
  }
  const std::filesystem::path left = work_dir(dir.db()) / key;
  const std::filesystem::path other = work_dir(dir.db()) / "not-a-task-of-this-campaign";
  for (const auto& folder : {left / "flow", other}) {
    std::filesystem::create_directories(folder);
    std::ofstream(folder / "segment") << "frames\n";
  }
  EXPECT_EQ(submit(campaign, dir.db()).cached, 4);
  EXPECT_FALSE(std::filesystem::exists(left));
  EXPECT_TRUE(std::filesystem::exists(other / "segment"));
}

// A coordinator killed mid-line leaves the campaign log without its last newline: the next one
// starts on a line of its own instead of gluing its first line to the torn one.
TEST(Runtime, TheNextCoordinatorStartsItsLogOnANewLine) {
  ScratchDir dir;
  std::filesystem::create_directories(logs_dir(dir.db()));
  const std::filesystem::path log = logs_dir(dir.db()) / "diamond.log";
  std::ofstream(log) << "[2026-12-06 04:24:17.998] [campaign] [info] torn";
  ASSERT_EQ(submit(test_campaign("diamond", diamond()), dir.db()).exit_code(), 0);
  std::ifstream in(log);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line, "[2026-12-06 04:24:17.998] [campaign] [info] torn");
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_TRUE(line.starts_with("[")) << line;
}

TEST(Runtime, ChangedParameterRerunsExactlyItsDownstream) {
  ScratchDir dir;
  submit(test_campaign("diamond", diamond(1)), dir.db());
  // Changing c re-keys c and d only.
  json changed = diamond(1);
  changed[2]["params"]["value"] = 30;
  const auto summary = submit(test_campaign("diamond", changed), dir.db());
  EXPECT_EQ(summary.done, 2);
  EXPECT_EQ(summary.cached, 2);
  EXPECT_EQ(sum_of(dir.db(), 30), 31);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM task_results WHERE campaign = 'diamond'"), 4);
  // Changing the root re-keys everything.
  EXPECT_EQ(submit(test_campaign("diamond", diamond(5)), dir.db()).done, 4);
}

TEST(Runtime, OverlappingCampaignsShareTasks) {
  ScratchDir dir;
  submit(test_campaign("first", diamond()), dir.db());
  json second = diamond();
  second.push_back({{"id", "e"}, {"kind", "sum"}, {"params", {{"value", 100}}}, {"after", {"d"}}});
  const auto summary = submit(test_campaign("second", second), dir.db());
  EXPECT_EQ(summary.cached, 4);
  EXPECT_EQ(summary.done, 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks"), 5);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM campaign_tasks"), 9);
}

TEST(Runtime, ResultsCanGrowTheDagWithStableChildKeys) {
  ScratchDir dir;
  const json tasks = json::array({{{"id", "root"}, {"kind", "sum"}, {"params", {{"value", 5}}}},
                                  {{"id", "fan"},
                                   {"kind", "fanout"},
                                   {"params", {{"children", 4}, {"value", 10}}},
                                   {"after", {"root"}}}});
  const auto first = submit(test_campaign("grow", tasks), dir.db());
  EXPECT_EQ(first.total, 6);
  EXPECT_EQ(first.done, 6);
  // Children see the fanout's sum (10) as input: 10 + i.
  EXPECT_EQ(count(dir.db(),
                  "SELECT sum(json_extract(r.result, '$.sum')) FROM tasks t JOIN results r ON "
                  "r.task_key = t.key "
                  "WHERE t.parent_key IS NOT NULL"),
            4 * 10 + (0 + 1 + 2 + 3));
  // A second campaign with the same tasks finds the expanded children cached.
  const auto second = submit(test_campaign("grow-again", tasks), dir.db());
  EXPECT_EQ(second.total, 6);
  EXPECT_EQ(second.cached, 6);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM task_results WHERE campaign = 'grow-again'"), 6);
}

TEST(Runtime, CorruptOrMissingArtifactMakesItsTaskRunAgain) {
  ScratchDir dir;
  const auto campaign = test_campaign(
      "files",
      json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 7}, {"artifact", true}}}},
                   {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 1}}}, {"after", {"a"}}}}));
  submit(campaign, dir.db());
  auto connection = open_read_only(dir.db());
  const auto key = [&] {
    auto row = connection.prepare("SELECT task_key FROM artifacts");
    row.step();
    return row.text(0);
  }();
  const auto artifact = find_artifacts(connection, key).at(0);
  const auto file = artifacts_dir(dir.db()) / artifact.sha256.substr(0, 2) / artifact.sha256;
  std::ofstream(file) << "8\n";  // same size, different content
  auto rerun = submit(campaign, dir.db());
  EXPECT_EQ(rerun.done, 1);
  EXPECT_EQ(rerun.cached, 1);
  std::filesystem::resize_file(file, 0);  // truncated
  EXPECT_EQ(submit(campaign, dir.db()).done, 1);
  std::filesystem::remove(file);  // missing
  EXPECT_EQ(submit(campaign, dir.db()).done, 1);
  std::ifstream in(file);
  std::int64_t restored = 0;
  in >> restored;
  EXPECT_EQ(restored, 7);
}

TEST(Runtime, StopRequestInterruptsRunningTasksAndResumeFinishes) {
  ScratchDir dir;
  json tasks = json::array();
  for (int i = 0; i < 4; ++i)
    tasks.push_back({{"id", std::to_string(i)}, {"kind", "sleep"}, {"params", {{"ms", 3000 + i}}}});
  const auto campaign = test_campaign("long", tasks);
  SubmitOptions options;
  options.run.jobs = 2;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
  options.run.stop_requested = [&] { return std::chrono::steady_clock::now() > deadline; };
  const auto stopped = submit_campaign(testing_registry(), campaign, dir.db(), options);
  EXPECT_EQ(stopped.exit_code(), 130);
  EXPECT_EQ(stopped.interrupted, 2);
  EXPECT_EQ(stopped.not_started, 2);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'interrupted'"), 2);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM campaigns WHERE outcome = 'interrupted'"), 1);
}

// One steps task of `steps` steps of 5 ms.
Campaign steps_campaign(int steps) {
  return test_campaign(
      "steps",
      json::array(
          {{{"id", "s"}, {"kind", "steps"}, {"params", {{"steps", steps}, {"step_ms", 5}}}}}));
}

// The steps kind's checkpoints in the store's work directory, each with the step it holds (0 when
// unreadable).
using StepsCheckpoints = std::vector<std::pair<std::filesystem::path, int>>;
StepsCheckpoints steps_checkpoints(const std::filesystem::path& db) {
  StepsCheckpoints found;
  std::error_code missing;
  for (const auto& entry : std::filesystem::directory_iterator(work_dir(db), missing)) {
    const auto file = entry.path() / "steps.checkpoint";
    std::ifstream checkpoint(file);
    int step = 0;
    if (checkpoint) found.emplace_back(file, checkpoint >> step ? step : 0);
  }
  return found;
}

// The result of one uninterrupted run of `campaign` (a single task) in a store of its own.
std::string uninterrupted_result(const Campaign& campaign) {
  ScratchDir whole;
  EXPECT_EQ(submit(campaign, whole.db()).exit_code(), 0);
  return only_result(whole.db());
}

// Submits `campaign` into `db`, stopping it once `stop` holds for the steps kind's checkpoints.
RunSummary submit_until(const Campaign& campaign, const std::filesystem::path& db,
                        const std::function<bool(const StepsCheckpoints&)>& stop) {
  SubmitOptions options;
  options.run.refresh_s = 0.002;
  options.run.stop_requested = [&] { return stop(steps_checkpoints(db)); };
  return submit_campaign(testing_registry(), campaign, db, options);
}

// The steps kind stands in for a long DEM task: stopped part-way, it continues from the checkpoint
// in its work directory, and the result equals that of one uninterrupted run.
TEST(Runtime, StoppedTaskContinuesFromItsCheckpointToTheSameResult) {
  const auto campaign = steps_campaign(60);
  const std::string whole = uninterrupted_result(campaign);
  ScratchDir dir;
  const auto a_few_steps_saved = [](const auto& checkpoints) {
    return std::any_of(checkpoints.begin(), checkpoints.end(),
                       [](const auto& checkpoint) { return checkpoint.second >= 5; });
  };
  EXPECT_EQ(submit_until(campaign, dir.db(), a_few_steps_saved).interrupted, 1);
  ASSERT_EQ(submit(campaign, dir.db()).exit_code(), 0);
  const auto resumed = count(dir.db(),
                             "SELECT CAST(substr(message, 22) AS INTEGER) FROM log_lines "
                             "WHERE message LIKE 'continuing from step % of 60'");
  EXPECT_GE(resumed, 5);
  EXPECT_LT(resumed, 60);
  EXPECT_EQ(only_result(dir.db()), whole);
  EXPECT_EQ(json::parse(only_result(dir.db()))["steps"], 60);
}

// A task's warning (a line marked kTaskWarning: here a checkpoint it cannot read) is stored at
// level warn without the marker, which the terminal's warning prefix would repeat.
TEST(Runtime, ATasksWarningIsLoggedAtWarnLevelWithoutItsMarker) {
  const auto campaign = steps_campaign(20);
  const std::string whole = uninterrupted_result(campaign);
  ScratchDir dir;
  const auto saved = [](const auto& checkpoints) { return !checkpoints.empty(); };
  ASSERT_EQ(submit_until(campaign, dir.db(), saved).interrupted, 1);
  ASSERT_EQ(steps_checkpoints(dir.db()).size(), 1u);
  // The file goes once the task is done.
  const std::filesystem::path checkpoint = steps_checkpoints(dir.db()).front().first;
  std::ofstream(checkpoint) << "garbage\n";
  ASSERT_EQ(submit(campaign, dir.db()).exit_code(), 0);
  EXPECT_EQ(count(dir.db(),
                  "SELECT count(*) FROM log_lines WHERE level = 'warn' AND message = '"
                  "the checkpoint " +
                      checkpoint.string() + " cannot be read; starting again from step 0'"),
            1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM log_lines WHERE message LIKE 'warning:%'"), 0);
  EXPECT_EQ(only_result(dir.db()), whole);
}

// A NaN in a result used to throw out of the commit and stop the coordinator, leaving the task
// running; every resume did the same. It is a failed attempt, logged, and a retry can succeed.
TEST(Runtime, ANonFiniteResultIsAFailedAttemptWithTheReasonInTheTaskLog) {
  ScratchDir dir;
  const json tasks = json::array(
      {{{"id", "nan"}, {"kind", "fail"}, {"params", {{"failures", 1}, {"non_finite", true}}}},
       {{"id", "after"}, {"kind", "sum"}, {"params", {{"value", 1}}}, {"after", {"nan"}}},
       {{"id", "sibling"}, {"kind", "sum"}, {"params", {{"value", 2}}}}});
  const auto first = submit(test_campaign("diverged", tasks), dir.db());
  EXPECT_EQ(first.failed, 1);
  EXPECT_EQ(first.skipped, 1);
  EXPECT_EQ(first.done, 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'running'"), 0);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM coordinator"), 0);
  EXPECT_EQ(count(dir.db(),
                  "SELECT count(*) FROM log_lines WHERE task_key IS NOT NULL AND level = 'error' "
                  "AND message LIKE 'attempt 1 failed: its result cannot be stored: /value: nan "
                  "is not a finite number%'"),
            1);
  // The second attempt returns a finite result: the campaign finishes on resume.
  const auto second = submit(test_campaign("diverged", tasks), dir.db());
  EXPECT_EQ(second.failed, 0);
  EXPECT_EQ(second.done, 2);
}

// A progress view that fails once a task runs, as one writing to a terminal that went away did
// (engine/progress.cpp writes best effort since).
class FailingView final : public ProgressView {
 public:
  void task_event(const std::string&, const std::string&, const std::string&) override {}
  void refresh(const ProgressSnapshot& snapshot) override {
    if (!snapshot.running.empty()) throw std::runtime_error("the terminal went away");
  }
  void message(const std::string&) override {}
};

// Whatever ends the coordinator's loop, its running tasks hold it: it asks them to stop and
// waits for them before it goes. It was destroyed under a running task (a segmentation fault on
// a full disk, found by hand), or its launcher waited out the task's whole run.
TEST(Runtime, ALoopThatFailsStopsAndWaitsForItsRunningTasks) {
  ScratchDir dir;
  Registry registry = testing_registry();
  const auto campaign = test_campaign(
      "failing-view",
      json::array({{{"id", "long"}, {"kind", "sleep"}, {"params", {{"ms", 30000}}}}}));
  FailingView view;
  SubmitOptions options;
  options.run.jobs = 1;
  options.run.refresh_s = 0.01;
  options.progress = &view;
  const auto started = std::chrono::steady_clock::now();
  EXPECT_THROW(submit_campaign(registry, campaign, dir.db(), options), std::runtime_error);
  // Stopped at its next 2 ms step, not slept out.
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(10));
}

}  // namespace
}  // namespace millflow::engine::testing
