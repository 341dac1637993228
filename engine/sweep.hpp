#pragma once
// Expansion of a document's `sweep` block into the points of a parameter study.
//
//   "sweep": {
//     "product": {"/macro/fill": [0.2, 0.3], "/macro/speed_fraction": {"start": 0.6, "stop": 0.9,
//     "step": 0.1}}, "zip": [{"/a": [1, 2, 3], "/b": {"start": 0, "stop": 1, "num": 3}}]
//   }
//
// Each product entry is one axis; each zip group is one axis whose paths advance together (their
// value lists must have equal lengths). The points are the Cartesian product of all axes: product
// axes in path order (the keys of a JSON object are sorted), then zip groups in list order, the
// last axis varying fastest. Values are a list, a linspace {start, stop, num} (both ends included)
// or a range {start, stop, step} (stop included when it lands within 1e-9 relative). Generated
// values are rounded to 12 significant digits, so floating-point noise never reaches a cache key.
//
// Swept paths are JSON pointers into the document; they must name a field of the table that the
// document holds, and each value must pass that field's rule. Errors point at the value as written,
// e.g. "/sweep/product/~1macro~1fill/2" (RFC 6901 escapes "/" in the key as "~1").
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/json_validator.hpp"
#include "engine/validation.hpp"

namespace millflow::engine {

struct SweepCoordinate {
  std::string path;      // JSON pointer of the swept field, e.g. "/macro/fill"
  nlohmann::json value;  // its value at this point (normalized by the field's rule)
  bool operator==(const SweepCoordinate&) const = default;
};

struct SweepPoint {
  nlohmann::json document;                   // the whole document at this point, without "sweep"
  std::vector<SweepCoordinate> coordinates;  // the swept values that define the point, axis order
};

// Every error of the `sweep` block of `document` (a normalized document: defaults filled). A
// document without a sweep has none.
std::vector<ValidationError> check_sweep(const nlohmann::json& document, const FieldTable& table);

// The points of the document's sweep (one point, with no coordinates, when it has none).
// Throws InvalidInput with every error of the sweep block.
std::vector<SweepPoint> expand_sweep(const nlohmann::json& document, const FieldTable& table);

// The values of a range form, rounded to 12 significant digits (exposed for tests and docs).
std::vector<double> linspace(double start, double stop, long long num);
std::vector<double> arange_inclusive(double start, double stop, double step);
double round_significant(double value, int digits = 12);

// JSON Schema (draft 2020-12) of a sweep block, for embedding in a document's schema.
nlohmann::json sweep_json_schema();

}  // namespace millflow::engine
