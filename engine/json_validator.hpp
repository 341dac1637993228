#pragma once
// A table-driven validator for JSON input files. The table lists every allowed field by its path
// pattern, with its type, range, unit, default and a description; validate() checks a document
// against it, collects every error at once (path, problem, fix), fills the defaults and returns the
// normalized document. The same table also produces the file's JSON Schema (to_json_schema), so
// the schema and the C++ checks cannot drift apart.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/validation.hpp"

namespace millflow::engine {

enum class FieldType { integer, number, string, boolean, object, array, enumeration };

// The most characters of a string or map key that a pattern checks: std::regex matches with one
// stack frame per character, and some ten thousand characters overflow the stack.
inline constexpr std::size_t kMaxPatternedLength = 200;

// One end of a numeric range.
struct Bound {
  double value = 0.0;
  bool inclusive = true;
};
inline Bound at_least(double value) {
  return {value, true};
}
inline Bound above(double value) {
  return {value, false};
}
inline Bound at_most(double value) {
  return {value, true};
}
inline Bound below(double value) {
  return {value, false};
}

// The rule for one field. `path` is a JSON-pointer pattern from the document root, e.g.
// "/mill/lifters/count"; a "*" segment stands for any key of a map or any item of an array (which
// of the two follows from the parent rule's type). An object rule without a "*" child accepts only
// the keys its child rules name.
struct FieldRule {
  std::string path;
  FieldType type = FieldType::object;
  std::string description;  // what the field means, without its unit
  std::string unit;         // SI unit ("m", "kg/m^3", "s"); empty for dimensionless values
  bool required = false;
  std::optional<nlohmann::json> default_value;  // filled in when the field is absent
  std::optional<Bound> minimum;                 // numbers and integers
  std::optional<Bound> maximum;
  std::string pattern;                   // strings: ECMAScript regex the whole string must match;
                                         // maps ("*" child of an object): the keys must match it
  std::vector<std::string> choices;      // enumeration: the allowed strings; number: strings
                                         // allowed in place of a number (e.g. "auto")
  std::optional<std::size_t> min_items;  // arrays: item count; maps: entry count
  std::optional<std::size_t> max_items;
  bool unique_items = false;                // arrays: no item twice
  std::vector<std::string> exactly_one_of;  // objects: exactly one of these keys must be present
  bool opaque =
      false;  // objects whose contents another check owns (e.g. a sweep block): kept as is
  bool whole_campaign = false;  // one value for the whole file (its name, executor): not swept
  std::string hint;             // extra advice appended to the fix of every error on this field
};

// Builds a FieldRule one property at a time, so tables read as one line per field:
//   Field("/mill/diameter", FieldType::number, "inner diameter of the mill shell").unit("m")
//       .required().range(at_least(0.1), at_most(15))
class Field {
 public:
  Field(std::string path, FieldType type, std::string description);
  Field& unit(std::string unit);
  Field& required();
  Field& defaults(nlohmann::json value);
  Field& range(std::optional<Bound> minimum, std::optional<Bound> maximum);
  Field& pattern(std::string pattern);
  Field& choices(std::vector<std::string> choices);
  // A number field that also takes one of these strings: "a number in (0, 2] or \"auto\"".
  Field& or_words(std::vector<std::string> words);
  Field& items(std::optional<std::size_t> minimum, std::optional<std::size_t> maximum);
  Field& unique();
  Field& exactly_one_of(std::vector<std::string> keys);
  Field& opaque();
  // A field (with everything under it) that holds one value for the whole file, which a sweep
  // would vary from point to point to no effect.
  Field& whole_campaign();
  Field& hint(std::string hint);
  operator FieldRule() const { return rule_; }  // NOLINT(google-explicit-constructor): table syntax

 private:
  FieldRule rule_;
};

class FieldTable {
 public:
  explicit FieldTable(std::vector<FieldRule> rules);

  const std::vector<FieldRule>& rules() const { return rules_; }
  // The rule whose pattern is exactly `pattern` ("" is the document root), or nullptr.
  const FieldRule* rule(std::string_view pattern) const;
  // The rule matching a concrete path such as "/interactions/0/friction", or nullptr.
  const FieldRule* match(std::string_view concrete_path) const;
  // The rules directly below `pattern`, in table order.
  std::vector<const FieldRule*> children(std::string_view pattern) const;

 private:
  std::vector<FieldRule> rules_;
};

struct ValidationResult {
  nlohmann::json document;  // defaults filled, numbers of "number" fields stored as floating point
  std::vector<ValidationError> errors;
  bool ok() const { return errors.empty(); }
};

// Validates a whole document against the table (its root must be an object).
ValidationResult validate(const nlohmann::json& document, const FieldTable& table);

// Validates `value` as the field at `pattern`; error paths start at `error_path` instead of the
// field's own path (the sweep reports errors of swept values where they were written).
ValidationResult validate_field(const nlohmann::json& value, std::string_view pattern,
                                const FieldTable& table, const std::string& error_path);

// JSON Schema (draft 2020-12) saying what the table says.
nlohmann::json to_json_schema(const FieldTable& table);

// Helpers shared by the engine's input checks.
// The candidate closest to `name` by edit distance, when close enough to be a likely typo.
std::optional<std::string> closest_match(std::string_view name,
                                         const std::vector<std::string>& candidates);
// RFC 6901 escaping of one path segment ("~" -> "~0", "/" -> "~1").
std::string escape_path_segment(std::string_view segment);
// A value as the messages quote it: strings in quotes, numbers in their shortest exact form.
std::string quote_value(const nlohmann::json& value);
// How an offending value is named in a problem text: `the string "4"`, `the number 2.5`, `a list`.
std::string describe_value(const nlohmann::json& value);

}  // namespace millflow::engine
