#pragma once
// Runs the built millflow_testing binary (MILLFLOW_BINARY_DIR/millflow_testing: the command line
// with the engine's test kinds) as a child process, for tests of the command line, exit codes,
// signals and crashes.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace millflow::testing {

inline std::filesystem::path millflow_binary() {
  return std::filesystem::path(MILLFLOW_BINARY_DIR) / "millflow_testing";
}
// The production binary: the method's kinds only.
inline std::filesystem::path production_millflow_binary() {
  return std::filesystem::path(MILLFLOW_BINARY_DIR) / "millflow";
}

// Starts millflow with `arguments`, stdout and stderr redirected to files, extra environment
// variables set. Returns the child's pid.
inline pid_t spawn_millflow(
    const std::vector<std::string>& arguments, const std::filesystem::path& out = "/dev/null",
    const std::filesystem::path& err = "/dev/null",
    const std::vector<std::pair<std::string, std::string>>& environment = {},
    const std::filesystem::path& program = millflow_binary()) {
  const std::string binary = program.string();
  const pid_t child = ::fork();
  if (child == 0) {
    for (const auto& [name, value] : environment) ::setenv(name.c_str(), value.c_str(), 1);
    ::dup2(::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644), STDOUT_FILENO);
    ::dup2(::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644), STDERR_FILENO);
    std::vector<char*> argv{const_cast<char*>(binary.c_str())};
    for (const auto& argument : arguments) argv.push_back(const_cast<char*>(argument.c_str()));
    argv.push_back(nullptr);
    ::execv(binary.c_str(), argv.data());
    ::_exit(127);
  }
  return child;
}

// The child's exit status, or minus the signal that killed it.
inline int wait_exit_code(pid_t child) {
  int status = 0;
  ::waitpid(child, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

inline std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

struct Finished {
  int exit_code;
  std::string out;
  std::string err;
};

// Runs millflow to its end; its output passes through files in `scratch`.
inline Finished run_millflow(const std::vector<std::string>& arguments,
                             const std::filesystem::path& scratch,
                             const std::filesystem::path& program = millflow_binary()) {
  const auto out = scratch / "stdout.txt";
  const auto err = scratch / "stderr.txt";
  const int code = wait_exit_code(spawn_millflow(arguments, out, err, {}, program));
  return Finished{code, read_text(out), read_text(err)};
}

}  // namespace millflow::testing
