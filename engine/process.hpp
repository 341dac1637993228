#pragma once
// Runs a program to its end and captures what it prints (the Slurm client commands).
#include <string>
#include <vector>

namespace millflow::engine {

struct ProcessResult {
  int exit_code = 0;  // minus the signal that killed it
  std::string out;
  std::string err;
};

// argv[0] is looked up in PATH. Throws std::runtime_error when it cannot be started.
ProcessResult run_process(const std::vector<std::string>& argv);

}  // namespace millflow::engine
