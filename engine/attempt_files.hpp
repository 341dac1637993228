#pragma once
// The files through which one task attempt runs in its own process (`millflow exec SPEC_FILE`),
// possibly on another machine sharing the filesystem. The process never opens the database.
//   SPEC_FILE                    written by the coordinator (write_attempt_spec):
//     {"millflow_attempt": 1, "key", "kind", "version", "params", "upstream": [keys],
//      "inputs": [{"key", "kind", "result", "artifacts": {name: file}}], "attempt", "threads",
//      "work_dir", "output_dir"}
//   <output_dir>/result.json     {"result": ..., "children": [{"kind", "params",
//   "extra_upstream"}]} <output_dir>/artifacts/<i>   copies of the produced files, in the order of
//   the marker's list <output_dir>/complete.json   the completion marker, written last:
//     {"status": "done"|"failed"|"stopped", "error", "duration_s", "result_sha256",
//      "artifacts": [{"name", "file", "sha256", "size"}]}
// Each file is written under a temporary name and renamed into place: a reader sees a whole file
// or none, and a marker only after everything it names.
#include <filesystem>
#include <functional>
#include <optional>
#include <ostream>

#include "engine/job_executor.hpp"
#include "engine/task.hpp"

namespace millflow::engine {

// Exit codes of `millflow exec`.
inline constexpr int kExecDone = 0;
inline constexpr int kExecFailed = 1;   // the task threw; the marker holds the error
inline constexpr int kExecBadSpec = 2;  // the spec file is unreadable or names an unknown kind
inline constexpr int kExecStopped =
    75;  // a signal asked it to checkpoint; it stopped and runs again

struct AttemptSpec {
  TaskSpec task;
  std::vector<TaskInput> inputs;
  int attempt = 1;
  int threads = 1;
  std::filesystem::path work_dir;
  std::filesystem::path output_dir;
};

void write_attempt_spec(const AttemptSpec& spec, const std::filesystem::path& file);
// Throws InvalidInput naming what is missing.
AttemptSpec read_attempt_spec(const std::filesystem::path& file);

// Runs the attempt of the spec file in this process and writes its output files. stop_requested
// is polled (SIGUSR1/SIGTERM handlers): the task is asked to stop at its next checkpoint. Log
// lines go to `log`. Returns the exit code.
int execute_attempt(const KindRegistry& kinds, const std::filesystem::path& spec_file,
                    const std::function<bool()>& stop_requested, std::ostream& log);

// The outcome written to output_dir, or nullopt while there is no completion marker. A marker
// whose files do not match their recorded SHA-256 gives a failed outcome.
std::optional<AttemptOutcome> read_attempt_outcome(const std::filesystem::path& output_dir,
                                                   const std::string& key, int attempt);

}  // namespace millflow::engine
