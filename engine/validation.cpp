#include "engine/validation.hpp"

namespace millflow::engine {
namespace {

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
  return text;
}

InvalidInput::InvalidInput(std::vector<ValidationError> errors)
    : std::runtime_error(join_messages(errors)), errors_(std::move(errors)) {}

}  // namespace millflow::engine
