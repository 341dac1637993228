#pragma once
// The engine's subcommands: validate, submit, resume, exec, status, query, export, show, explain,
// dag, gc. Exit codes: 0 done, 1 some tasks failed (or an unexpected error), 2 bad input, 3 the
// database is held by another coordinator, 130 interrupted; exec has its own
// (engine/attempt_files.hpp).
#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <optional>

#include "engine/campaign.hpp"

namespace millflow::cli {

inline constexpr int kBadInput = 2;

// Runs a command body, turning errors into messages and exit codes (kBadInput for bad input).
int guarded(const std::function<int()>& body);

// An --out directory, checked before anything is written: refused (InvalidInput, path "--out")
// when it or the nearest existing directory above it is something else or cannot be written.
// The command creates it when missing.
std::filesystem::path output_directory(const std::string& given);

// Adds the subcommands; the one that runs stores its exit code in `exit_code`.
void add_engine_commands(CLI::App& app, const engine::Registry& registry,
                         std::optional<int>& exit_code);

}  // namespace millflow::cli
