#pragma once
// Checks of the command line's numbers. CLI11's CLI::Range lets NaN through (every comparison
// with NaN is false), and a NaN fill or speed then reached the library, or a NaN count of
// revolutions ran nothing and exited 0.
#include <string>

#include <CLI/CLI.hpp>

namespace millflow::cli {

// A finite number in [low, high]; `unit` follows the number in the messages ("s", or "").
CLI::Validator finite_between(double low, double high, const std::string& unit = "");

}  // namespace millflow::cli
