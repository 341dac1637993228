#pragma once
// Runs task attempts as Slurm jobs. The attempts the coordinator hands over in one turn go out as
// one job array (`sbatch --parsable --array=0-(n-1)%K --job-name=millflow-<batch>`); element i
// runs `millflow exec` on the spec file <batch>/<i>.json and writes its output, marker and Slurm
// stdout/stderr into the batch directory. Layout of the run directory (on a filesystem the
// compute nodes share; never the database's directory on a cluster, see docs/slurm.md):
//   batches/<batch>/job.sh, <i>.json, <i>/ (output), <i>.out, <i>.err
//   inputs/<sha[0:2]>/<sha>   upstream artifacts staged for the jobs (content-addressed)
//   work/<task key>/          task work directories, kept across attempts for checkpoints
// The jobs are recorded (SUBMITTING, with their job name) before sbatch runs: a coordinator
// killed before it recorded the array id leaves jobs that resume finds by name in squeue, or by
// their completion markers, and submits again only when Slurm never got them.
// Polling reads completion markers first and asks squeue only about jobs without one. A job that
// ended (FAILED, CANCELLED, TIMEOUT, NODE_FAIL, ...) or vanished from squeue without a marker is
// a failed attempt, handled by the runtime's retry policy; a marker saying "stopped" (the job
// checkpointed on --signal before its time limit) comes back interrupted and is submitted again.
// A failed squeue is a warning and polled again; max_squeue_failures in a row make poll() report
// the cluster unreachable (the coordinator stops; the jobs run on for `millflow resume`).
#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "engine/job_executor.hpp"
#include "engine/slurm_commands.hpp"

namespace millflow::engine {

// sbatch's --signal takes a lead of at most 65535 s.
inline constexpr int kSlurmMaxSignalLeadS = 65535;

// What one task kind's jobs ask Slurm for, where it differs from the campaign-wide settings
// (a macro run of a large mill and a powder cell differ by orders of magnitude).
struct SlurmResources {
  std::string time_limit;  // empty: the campaign-wide one
  std::string memory;      // empty: the campaign-wide one
  int cpus_per_task = 0;   // 0: the campaign-wide one
};

// The campaign file's executor.slurm block (docs/slurm.md) plus what the
// command line adds (run_dir, program, poll_interval_s).
struct SlurmSettings {
  std::string partition;  // empty: the cluster's default
  std::string account;
  std::string time_limit;  // sbatch --time, e.g. "90" (minutes) or "1-00:00:00"
  std::string memory;      // sbatch --mem, e.g. "16G"
  int cpus_per_task = 1;   // also the threads of each task
  std::vector<std::string> extra_args;
  std::map<std::string, SlurmResources> per_kind;  // by task kind
  int max_in_flight = 100;                         // jobs queued or running at once
  int checkpoint_signal_s = 300;  // --signal=B:USR1@N: checkpoint N s before the time limit
  // squeue failures in a row (a controller restarting, a network blip) ridden out before poll()
  // gives up; at the default poll interval of 10 s, 30 are five minutes.
  int max_squeue_failures = 30;
  double poll_interval_s = 10.0;
  std::filesystem::path run_dir;  // see above; shared with the compute nodes
  std::filesystem::path program;  // the millflow executable the jobs run
};

class SlurmExecutor final : public JobExecutor {
 public:
  SlurmExecutor(SlurmSettings settings, SlurmCommands& commands);

  std::filesystem::path work_root() const override { return settings_.run_dir / "work"; }
  int max_in_flight() const override { return settings_.max_in_flight; }
  double poll_interval_s() const override { return settings_.poll_interval_s; }
  std::vector<JobRecord> submit(const std::vector<AttemptOrder>& attempts,
                                const RecordJobs& record_before_sending) override;
  std::optional<JobRecord> reattach(const JobRecord& job) override;
  Poll poll() override;

  // The sbatch options of an array of `count` attempts of `kind` writing into batch_dir.
  std::vector<std::string> sbatch_options(int count, const std::filesystem::path& batch_dir,
                                          const std::string& kind = {}) const;
  // The campaign-wide settings with `kind`'s own resources over them.
  SlurmResources resources_of(const std::string& kind) const;
  // "millflow-<batch dir name>": unique per array, so squeue finds an array by it.
  static std::string job_name_of(const std::filesystem::path& batch_dir);

 private:
  std::vector<JobRecord> submit_array(const std::vector<AttemptOrder>& attempts,
                                      const std::string& kind,
                                      const RecordJobs& record_before_sending);
  struct Tracked {
    JobRecord job;
    std::chrono::steady_clock::time_point since;
    int polls_without_marker_after_end = 0;
  };

  std::filesystem::path new_batch_dir();
  std::vector<TaskInput> staged(const std::vector<TaskInput>& inputs) const;
  void write_batch_script(const std::filesystem::path& batch_dir) const;
  void track(const JobRecord& job);
  // The Slurm id of a job recorded without one, from squeue by its job name; empty if unknown.
  std::string find_id_by_name(const JobRecord& job);
  // squeue's states of the tracked jobs; on failure a warning, or `unreachable` after too many.
  std::optional<std::map<std::string, std::string>> squeue_tracked(Poll& result);
  // The outcome of a job that ended or vanished: from its marker, or a failure once the marker is
  // still missing a poll later. Sets the job's state to record.
  std::optional<AttemptOutcome> settle(Tracked& tracked, const std::string& state) const;

  SlurmSettings settings_;
  SlurmCommands& commands_;
  std::map<std::filesystem::path, Tracked> tracked_;  // by output directory (one per attempt)
  Poll refused_;  // attempts that could not be submitted, reported by the next poll
  std::map<std::string, std::map<std::string, std::string>> squeue_by_name_;  // reattach's lookups
  int squeue_failures_ = 0;                                                   // in a row
  int batches_ = 0;
};

// True for the squeue states of a job that has not ended yet (PENDING, RUNNING, ...).
bool slurm_state_is_active(const std::string& state);

}  // namespace millflow::engine
