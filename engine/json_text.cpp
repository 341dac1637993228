#include "engine/json_text.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <set>
#include <string>

#include "engine/json_validator.hpp"

namespace millflow::engine {
namespace {

using nlohmann::json;

// The numbers of a JSON text as written, in order (what is outside strings and starts with a
// digit or '-'): the parser's events give a number's value, not how it was written.
std::vector<std::string_view> number_lexemes(std::string_view text) {
  std::vector<std::string_view> numbers;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;  // the escaped character, whatever it is
      else if (c == '"')
        in_string = false;
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '-' || (c >= '0' && c <= '9')) {
      const std::size_t end = text.find_first_not_of("0123456789+-.eE", i);
      numbers.push_back(text.substr(i, end == std::string_view::npos ? end : end - i));
      i = (end == std::string_view::npos ? text.size() : end) - 1;
    }
  }
  return numbers;
}

// Whether a number written this way is too small for a double: it reads as 0 or a subnormal,
// which strtod reports as a range error (a written 0 is none).
bool underflows(std::string_view lexeme) {
  const std::string written(lexeme);
  errno = 0;
  const double value = std::strtod(written.c_str(), nullptr);
  return errno == ERANGE && std::abs(value) < std::numeric_limits<double>::min();
}

// Follows the parser's events to know the path of every key, and remembers the keys seen in each
// open object.
class DuplicateKeyFinder {
 public:
  explicit DuplicateKeyFinder(std::string_view text) : numbers_(number_lexemes(text)) {}

  bool operator()(int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
        enter_container();
        frames_.push_back({true, {}, {}, 0});
        break;
      case json::parse_event_t::array_start:
        enter_container();
        frames_.push_back({false, {}, {}, 0});
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        frames_.pop_back();
        break;
      case json::parse_event_t::key:
        on_key(parsed.get<std::string>());
        break;
      case json::parse_event_t::value:
        enter_element();
        if (parsed.is_number()) check_number(parsed);
        break;
    }
    return true;
  }

  std::vector<ValidationError> take_errors() { return std::move(errors_); }

  // The path of the value the parser is reading now (where a number overflowed).
  std::string current_value_path() const {
    std::string text;
    for (std::size_t i = 0; i < frames_.size(); ++i) {
      const auto& frame = frames_[i];
      const bool innermost = i + 1 == frames_.size();
      text += '/';
      text += frame.object ? escape_path_segment(frame.key)
                           : std::to_string(innermost ? frame.items : frame.items - 1);
    }
    return text;
  }

 private:
  struct Frame {
    bool object;
    std::set<std::string> keys;
    std::string key;        // objects: the key being read
    std::size_t items = 0;  // lists: items started so far
  };

  void enter_element() {
    if (!frames_.empty() && !frames_.back().object) ++frames_.back().items;
  }

  // Copying, printing and destroying a document recurse once per level: some 130,000 levels
  // overflowed the stack.
  void enter_container() {
    enter_element();
    if (frames_.size() < kMaxJsonDepth) return;
    throw InvalidInput({{path(), fmt::format("nested more than {} levels deep", kMaxJsonDepth),
                         "check the brackets: a millflow file nests a few levels"}});
  }

  // 1e-401 read as 0 without a word (a number above a double's range is the parser's error).
  void check_number(const json& parsed) {
    if (next_number_ >= numbers_.size()) return;
    const std::string_view lexeme = numbers_[next_number_++];
    if (!parsed.is_number_float() || !underflows(lexeme)) return;
    throw InvalidInput({{path(), fmt::format("number underflow parsing '{}'", lexeme),
                         "write 0, or a number a double can hold (magnitude at least 2.2e-308)"}});
  }

  void on_key(std::string key) {
    auto& frame = frames_.back();
    frame.key = std::move(key);
    if (frame.keys.insert(frame.key).second) return;
    errors_.push_back({path(), "key \"" + frame.key + "\" appears twice in the same object",
                       "keep one of them (only the last one would count)"});
  }

  std::string path() const {
    std::string text;
    for (const auto& frame : frames_) {
      text += '/';
      text += frame.object ? escape_path_segment(frame.key) : std::to_string(frame.items - 1);
    }
    return text;
  }

  std::vector<Frame> frames_;
  std::vector<ValidationError> errors_;
  std::vector<std::string_view> numbers_;
  std::size_t next_number_ = 0;
};

// A syntax error at a byte of the text, by line and column.
ValidationError syntax_error_at(std::size_t index, std::string_view text, const std::string& reason,
                                std::string fix) {
  index = std::min(index, text.size());
  const auto before = text.substr(0, index);
  const auto line = 1 + std::count(before.begin(), before.end(), '\n');
  const auto line_start = before.rfind('\n');
  const auto column = line_start == std::string_view::npos ? index + 1 : index - line_start;
  return {"",
          "JSON syntax error at line " + std::to_string(line) + ", column " +
              std::to_string(column) + ": " + reason,
          std::move(fix)};
}

// Line and column from the parser's byte offset, plus the parser's reason.
ValidationError syntax_error(const json::parse_error& error, std::string_view text) {
  std::string reason = error.what();
  const auto column_text = reason.find("column ");
  const auto colon =
      column_text == std::string::npos ? std::string::npos : reason.find(": ", column_text);
  if (colon != std::string::npos) reason = reason.substr(colon + 2);
  if (reason.starts_with("syntax error "))
    reason.erase(0, std::string_view("syntax error ").size());
  return syntax_error_at(error.byte == 0 ? 0 : error.byte - 1, text, reason,
                         "correct the JSON there (a missing comma or quote, or a comma before } or "
                         "], is the usual cause)");
}

}  // namespace

ParsedJson parse_json_text(std::string_view text) {
  // The parser takes a NUL byte for the end of the text and would ignore what follows it.
  if (const auto nul = text.find('\0'); nul != std::string_view::npos) {
    throw InvalidInput({syntax_error_at(nul, text, "a NUL byte",
                                        "remove it (JSON text has none; write \\u0000 in a "
                                        "string for one)")});
  }
  DuplicateKeyFinder finder(text);
  ParsedJson parsed;
  try {
    parsed.document = json::parse(text, std::ref(finder));
  } catch (const json::parse_error& error) {
    throw InvalidInput({syntax_error(error, text)});
  } catch (const json::out_of_range& error) {  // a number beyond a double, e.g. 1e400
    std::string reason = error.what();
    if (const auto at = reason.find("] "); at != std::string::npos) reason.erase(0, at + 2);
    throw InvalidInput({{finder.current_value_path(), reason,
                         "write a number a double can hold (magnitude below 1.8e308)"}});
  }
  parsed.duplicate_keys = finder.take_errors();
  return parsed;
}

}  // namespace millflow::engine
