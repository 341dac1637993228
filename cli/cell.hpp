#pragma once
#include <CLI/CLI.hpp>
#include <optional>

namespace millflow::cli {

// `millflow cell SPEC.json --out DIR`: one shear cell outside a campaign (tasks/cell_spec.hpp);
// prints its result JSON to stdout, its log to stderr, and leaves its files in DIR.
void add_cell_command(CLI::App& app, std::optional<int>& exit_code);

}  // namespace millflow::cli
