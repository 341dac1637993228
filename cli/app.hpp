#pragma once
#include <functional>

#include "engine/campaign.hpp"

namespace millflow::cli {

// Parses the command line, runs the subcommand and returns the process exit code
// (0 done, 1 some tasks failed, 2 bad input, 130 interrupted). `extend` registers more task kinds
// and formats beside the method's (the test executable's test kinds).
int run(int argc, char** argv, const std::function<void(engine::Registry&)>& extend = nullptr);

}  // namespace millflow::cli
