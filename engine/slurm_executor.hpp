#pragma once
// Runs task attempts as Slurm jobs. The attempts the coordinator hands over in one turn go out as
// one job array (`sbatch --parsable --array=0-(n-1)%K`); element i runs `millflow exec` on the
// spec file <batch>/<i>.json and writes its output, marker and Slurm stdout/stderr into the batch
// directory. Layout of the run directory (on a filesystem the compute nodes share; never the
// database's directory on a cluster, see README "Running on a Slurm cluster"):
//   batches/<batch>/job.sh, <i>.json, <i>/ (output), <i>.out, <i>.err
//   inputs/<sha[0:2]>/<sha>   upstream artifacts staged for the jobs (content-addressed)
//   work/<task key>/          task work directories, kept across attempts for checkpoints
// Polling reads completion markers first and asks squeue only about jobs without one. A job that
// ended (FAILED, CANCELLED, TIMEOUT, NODE_FAIL, ...) or vanished from squeue without a marker is
// a failed attempt, handled by the runtime's retry policy; a marker saying "stopped" (the job
// checkpointed on --signal before its time limit) comes back interrupted and is submitted again.
#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "engine/job_executor.hpp"
#include "engine/slurm_commands.hpp"

namespace millflow::engine {

struct SlurmSettings {
  std::string partition;             // empty: the cluster's default
  std::string account;
  std::string time_limit;            // sbatch --time, e.g. "90" (minutes) or "1-00:00:00"
  std::string memory;                // sbatch --mem, e.g. "16G"
  int cpus_per_task = 1;             // also the threads of each task
  std::vector<std::string> extra_args;
  int max_in_flight = 100;           // jobs queued or running at once
  int checkpoint_signal_s = 300;     // --signal=B:USR1@N: checkpoint N s before the time limit
  double poll_interval_s = 10.0;
  std::filesystem::path run_dir;     // see above; shared with the compute nodes
  std::filesystem::path program;     // the millflow executable the jobs run
};

class SlurmExecutor final : public JobExecutor {
 public:
  SlurmExecutor(SlurmSettings settings, SlurmCommands& commands);

  std::filesystem::path work_root() const override { return settings_.run_dir / "work"; }
  int max_in_flight() const override { return settings_.max_in_flight; }
  double poll_interval_s() const override { return settings_.poll_interval_s; }
  std::vector<JobRecord> submit(const std::vector<AttemptOrder>& attempts) override;
  void reattach(const JobRecord& job) override;
  Poll poll() override;

  // The sbatch options of an array of `count` attempts writing into batch_dir.
  std::vector<std::string> sbatch_options(int count, const std::filesystem::path& batch_dir) const;

 private:
  struct Tracked {
    JobRecord job;
    std::chrono::steady_clock::time_point since;
    int polls_without_marker_after_end = 0;
  };

  std::filesystem::path new_batch_dir();
  std::vector<TaskInput> staged(const std::vector<TaskInput>& inputs) const;
  void write_batch_script(const std::filesystem::path& batch_dir) const;
  // The outcome of a job that ended or vanished: from its marker, or a failure once the marker is
  // still missing a poll later. Sets the job's state to record.
  std::optional<AttemptOutcome> settle(Tracked& tracked, const std::string& state) const;

  SlurmSettings settings_;
  SlurmCommands& commands_;
  std::map<std::string, Tracked> tracked_;  // by job id
  std::vector<AttemptOutcome> refused_;     // attempts sbatch refused, reported by the next poll
  int batches_ = 0;
};

// True for the squeue states of a job that has not ended yet (PENDING, RUNNING, ...).
bool slurm_state_is_active(const std::string& state);

}  // namespace millflow::engine
