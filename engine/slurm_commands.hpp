#pragma once
// The I/O edge of the Slurm executor: the Slurm client commands behind an interface, so unit
// tests put a fake cluster in its place. The system implementation runs sbatch and squeue (the
// SLURM_CONF environment variable picks the cluster). Neither sacct nor slurmdbd is needed.
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace millflow::engine {

class SlurmCommands {
 public:
  virtual ~SlurmCommands() = default;
  // `sbatch OPTIONS SCRIPT` with --parsable among the options; returns the job id it printed.
  // Throws std::runtime_error with sbatch's message when the submission is refused.
  virtual std::string sbatch(const std::vector<std::string>& options,
                             const std::filesystem::path& script) = 0;
  // The state of each listed job that the controller still knows, array elements one by one
  // (`squeue --array --states=all`): {"1234_5": "RUNNING", ...}. Jobs it has forgotten are absent.
  virtual std::map<std::string, std::string> squeue(const std::vector<std::string>& job_ids) = 0;
  // Likewise for the jobs named job_name (`squeue --name=NAME --array --states=all`); none when
  // the controller knows no such job.
  virtual std::map<std::string, std::string> squeue_named(const std::string& job_name) = 0;
};

std::unique_ptr<SlurmCommands> system_slurm_commands();

}  // namespace millflow::engine
