#pragma once
// Canonical JSON: the one spelling of a JSON value that task keys hash.
//  - object keys sorted by their UTF-8 bytes, no whitespace;
//  - integers as plain decimals; floating-point numbers in their shortest exact round-trip form,
//    always with a '.' or an exponent so that 1.0 stays distinct from the integer 1; -0.0 is 0.0;
//  - strings with the minimal JSON escapes (", \, control characters), everything else verbatim.
// NaN and infinities are not JSON and are refused with engine::InvalidInput.
#include <nlohmann/json.hpp>
#include <string>

namespace millflow::engine {

std::string canonical_json(const nlohmann::json& value);

}  // namespace millflow::engine
