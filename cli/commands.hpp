#pragma once
// The engine's subcommands: validate, submit, resume, exec, status, query, export, show, explain,
// dag, gc. Exit codes: 0 done, 1 some tasks failed (or an unexpected error), 2 bad input, 3 the
// database is held by another coordinator, 130 interrupted; exec has its own
// (engine/attempt_files.hpp).
#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>

#include "engine/campaign.hpp"
#include "engine/progress.hpp"

namespace millflow::cli {

inline constexpr int kBadInput = 2;

// Runs a command body, turning errors into messages and exit codes (kBadInput for bad input).
int guarded(const std::function<int()>& body);

// An --out directory, checked before anything is written: refused (InvalidInput, path "--out")
// when it or the nearest existing directory above it is something else or cannot be written.
// The command creates it when missing.
std::filesystem::path output_directory(const std::string& given);

// While it lives, what the libraries log goes to stderr through the progress view (above its
// status line).
class LogThrough {
 public:
  explicit LogThrough(engine::ProgressView& view);
  ~LogThrough();
  LogThrough(const LogThrough&) = delete;
  LogThrough& operator=(const LogThrough&) = delete;

 private:
  std::shared_ptr<spdlog::logger> previous_;
};

// The live status line on a terminal, plain lines otherwise (stderr).
engine::ProgressView& terminal_or_plain(engine::LiveProgress& live, engine::PlainProgress& plain);

// Adds the subcommands; the one that runs stores its exit code in `exit_code`.
void add_engine_commands(CLI::App& app, const engine::Registry& registry,
                         std::optional<int>& exit_code);

}  // namespace millflow::cli
