// The coordinator's status line: it fits the terminal, its ETA comes from the kinds' cost models
// (the others: each kind's own task times), and skipped tasks are shown as skipped.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "engine/progress.hpp"
#include "support_engine.hpp"

namespace millflow::engine {
namespace {

using nlohmann::json;

// quick.json in its first minutes: the macro runs done (30 s each), 120 cells to go, two of
// them running.
ProgressSnapshot quick_campaign() {
  ProgressSnapshot s;
  s.done_total_by_kind = {{"macro", {4, 4}},        {"average", {4, 4}},  {"sites", {4, 4}},
                          {"shear_cell", {6, 120}}, {"upscale", {0, 12}}, {"report", {0, 1}}};
  s.remaining_by_kind = {{"shear_cell", 112}, {"upscale", 12}, {"report", 1}};
  s.skipped_by_kind = {{"shear_cell", 2}};
  s.task_seconds_by_kind = {
      {"macro", {120.0, 4}}, {"average", {4.0, 4}}, {"sites", {2.0, 4}}, {"shear_cell", {24.0, 6}}};
  s.running = {{"0123456789abcdef", "shear_cell", 0.5, "strain 2/6"},
               {"fedcba9876543210", "shear_cell", 0.25, "strain 1/6"}};
  s.elapsed_s = 95.0;
  s.jobs = 2;
  s.finished_this_run = 18;
  s.remaining = 125;
  return s;
}

TEST(Progress, EtaIsEachKindsMeanTimeTimesItsTasksLeftOverTheJobs) {
  ProgressSnapshot s = quick_campaign();
  s.remaining_by_kind = {{"shear_cell", 112}};
  const auto eta = estimate_remaining(s);
  ASSERT_TRUE(eta);
  // 112 cells of 4 s, less the 0.75 of a cell the running ones did, on 2 jobs.
  EXPECT_DOUBLE_EQ(eta->seconds, (112 * 4.0 - 0.75 * 4.0) / 2);
  EXPECT_FALSE(eta->lower_bound);
  // The 30 s macro runs do not make the cells look 30 s long (a campaign-wide mean would).
}

TEST(Progress, EtaOfKindsWithoutAFinishedTaskIsALowerBound) {
  const auto eta = estimate_remaining(quick_campaign());
  ASSERT_TRUE(eta);
  EXPECT_TRUE(eta->lower_bound);  // no upscale or report has finished
  ProgressSnapshot none = quick_campaign();
  none.task_seconds_by_kind.clear();
  EXPECT_FALSE(estimate_remaining(none));
}

TEST(Progress, EtaOfEstimatedTasksIsTheirCostAtTheModelsPaceUntilTasksFinish) {
  ProgressSnapshot s;
  s.jobs = 2;
  s.estimated_left_s = 1000.0;  // CPU-seconds of one core, from the kinds' cost models
  s.estimated_tasks_left = 10;
  auto eta = estimate_remaining(s);
  ASSERT_TRUE(eta);
  EXPECT_DOUBLE_EQ(eta->seconds, 1000.0 / 2);  // nothing finished: the model's own pace
  EXPECT_FALSE(eta->lower_bound);
  s.threads_per_task = 4;
  EXPECT_DOUBLE_EQ(estimate_remaining(s)->seconds, 1000.0 / 4 / 2);
  s.threads_per_task = 1;
  // Finished tasks estimated at 20 s took 60 s in all: the pace moves towards 3 s per estimated
  // second, weighted against the prior of kEstimatePriorS.
  s.finished_estimate_s = 20.0;
  s.finished_measured_s = 60.0;
  const double pace = (60.0 + kEstimatePriorS) / (20.0 + kEstimatePriorS);
  EXPECT_DOUBLE_EQ(estimate_remaining(s)->seconds, 1000.0 * pace / 2);
  // Once much more has finished, the measured pace rules.
  s.finished_estimate_s = 2000.0;
  s.finished_measured_s = 6000.0;
  EXPECT_NEAR(estimate_remaining(s)->seconds, 1000.0 * 3.0 / 2, 0.1 * 1000.0);
  // One estimated task left on 2 jobs runs on one.
  s.estimated_tasks_left = 1;
  s.estimated_left_s = 10.0;
  s.finished_estimate_s = s.finished_measured_s = 0.0;
  EXPECT_DOUBLE_EQ(estimate_remaining(s)->seconds, 10.0);
}

TEST(Progress, EtaAddsEstimatedTasksAndTheMeanTimesOfKindsWithoutAModel) {
  ProgressSnapshot s = quick_campaign();
  s.remaining_by_kind = {{"upscale", 12}};  // the cells have a model now
  s.task_seconds_by_kind = {{"upscale", {3.0, 3}}};
  s.running.clear();
  s.estimated_left_s = 448.0;
  s.estimated_tasks_left = 112;
  const auto eta = estimate_remaining(s);
  ASSERT_TRUE(eta);
  EXPECT_DOUBLE_EQ(eta->seconds, (448.0 + 12 * 1.0) / 2);
}

// A clock that moves one second each time it is read: the coordinator's loop refreshes the view
// every turn, and task durations are whole seconds of it.
class TickingClock final : public Clock {
 public:
  double now() const override { return ticks_.fetch_add(1) + 1.0; }

 private:
  mutable std::atomic<long> ticks_{0};
};

class RecordingView final : public ProgressView {
 public:
  void task_event(const std::string&, const std::string&, const std::string&) override {}
  void refresh(const ProgressSnapshot& snapshot) override { snapshots.push_back(snapshot); }
  void message(const std::string&) override {}
  std::vector<ProgressSnapshot> snapshots;
};

TEST(Progress, CoordinatorTakesEachTasksCostFromItsKindsModelAndRefinesItBelowAFinishedTask) {
  Registry registry = testing::testing_registry();
  // sum tasks cost their value in seconds; one with upstream tasks costs nothing known until they
  // finished, then the sum of their results.
  registry.kinds.set_cost_model("sum", [](const TaskSpec& spec, const TaskLookup& lookup) {
    double seconds = spec.params.at("value").get<double>();
    for (const auto& key : spec.upstream) {
      const KnownTask above = lookup(key);
      if (above.spec == nullptr || above.result == nullptr) return std::optional<double>();
      seconds += above.result->at("sum").get<double>();
    }
    return std::optional<double>(seconds);
  });
  const auto campaign = testing::test_campaign(
      "costs",
      json::array(
          {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 10}}}},
           {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 20}}}},
           {{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 5}}}, {"after", {"a", "b"}}},
           {{"id", "w"}, {"kind", "sleep"}, {"params", {{"ms", 1}}}}}));
  testing::ScratchDir dir;
  RecordingView view;
  TickingClock clock;
  SubmitOptions options;
  options.run.jobs = 1;
  options.run.refresh_s = 0.5;
  options.progress = &view;
  options.clock = &clock;
  const auto summary = submit_campaign(registry, campaign, dir.path() / "costs.db", options);
  ASSERT_EQ(summary.exit_code(), 0);
  ASSERT_GE(view.snapshots.size(), 2u);
  // At first: a and b estimated (30 s), c not yet (counted by kind), the sleep task has no model.
  const ProgressSnapshot& first = view.snapshots.front();
  EXPECT_DOUBLE_EQ(first.estimated_left_s, 30.0);
  EXPECT_EQ(first.estimated_tasks_left, 2);
  EXPECT_EQ(first.remaining_by_kind.at("sum"), 1);
  EXPECT_EQ(first.remaining_by_kind.at("sleep"), 1);
  // Once a and b finished, c costs 5 + 10 + 20.
  bool refined = false;
  for (const auto& s : view.snapshots) {
    if (s.finished_estimate_s == 30.0 && s.estimated_tasks_left == 1) {
      EXPECT_DOUBLE_EQ(s.estimated_left_s, 35.0);
      EXPECT_EQ(s.remaining_by_kind.count("sum"), 0u);
      refined = true;
    }
  }
  EXPECT_TRUE(refined);
  const ProgressSnapshot& last = view.snapshots.back();
  EXPECT_DOUBLE_EQ(last.finished_estimate_s, 65.0);
  EXPECT_GT(last.finished_measured_s, 0.0);
  EXPECT_EQ(last.estimated_tasks_left, 0);
  EXPECT_EQ(last.task_seconds_by_kind.at("sleep").second, 1);  // timed by kind instead

  // With --until sleep the sum tasks are held back: they are not part of the time left.
  RecordingView until_view;
  options.progress = &until_view;
  options.run.until = "sleep";
  const auto held = submit_campaign(registry, campaign, dir.path() / "until.db", options);
  ASSERT_EQ(held.exit_code(), 0);
  ASSERT_FALSE(until_view.snapshots.empty());
  EXPECT_EQ(until_view.snapshots.front().estimated_tasks_left, 0);
  EXPECT_EQ(until_view.snapshots.front().remaining_by_kind,
            (std::map<std::string, int>{{"sleep", 1}}));
}

TEST(Progress, StatusLineShowsSkippedAndNeverExceedsTheWidth) {
  const ProgressSnapshot s = quick_campaign();
  const std::string full = format_status_line(s);
  EXPECT_EQ(full.substr(0, 14), "[1m35s] ETA >3");
  EXPECT_NE(full.find("shear_cell 6/120 (2 skipped)"), std::string::npos) << full;
  EXPECT_NE(full.find("shear_cell:012345 50%"), std::string::npos) << full;
  // Tenths below 10%, where a long task would otherwise sit at 0% for minutes.
  ProgressSnapshot early = s;
  early.running.front().fraction = 0.0043;
  EXPECT_NE(format_status_line(early).find("shear_cell:012345 0.4%"), std::string::npos);
  early.running.front().fraction = 0.0996;
  EXPECT_NE(format_status_line(early).find("shear_cell:012345 10%"), std::string::npos);
  for (std::size_t width = 1; width <= full.size() + 5; ++width) {
    const std::string line = format_status_line(s, width);
    EXPECT_LE(line.size(), width) << line;
    EXPECT_EQ(full.substr(0, line.size()), line);  // what is left out is left out at the end
  }
  // On an 80-column terminal: the time, the ETA and the counts of every kind, cut at a part.
  const std::string eighty = format_status_line(s, 79);
  EXPECT_NE(eighty.find("[1m35s] ETA >"), std::string::npos);
  EXPECT_NE(eighty.find("macro 4/4"), std::string::npos) << eighty;
}

TEST(Progress, PlainLinesComeAtTheirPaceAndLogLinesAsTheyCome) {
  std::FILE* out = std::tmpfile();
  PlainProgress plain(out, 30.0);
  ProgressSnapshot s = quick_campaign();
  for (const double t : {0.0, 10.0, 29.0, 30.0, 45.0, 61.0}) {
    s.elapsed_s = t;
    plain.refresh(s);
  }
  plain.message("[info] a log line");
  std::rewind(out);
  std::string text(4096, '\0');
  text.resize(std::fread(text.data(), 1, text.size(), out));
  std::fclose(out);
  std::vector<std::string> starts;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) starts.push_back(line.substr(0, 7));
  EXPECT_EQ(starts, (std::vector<std::string>{"[0s] ET", "[30s] E", "[1m01s]", "[info] "}));
  EXPECT_EQ(text.find('\r'), std::string::npos);  // no redraws in a log file
}

}  // namespace
}  // namespace millflow::engine
