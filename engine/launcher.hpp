#pragma once
// Where task attempts run. The coordinator hands each attempt to a Launcher; tests may use
// InlineLauncher (runs the attempt at once on the calling thread: a deterministic order).
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <functional>
#include <memory>

namespace millflow::engine {

class Launcher {
 public:
  virtual ~Launcher() = default;
  virtual void launch(std::function<void()> attempt) = 0;
  // Blocks until every launched attempt has returned.
  virtual void wait_idle() = 0;
};

class InlineLauncher final : public Launcher {
 public:
  void launch(std::function<void()> attempt) override { attempt(); }
  void wait_idle() override {}
};

// Runs attempts on oneTBB worker threads of an arena with `jobs` slots (the coordinator never
// launches more than `jobs` at once). The runtime runs each attempt inside an arena of
// threads_per_task that no other running task shares, so nested parallelism stays inside its
// task (a waiting thread never picks up another task).
class TbbLauncher final : public Launcher {
 public:
  TbbLauncher(int jobs, int threads_per_task);
  ~TbbLauncher() override;
  void launch(std::function<void()> attempt) override;
  void wait_idle() override;

 private:
  std::unique_ptr<tbb::global_control> workers_;
  tbb::task_arena arena_;
  std::atomic<int> in_flight_{0};
};

}  // namespace millflow::engine
