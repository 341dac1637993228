#pragma once
// The DAG runtime: the coordinating thread owns the store (the one writing connection), launches
// ready tasks up to --jobs at once, and commits each outcome in its own transaction as it arrives
// from the workers through an event queue.
#include <spdlog/logger.h>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "engine/artifacts.hpp"
#include "engine/cache.hpp"
#include "engine/clock.hpp"
#include "engine/job_executor.hpp"
#include "engine/launcher.hpp"
#include "engine/progress.hpp"
#include "engine/store.hpp"
#include "engine/task.hpp"

namespace millflow::engine {

struct RunOptions {
  int jobs = 1;              // tasks running at once
  int threads_per_task = 1;  // size of each task's own arena
  int retries = 0;           // extra attempts of a failing task within one run
  double refresh_s = 0.25;   // progress line period
  ForceRule force;           // cached tasks that run again (--force)
  std::string until;         // when set, only tasks of this kind and what they need run
  std::function<bool()> stop_requested = [] { return false; };  // polled: Ctrl-C, tests
};

struct RunSummary {
  int total = 0;
  int done = 0;    // ran to completion in this run
  int cached = 0;  // already done before this run
  int failed = 0;
  int skipped = 0;  // below a failed task
  // Done (in this run) or cached, but the result holds "skipped" (the task's reason for not doing
  // its work, e.g. a shear cell without a usable site): counted among done or cached, described
  // as skipped, like everywhere they are shown (status, dag, the progress line).
  int skipped_their_work_done = 0;
  int skipped_their_work_cached = 0;
  int interrupted = 0;
  int not_started = 0;  // left pending by an interruption
  int detached = 0;     // left running as batch jobs by an interruption; resume re-attaches
  int held_back = 0;    // beyond --until, left pending
  bool stopped = false;
  std::string
      stop_reason;  // why the run stopped without a stop request (the scheduler was unreachable)

  // 0 done, 1 some tasks failed, 130 interrupted (a stop request, or the batch scheduler
  // unreachable).
  int exit_code() const;
  std::string describe() const;
};

struct RunEnvironment {
  Store& store;
  const KindRegistry& kinds;
  Launcher& launcher;
  ProgressView& progress;
  const Clock& clock;
  const FileSystem& files;              // where artifacts are written and read
  std::shared_ptr<spdlog::logger> log;  // the campaign's log file (may be null)
  // When set, attempts run as its batch jobs (the launcher stays idle); a stop leaves running jobs
  // to be re-attached by the next run instead of waiting for them.
  JobExecutor* jobs = nullptr;
};

// Runs the campaign's tasks (already registered in the store) until all are done, failed or
// skipped, or a stop is requested.
RunSummary run_campaign(RunEnvironment environment, std::int64_t campaign,
                        const std::vector<TaskSpec>& planned, const RunOptions& options);

}  // namespace millflow::engine
