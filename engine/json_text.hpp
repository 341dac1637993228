#pragma once
// Parsing of JSON input files with errors users can act on: a syntax error names its line and
// column; a key written twice in one object (which JSON parsers silently resolve, each its own
// way) is reported with its path instead of being dropped.
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/validation.hpp"

namespace millflow::engine {

// The most levels of objects and lists a JSON input file may nest.
inline constexpr std::size_t kMaxJsonDepth = 100;

struct ParsedJson {
  nlohmann::json document;
  std::vector<ValidationError> duplicate_keys;  // one per repeated key; the document keeps the last
};

// Throws InvalidInput with the syntax error ("JSON syntax error at line L, column C: ...").
ParsedJson parse_json_text(std::string_view text);

}  // namespace millflow::engine
