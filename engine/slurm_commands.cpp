#include "engine/slurm_commands.hpp"

#include <sstream>
#include <stdexcept>

#include "engine/process.hpp"

namespace millflow::engine {
namespace {

std::string trimmed(const std::string& text) {
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return {};
  return text.substr(first, text.find_last_not_of(" \t\r\n") - first + 1);
}

class SystemSlurmCommands final : public SlurmCommands {
 public:
  std::string sbatch(const std::vector<std::string>& options,
                     const std::filesystem::path& script) override {
    std::vector<std::string> argv{"sbatch"};
    argv.insert(argv.end(), options.begin(), options.end());
    argv.push_back(script.string());
    const auto run = run_process(argv);
    if (run.exit_code != 0) {
      throw std::runtime_error("sbatch refused the job (exit " + std::to_string(run.exit_code) +
                               "): " + trimmed(run.err));
    }
    // --parsable prints "jobid" or "jobid;cluster".
    const std::string line = trimmed(run.out);
    return line.substr(0, line.find(';'));
  }

  std::map<std::string, std::string> squeue(const std::vector<std::string>& job_ids) override {
    if (job_ids.empty()) return {};
    std::string list;
    for (const auto& id : job_ids) list += (list.empty() ? "" : ",") + id;
    return states_of("--jobs=" + list);
  }

  std::map<std::string, std::string> squeue_named(const std::string& job_name) override {
    return states_of("--name=" + job_name);
  }

 private:
  // {"1234_5": "RUNNING", ...} of the jobs `selection` (an squeue option) picks.
  static std::map<std::string, std::string> states_of(const std::string& selection) {
    std::map<std::string, std::string> states;
    const auto run = run_process(
        {"squeue", "--noheader", "--array", "--states=all", "--format=%i %T", selection});
    if (run.exit_code != 0) {
      // squeue refuses a list in which it knows no job at all: they have all been forgotten.
      if (run.err.find("Invalid job id") != std::string::npos) return states;
      throw std::runtime_error("squeue failed (exit " + std::to_string(run.exit_code) +
                               "): " + trimmed(run.err));
    }
    std::istringstream lines(run.out);
    std::string id;
    std::string state;
    while (lines >> id >> state) states[id] = state;
    return states;
  }
};

}  // namespace

std::unique_ptr<SlurmCommands> system_slurm_commands() {
  return std::make_unique<SystemSlurmCommands>();
}

}  // namespace millflow::engine
