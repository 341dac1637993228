#pragma once
#include <CLI/CLI.hpp>

namespace millflow::cli {

// `millflow demo`: a built-in DEM mill slice that prints its power draw.
void add_demo_command(CLI::App& app);

// Exit code left by the subcommand that ran.
int exit_code();

}  // namespace millflow::cli
