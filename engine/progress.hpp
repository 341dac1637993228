#pragma once
// What the coordinator shows while a campaign runs: a live status line on a terminal, plain log
// lines otherwise, nothing for benchmarks.
#include <cstdio>
#include <map>
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
  std::vector<RunningTask> running;
  double elapsed_s = 0.0;
  int finished_this_run = 0;  // tasks that ran to an end in this run (for the ETA)
  int remaining = 0;
};

class ProgressView {
 public:
  virtual ~ProgressView() = default;
  virtual void task_event(const std::string& kind, const std::string& key,
                          const std::string& what) = 0;
  virtual void refresh(const ProgressSnapshot& snapshot) = 0;
  virtual void finish() {}
};

class QuietProgress final : public ProgressView {
 public:
  void task_event(const std::string&, const std::string&, const std::string&) override {}
  void refresh(const ProgressSnapshot&) override {}
};

// One line per task event on `out`.
class PlainProgress final : public ProgressView {
 public:
  explicit PlainProgress(std::FILE* out) : out_(out) {}
  void task_event(const std::string& kind, const std::string& key,
                  const std::string& what) override;
  void refresh(const ProgressSnapshot&) override {}

 private:
  std::FILE* out_;
};

// A status line redrawn in place (carriage return), task events above it.
class LiveProgress final : public ProgressView {
 public:
  explicit LiveProgress(std::FILE* out) : out_(out) {}
  void task_event(const std::string& kind, const std::string& key,
                  const std::string& what) override;
  void refresh(const ProgressSnapshot& snapshot) override;
  void finish() override;

 private:
  std::FILE* out_;
  std::string line_;
};

std::string format_status_line(const ProgressSnapshot& snapshot);

}  // namespace millflow::engine
