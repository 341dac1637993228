#include "engine/validation.hpp"

#include <fmt/format.h>

namespace millflow::engine {
namespace {

// Control characters of a key or value (from a JSON escape such as \u0000) written as that escape:
// printed raw, a NUL cut the report short, an escape sequence drove the terminal and a line break
// split an error in two.
std::string printable(const std::string& text) {
  std::string shown;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f)
      shown += fmt::format("\\u{:04x}", byte);
    else
      shown += c;
  }
  return shown;
}

std::string join_messages(const std::vector<ValidationError>& errors) {
  std::string text;
  for (const auto& error : errors) {
    if (!text.empty()) text += '\n';
    text += error.message();
  }
  return text;
}

}  // namespace

std::string ValidationError::message() const {
  std::string text = (path.empty() ? std::string("(document)") : path) + ": " + problem;
  if (!fix.empty()) text += "; " + fix;
  return printable(text);
}

InvalidInput::InvalidInput(std::vector<ValidationError> errors)
    : std::runtime_error(join_messages(errors)), errors_(std::move(errors)) {}

}  // namespace millflow::engine
