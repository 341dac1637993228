#pragma once
// Executors that run task attempts as jobs of a batch scheduler (Slurm), in other processes and
// possibly on other machines. The coordinator hands them attempts and polls them between its
// turns, so no thread ever blocks waiting on a job. Jobs never touch the database: the
// coordinator records the JobRecords that submit/poll return and ingests every outcome itself,
// as the store's only writer. (The in-process alternative is a Launcher: engine/launcher.hpp.)
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/task.hpp"

namespace millflow::engine {

// One attempt of a task, claimed by the coordinator (recorded running, inputs gathered).
struct AttemptOrder {
  const TaskSpec* spec = nullptr;
  std::shared_ptr<const std::vector<TaskInput>> inputs;
  int attempt = 0;
};

// The job running one attempt, as the store records it (table jobs).
struct JobRecord {
  std::string task_key;
  int attempt = 0;
  std::string executor;  // "slurm"
  std::string job_id;    // the scheduler's id, e.g. "1234_5": element 5 of array 1234;
                         // empty while being submitted
  std::string state;     // last state seen: SUBMITTING (recorded before the scheduler has
                         // it), PENDING, RUNNING, COMPLETED, TIMEOUT, ... NOT_SUBMITTED
  std::string job_name;  // the scheduler's job name, unique per submission: how a job
                         // recorded without id is found again
  std::filesystem::path output_dir;  // where the job writes its result, artifacts and marker
  std::filesystem::path stdout_file;
  std::filesystem::path stderr_file;
};

// How an attempt ended, for the coordinator to commit.
struct AttemptOutcome {
  std::string key;
  int attempt = 0;
  std::optional<std::string> error;  // the attempt failed, for this reason
  TaskOutcome outcome;               // otherwise: done (files verified) or interrupted
  double duration_s = 0.0;
};

class JobExecutor {
 public:
  struct Poll {
    std::vector<AttemptOutcome> finished;
    std::vector<JobRecord> changed;  // jobs whose state changed since the last poll
    std::vector<std::string>
        warnings;  // trouble ridden out (e.g. one failed squeue): logged, polled again
    // Set when the scheduler stayed unreachable too long: the coordinator stops, leaving the jobs
    // running for `millflow resume` to re-attach to.
    std::optional<std::string> unreachable;
  };

  virtual ~JobExecutor() = default;
  // Task work directories (kept across attempts for checkpoints), on a filesystem the jobs see.
  virtual std::filesystem::path work_root() const = 0;
  virtual int max_in_flight() const = 0;
  virtual double poll_interval_s() const = 0;
  using RecordJobs = std::function<void(const std::vector<JobRecord>&)>;
  // Sends the attempts off without waiting for them; returns the jobs to record. Before handing
  // them to the scheduler it passes them to record_before_sending (state SUBMITTING, no id yet),
  // so a coordinator that dies while submitting leaves records that reattach() can find the
  // jobs by. An attempt that could not be submitted comes back from the next poll as failed.
  virtual std::vector<JobRecord> submit(const std::vector<AttemptOrder>& attempts,
                                        const RecordJobs& record_before_sending) = 0;
  // Follows a job recorded by an earlier coordinator instead of submitting its attempt again, and
  // returns it as now followed (a job recorded without id gets the id the scheduler knows it by).
  // nullopt: the scheduler never got the job and it left no output, so its attempt never ran.
  virtual std::optional<JobRecord> reattach(const JobRecord& job) = 0;
  virtual Poll poll() = 0;
};

}  // namespace millflow::engine
