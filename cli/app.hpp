#pragma once

namespace millflow::cli {

// Parses the command line, runs the subcommand and returns the process exit code
// (0 done, 1 some tasks failed, 2 bad input, 130 interrupted).
int run(int argc, char** argv);

}  // namespace millflow::cli
