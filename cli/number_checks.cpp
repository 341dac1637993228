#include "cli/number_checks.hpp"

#include <fmt/format.h>

namespace millflow::cli {

CLI::Validator finite_between(double low, double high, const std::string& unit) {
  const std::string suffix = unit.empty() ? "" : " " + unit;
  const std::string what = unit == "s" ? "a number of seconds" : "a number";
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        double value = 0.0;
        try {
          std::size_t used = 0;
          value = std::stod(text, &used);
          if (used != text.size()) return "\"" + text + "\" is not " + what;
        } catch (const std::exception&) {
          return "\"" + text + "\" is not " + what;
        }
        if (!(value >= low && value <= high))
          return fmt::format("{}{} is outside [{}, {}]{}", text, suffix, low, high, suffix);
        return {};
      },
      fmt::format("{} in [{}, {}]", unit == "s" ? "SECONDS" : "NUMBER", low, high));
}

}  // namespace millflow::cli
