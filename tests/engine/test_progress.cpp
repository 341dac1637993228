// The coordinator's status line: it fits the terminal, its ETA comes from each kind's own task
// times, and skipped tasks are shown as skipped.
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "engine/progress.hpp"

namespace millflow::engine {
namespace {

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

TEST(Progress, StatusLineShowsSkippedAndNeverExceedsTheWidth) {
  const ProgressSnapshot s = quick_campaign();
  const std::string full = format_status_line(s);
  EXPECT_EQ(full.substr(0, 14), "[1m35s] ETA >3");
  EXPECT_NE(full.find("shear_cell 6/120 (2 skipped)"), std::string::npos) << full;
  EXPECT_NE(full.find("shear_cell:012345 50%"), std::string::npos) << full;
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
