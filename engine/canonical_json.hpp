#pragma once
// Canonical JSON: the one spelling of a JSON value that task keys hash.
//  - object keys sorted by their UTF-8 bytes, no whitespace;
//  - integers as plain decimals; floating-point numbers in their shortest exact round-trip form,
//    always with a '.' or an exponent so that 1.0 stays distinct from the integer 1; -0.0 is 0.0;
//  - strings with the minimal JSON escapes (", \, control characters), everything else verbatim.
// NaN and infinities are not JSON and are refused with engine::InvalidInput.
#include <map>
#include <nlohmann/json.hpp>
#include <string>

namespace millflow::engine {

std::string canonical_json(const nlohmann::json& value);

// The leaves of a JSON value by path ("/a/b"; "/" for a value that is no object), each spelled
// canonically; an array is one leaf. Parameter diffs and CSV columns are made of these.
std::map<std::string, std::string> json_leaves(const nlohmann::json& value);

}  // namespace millflow::engine
