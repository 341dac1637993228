#pragma once
// What the coordinator shows while a campaign runs: a live status line on a terminal (fitted to
// its width, log lines printed above it), plain lines at a steady pace otherwise, nothing for
// benchmarks.
#include <spdlog/logger.h>

#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace millflow::engine {

struct RunningTask {
  std::string key;
  std::string kind;
  double fraction = 0.0;
  std::string message;
};

struct ProgressSnapshot {
  std::map<std::string, std::pair<int, int>> done_total_by_kind;  // done or cached / total
  // pending or running (not held beyond --until), without a cost estimate
  std::map<std::string, int> remaining_by_kind;
  std::map<std::string, int> skipped_by_kind;
  // Tasks without a cost estimate that finished well in this run, per kind: their seconds in
  // all, and how many.
  std::map<std::string, std::pair<double, int>> task_seconds_by_kind;
  // Tasks with a cost estimate (their kind's cost model, engine/task.hpp: CPU-seconds of one
  // core): the estimate of those pending or running, less the done fraction of the running
  // ones, and how many they are (not those held beyond --until); and of those that finished well
  // in this run, their estimates
  // and their measured seconds in all.
  double estimated_left_s = 0.0;
  int estimated_tasks_left = 0;
  double finished_estimate_s = 0.0;
  double finished_measured_s = 0.0;
  std::vector<RunningTask> running;
  double elapsed_s = 0.0;
  int jobs = 1;               // tasks that may run at once
  int threads_per_task = 1;   // threads of each task
  int finished_this_run = 0;  // tasks that ran to an end in this run
  int remaining = 0;
};

// The time left. Tasks with a cost estimate: their estimates left, in seconds of a task at
// the pace measured so far: (measured + kEstimatePriorS / threads_per_task) / (estimated +
// kEstimatePriorS) seconds per estimated second over the tasks that finished in this run; the
// prior (the model's own pace, a CPU-second per estimated second spread over the task's threads)
// dominates until kEstimatePriorS of estimated work has finished, so the first small tasks do
// not swing it. Tasks without one: their kind's mean task time in this run so far, times its
// tasks still to run (less what the running ones have done). Both over the tasks that run at
// once. `lower_bound` when some kind without an estimate still to run has no finished task yet
// (its tasks are not counted); none when nothing left can be estimated.
inline constexpr double kEstimatePriorS = 60.0;
struct Eta {
  double seconds = 0.0;
  bool lower_bound = false;
};
std::optional<Eta> estimate_remaining(const ProgressSnapshot& snapshot);

// The status line, at most `width` characters: elapsed time, ETA, per kind done/total (and
// skipped), then the running tasks, dropping from the end what does not fit.
std::string format_status_line(const ProgressSnapshot& snapshot, std::size_t width = 1000);

class ProgressView {
 public:
  virtual ~ProgressView() = default;
  virtual void task_event(const std::string& kind, const std::string& key,
                          const std::string& what) = 0;
  virtual void refresh(const ProgressSnapshot& snapshot) = 0;
  // A log line from anywhere (any thread).
  virtual void message(const std::string& line) = 0;
  virtual void finish() {}
};

class QuietProgress final : public ProgressView {
 public:
  void task_event(const std::string&, const std::string&, const std::string&) override {}
  void refresh(const ProgressSnapshot&) override {}
  void message(const std::string&) override {}
};

// One line per task event and per log line on `out`, and the status line every
// `status_every_s` of the run (for logs and pipes, where a redrawn line would be garbage).
class PlainProgress final : public ProgressView {
 public:
  explicit PlainProgress(std::FILE* out, double status_every_s = 30.0)
      : out_(out), status_every_s_(status_every_s) {}
  void task_event(const std::string& kind, const std::string& key,
                  const std::string& what) override;
  void refresh(const ProgressSnapshot& snapshot) override;
  void message(const std::string& line) override;
  void finish() override;

 private:
  std::FILE* out_;
  double status_every_s_;
  double next_status_s_ = 0.0;
  std::string line_;
  std::mutex mutex_;
};

// A status line redrawn in place (carriage return, erase line), fitted to the terminal's width
// at each redraw so it never wraps; task events and log lines are printed above it.
class LiveProgress final : public ProgressView {
 public:
  explicit LiveProgress(std::FILE* out) : out_(out) {}
  void task_event(const std::string& kind, const std::string& key,
                  const std::string& what) override;
  void refresh(const ProgressSnapshot& snapshot) override;
  void message(const std::string& line) override;
  void finish() override;

 private:
  std::FILE* out_;
  std::string line_;
  std::mutex mutex_;
};

// A logger whose lines go through `view` (above a live status line, never into it), e.g. as
// spdlog's default logger while a campaign runs, for what the libraries log.
std::shared_ptr<spdlog::logger> progress_logger(ProgressView& view);

// Columns of the terminal `out` writes to: its window size, else $COLUMNS, else 80.
std::size_t terminal_width(std::FILE* out);

}  // namespace millflow::engine
