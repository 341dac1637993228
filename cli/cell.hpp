#pragma once
#include <CLI/CLI.hpp>
#include <optional>

namespace millflow::cli {

// `millflow cell SPEC.json --out DIR`: one shear cell outside a campaign (tasks/cell_spec.hpp);
// prints its result JSON to stdout, its log, its phases and a status line with an ETA to stderr,
// and leaves its files in DIR; --threads N runs it on N threads (the same result bytes at any N).
void add_cell_command(CLI::App& app, std::optional<int>& exit_code);

}  // namespace millflow::cli
