#include "engine/json_validator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <regex>
#include <stdexcept>

#include <fmt/format.h>

namespace millflow::engine {
namespace {

using nlohmann::json;

std::string parent_pattern(std::string_view pattern) {
  const auto slash = pattern.rfind('/');
  return slash == std::string_view::npos ? std::string() : std::string(pattern.substr(0, slash));
}

std::string last_segment(std::string_view pattern) {
  const auto slash = pattern.rfind('/');
  return std::string(slash == std::string_view::npos ? pattern : pattern.substr(slash + 1));
}

std::vector<std::string> split_path(std::string_view path) {
  std::vector<std::string> segments;
  std::size_t start = 1;
  while (start <= path.size()) {
    const auto end = std::min(path.find('/', start), path.size());
    segments.emplace_back(path.substr(start, end - start));
    start = end + 1;
  }
  return segments;
}

std::string unescape_path_segment(std::string_view segment) {
  std::string text;
  for (std::size_t i = 0; i < segment.size(); ++i) {
    if (segment[i] == '~' && i + 1 < segment.size() &&
        (segment[i + 1] == '0' || segment[i + 1] == '1')) {
      text += segment[i + 1] == '0' ? '~' : '/';
      ++i;
    } else {
      text += segment[i];
    }
  }
  return text;
}

std::string format_number(double value) {
  return fmt::format("{}", value);
}

std::string quoted_list(const std::vector<std::string>& names) {
  std::string text;
  for (const auto& name : names) {
    if (!text.empty()) text += ", ";
    text += '"' + name + '"';
  }
  return text;
}

std::string with_unit(const std::string& number, const std::string& unit) {
  return unit.empty() ? number : number + " " + unit;
}

// "in [0.1, 15] m", ">= 20", "> 0 s".
std::string range_text(const FieldRule& rule) {
  if (rule.minimum && rule.maximum) {
    return with_unit(
        fmt::format("in {}{}, {}{}", rule.minimum->inclusive ? '[' : '(',
                    format_number(rule.minimum->value), format_number(rule.maximum->value),
                    rule.maximum->inclusive ? ']' : ')'),
        rule.unit);
  }
  if (rule.minimum) {
    return with_unit(fmt::format("{} {}", rule.minimum->inclusive ? ">=" : ">",
                                 format_number(rule.minimum->value)),
                     rule.unit);
  }
  if (rule.maximum) {
    return with_unit(fmt::format("{} {}", rule.maximum->inclusive ? "<=" : "<",
                                 format_number(rule.maximum->value)),
                     rule.unit);
  }
  return {};
}

// ' or "auto"', ' or one of "a", "b"': the words a number field takes in place of a number.
std::string or_words_text(const FieldRule& rule) {
  if (rule.type != FieldType::number || rule.choices.empty()) return {};
  return rule.choices.size() == 1 ? " or " + quoted_list(rule.choices)
                                  : " or one of " + quoted_list(rule.choices);
}

std::string type_name(const FieldRule& rule) {
  switch (rule.type) {
    case FieldType::integer:
      return "an integer";
    case FieldType::number:
      return "a number" + or_words_text(rule);
    case FieldType::string:
      return "a string";
    case FieldType::boolean:
      return "true or false";
    case FieldType::object:
      return "an object";
    case FieldType::array:
      return "a list";
    case FieldType::enumeration:
      return "one of " + quoted_list(rule.choices);
  }
  return {};
}

// "a number in [0.1, 15] m": the type with its range, as the fixes describe a field.
std::string type_with_range(const FieldRule& rule) {
  const auto range = range_text(rule);
  if (range.empty()) return type_name(rule) + (rule.unit.empty() ? "" : " in " + rule.unit);
  if (rule.type == FieldType::number) return "a number " + range + or_words_text(rule);
  return type_name(rule) + " " + range;
}

std::string add_hint(std::string fix, const FieldRule& rule) {
  if (!rule.hint.empty()) fix += "; " + rule.hint;
  return fix;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  // Optimal string alignment distance: insertions, deletions, substitutions and adjacent swaps.
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[a.size()][b.size()];
}

std::string too_long(const std::string& text, const std::string& what) {
  return fmt::format("{} has {} characters, more than {}", what, text.size(), kMaxPatternedLength);
}

// Only for texts of at most kMaxPatternedLength characters.
bool full_match(const std::string& text, const std::string& pattern) {
  return std::regex_match(text, std::regex(pattern, std::regex::ECMAScript));
}

bool in_range(double value, const FieldRule& rule) {
  if (rule.minimum &&
      (rule.minimum->inclusive ? value < rule.minimum->value : value <= rule.minimum->value)) {
    return false;
  }
  if (rule.maximum &&
      (rule.maximum->inclusive ? value > rule.maximum->value : value >= rule.maximum->value)) {
    return false;
  }
  return true;
}

// Walks a document alongside the table, collecting errors and building the normalized copy.
class Checker {
 public:
  explicit Checker(const FieldTable& table) : table_(table) {}

  json check(const json& value, const FieldRule& rule, const std::string& path) {
    switch (rule.type) {
      case FieldType::integer:
        return check_integer(value, rule, path);
      case FieldType::number:
        return check_number(value, rule, path);
      case FieldType::string:
        return check_string(value, rule, path);
      case FieldType::boolean:
        return check_boolean(value, rule, path);
      case FieldType::enumeration:
        return check_enumeration(value, rule, path);
      case FieldType::object:
        return check_object(value, rule, path);
      case FieldType::array:
        return check_array(value, rule, path);
    }
    return value;
  }

  std::vector<ValidationError> take_errors() { return std::move(errors_); }

 private:
  void report(const std::string& path, std::string problem, std::string fix) {
    errors_.push_back({path, std::move(problem), std::move(fix)});
  }

  void report(const std::string& path, std::string problem, std::string fix,
              const FieldRule& rule) {
    report(path, std::move(problem), add_hint(std::move(fix), rule));
  }

  json wrong_type(const json& value, const FieldRule& rule, const std::string& path) {
    report(path, "expected " + type_name(rule) + ", got " + describe_value(value),
           "give " + rule.description + " as " + type_name(rule) +
               (rule.unit.empty() ? "" : " in " + rule.unit),
           rule);
    return value;
  }

  void check_range(double number, const json& value, const FieldRule& rule,
                   const std::string& path) {
    if (in_range(number, rule)) return;
    report(path, with_unit(quote_value(value), rule.unit) + " is out of range",
           rule.description + " must be " + range_text(rule) + or_words_text(rule), rule);
  }

  json check_integer(const json& value, const FieldRule& rule, const std::string& path) {
    json integer;
    if (value.is_number_integer()) {
      integer = value;
    } else if (value.is_number_float() && std::floor(value.get<double>()) == value.get<double>() &&
               std::abs(value.get<double>()) < 9.0e15) {
      integer =
          static_cast<std::int64_t>(value.get<double>());  // 2.0 is an integer, as in JSON Schema
    } else {
      return wrong_type(value, rule, path);
    }
    check_range(integer.get<double>(), integer, rule, path);
    return integer;
  }

  json check_number(const json& value, const FieldRule& rule, const std::string& path) {
    if (value.is_string() && !rule.choices.empty())
      return check_choice(value, rule, path, type_with_range(rule), type_with_range(rule));
    if (!value.is_number()) return wrong_type(value, rule, path);
    // One spelling per number: 1 and 1.0 give the same normalized document (and cache key).
    const json number = value.get<double>();
    check_range(number.get<double>(), number, rule, path);
    return number;
  }

  json check_string(const json& value, const FieldRule& rule, const std::string& path) {
    if (!value.is_string()) return wrong_type(value, rule, path);
    if (rule.pattern.empty()) return value;
    const auto& text = value.get_ref<const std::string&>();
    if (text.size() > kMaxPatternedLength) {
      report(path, too_long(text, "the string"),
             fmt::format("give {} as at most {} characters matching {}", rule.description,
                         kMaxPatternedLength, rule.pattern),
             rule);
    } else if (!full_match(text, rule.pattern)) {
      report(path, quote_value(value) + " does not match the pattern " + rule.pattern,
             "give " + rule.description + " as a string matching it", rule);
    }
    return value;
  }

  json check_boolean(const json& value, const FieldRule& rule, const std::string& path) {
    if (!value.is_boolean()) return wrong_type(value, rule, path);
    return value;
  }

  json check_enumeration(const json& value, const FieldRule& rule, const std::string& path) {
    if (!value.is_string()) return wrong_type(value, rule, path);
    return check_choice(value, rule, path, quoted_list(rule.choices),
                        "one of " + quoted_list(rule.choices));
  }

  // A string that must be one of the rule's choices; `allowed` lists what the field takes, `use`
  // says it as the fix's object.
  json check_choice(const json& value, const FieldRule& rule, const std::string& path,
                    const std::string& allowed, const std::string& use) {
    const auto text = value.get<std::string>();
    if (std::find(rule.choices.begin(), rule.choices.end(), text) != rule.choices.end())
      return value;
    const auto suggestion = closest_match(text, rule.choices);
    report(path, quote_value(value) + " is not allowed",
           suggestion ? "did you mean \"" + *suggestion + "\"? (allowed: " + allowed + ")"
                      : "use " + use,
           rule);
    return value;
  }

  void check_count(std::size_t count, const FieldRule& rule, const std::string& path) {
    const bool too_few = rule.min_items && count < *rule.min_items;
    const bool too_many = rule.max_items && count > *rule.max_items;
    if (!too_few && !too_many) return;
    const auto counted = [&](std::size_t n) {
      const bool entries = rule.type == FieldType::object;
      return fmt::format("{} {}", n,
                         n == 1 ? (entries ? "entry" : "item") : (entries ? "entries" : "items"));
    };
    std::string wanted;
    if (rule.min_items && rule.max_items) {
      wanted = *rule.min_items == *rule.max_items
                   ? "exactly " + counted(*rule.min_items)
                   : fmt::format("between {} and {}", *rule.min_items, counted(*rule.max_items));
    } else {
      wanted = rule.min_items ? "at least " + counted(*rule.min_items)
                              : "at most " + counted(*rule.max_items);
    }
    report(path, "has " + counted(count), "give " + wanted, rule);
  }

  json check_object(const json& value, const FieldRule& rule, const std::string& path) {
    if (!value.is_object()) return wrong_type(value, rule, path);
    if (rule.opaque) return value;
    const auto* map_items = table_.rule(rule.path + "/*");
    json normalized = map_items ? check_map_entries(value, rule, *map_items, path)
                                : check_named_fields(value, rule, path);
    check_count(value.size(), rule, path);
    check_exactly_one_of(value, rule, path);
    return normalized;
  }

  json check_map_entries(const json& value, const FieldRule& rule, const FieldRule& item,
                         const std::string& path) {
    json normalized = json::object();
    for (const auto& [key, entry] : value.items()) {
      const auto entry_path = path + "/" + escape_path_segment(key);
      if (!rule.pattern.empty()) check_name(key, rule, entry_path);
      normalized[key] = check(entry, item, entry_path);
    }
    return normalized;
  }

  void check_name(const std::string& key, const FieldRule& rule, const std::string& path) {
    if (key.size() > kMaxPatternedLength) {
      report(path, too_long(key, "the name"),
             fmt::format("rename it to at most {} characters", kMaxPatternedLength), rule);
    } else if (!full_match(key, rule.pattern)) {
      report(path, "name \"" + key + "\" does not match the pattern " + rule.pattern, "rename it",
             rule);
    }
  }

  json check_named_fields(const json& value, const FieldRule& rule, const std::string& path) {
    const auto fields = table_.children(rule.path);
    std::vector<std::string> names;
    for (const auto* field : fields) names.push_back(last_segment(field->path));
    json normalized = json::object();
    for (const auto& [key, entry] : value.items()) {
      if (std::find(names.begin(), names.end(), key) != names.end()) continue;
      const auto suggestion = closest_match(key, names);
      report(path + "/" + escape_path_segment(key), "unknown field \"" + key + "\"",
             suggestion ? "did you mean \"" + *suggestion + "\"?"
                        : "allowed fields here: " + quoted_list(names));
    }
    for (std::size_t i = 0; i < fields.size(); ++i) {
      const auto field_path = path + "/" + escape_path_segment(names[i]);
      if (value.contains(names[i])) {
        normalized[names[i]] = check(value.at(names[i]), *fields[i], field_path);
      } else if (fields[i]->required) {
        report(field_path, "required field is missing",
               "add " + fields[i]->description + ", " + type_with_range(*fields[i]), *fields[i]);
      } else if (fields[i]->default_value) {
        normalized[names[i]] = check(*fields[i]->default_value, *fields[i], field_path);
      }
    }
    return normalized;
  }

  void check_exactly_one_of(const json& value, const FieldRule& rule, const std::string& path) {
    if (rule.exactly_one_of.empty()) return;
    std::vector<std::string> present;
    for (const auto& key : rule.exactly_one_of) {
      if (value.contains(key)) present.push_back(key);
    }
    if (present.size() == 1) return;
    if (present.empty()) {
      report(path, "sets none of " + quoted_list(rule.exactly_one_of), "add exactly one of them",
             rule);
    } else {
      report(path, "sets " + quoted_list(present) + " together",
             "keep exactly one of " + quoted_list(rule.exactly_one_of), rule);
    }
  }

  json check_array(const json& value, const FieldRule& rule, const std::string& path) {
    if (!value.is_array()) return wrong_type(value, rule, path);
    const auto* item = table_.rule(rule.path + "/*");
    json normalized = json::array();
    for (std::size_t i = 0; i < value.size(); ++i) {
      const auto item_path = path + "/" + std::to_string(i);
      normalized.push_back(item ? check(value[i], *item, item_path) : value[i]);
      if (rule.unique_items &&
          std::find(value.begin(), value.begin() + static_cast<std::ptrdiff_t>(i), value[i]) !=
              value.begin() + static_cast<std::ptrdiff_t>(i)) {
        report(item_path, quote_value(value[i]) + " appears more than once", "list each value once",
               rule);
      }
    }
    check_count(value.size(), rule, path);
    return normalized;
  }

  const FieldTable& table_;
  std::vector<ValidationError> errors_;
};

json number_bounds_schema(const FieldRule& rule) {
  // Integer fields get integer bounds, so the schema reads as the table does.
  const auto bound = [&](double value) {
    return rule.type == FieldType::integer ? json(static_cast<std::int64_t>(value)) : json(value);
  };
  json schema = json::object();
  if (rule.minimum)
    schema[rule.minimum->inclusive ? "minimum" : "exclusiveMinimum"] = bound(rule.minimum->value);
  if (rule.maximum)
    schema[rule.maximum->inclusive ? "maximum" : "exclusiveMaximum"] = bound(rule.maximum->value);
  return schema;
}

std::string anchored(const std::string& pattern) {
  return "^(?:" + pattern + ")$";
}

json patterned_schema(const FieldRule& rule) {
  return {{"pattern", anchored(rule.pattern)}, {"maxLength", kMaxPatternedLength}};
}

json schema_of(const FieldRule& rule, const FieldTable& table);

json object_schema(const FieldRule& rule, const FieldTable& table) {
  json schema = {{"type", "object"}};
  if (rule.opaque) return schema;
  if (const auto* entries = table.rule(rule.path + "/*")) {
    schema["additionalProperties"] = schema_of(*entries, table);
    if (!rule.pattern.empty()) schema["propertyNames"] = patterned_schema(rule);
  } else {
    schema["properties"] = json::object();
    json required = json::array();
    for (const auto* field : table.children(rule.path)) {
      const auto name = last_segment(field->path);
      schema["properties"][name] = schema_of(*field, table);
      if (field->required) required.push_back(name);
    }
    if (!required.empty()) schema["required"] = required;
    schema["additionalProperties"] = false;
  }
  if (rule.min_items) schema["minProperties"] = *rule.min_items;
  if (rule.max_items) schema["maxProperties"] = *rule.max_items;
  if (!rule.exactly_one_of.empty()) {
    json alternatives = json::array();
    for (const auto& key : rule.exactly_one_of) alternatives.push_back({{"required", {key}}});
    schema["oneOf"] = alternatives;
  }
  return schema;
}

json array_schema(const FieldRule& rule, const FieldTable& table) {
  json schema = {{"type", "array"}};
  if (const auto* item = table.rule(rule.path + "/*")) schema["items"] = schema_of(*item, table);
  if (rule.min_items) schema["minItems"] = *rule.min_items;
  if (rule.max_items) schema["maxItems"] = *rule.max_items;
  if (rule.unique_items) schema["uniqueItems"] = true;
  return schema;
}

json schema_of(const FieldRule& rule, const FieldTable& table) {
  json schema;
  switch (rule.type) {
    case FieldType::integer:
      schema = number_bounds_schema(rule);
      schema["type"] = "integer";
      break;
    case FieldType::number:
      schema = number_bounds_schema(rule);
      schema["type"] = "number";
      if (!rule.choices.empty()) {
        schema = {{"anyOf", {schema, {{"type", "string"}, {"enum", rule.choices}}}}};
      }
      break;
    case FieldType::string:
      schema = {{"type", "string"}};
      if (!rule.pattern.empty()) schema.update(patterned_schema(rule));
      break;
    case FieldType::boolean:
      schema = {{"type", "boolean"}};
      break;
    case FieldType::enumeration:
      schema = {{"type", "string"}, {"enum", rule.choices}};
      break;
    case FieldType::object:
      schema = object_schema(rule, table);
      break;
    case FieldType::array:
      schema = array_schema(rule, table);
      break;
  }
  schema["description"] =
      rule.unit.empty() ? rule.description : rule.description + " [" + rule.unit + "]";
  if (rule.default_value) schema["default"] = *rule.default_value;
  return schema;
}

}  // namespace

Field::Field(std::string path, FieldType type, std::string description) {
  rule_.path = std::move(path);
  rule_.type = type;
  rule_.description = std::move(description);
}

Field& Field::unit(std::string unit) {
  rule_.unit = std::move(unit);
  return *this;
}

Field& Field::required() {
  rule_.required = true;
  return *this;
}

Field& Field::defaults(nlohmann::json value) {
  rule_.default_value = std::move(value);
  return *this;
}

Field& Field::range(std::optional<Bound> minimum, std::optional<Bound> maximum) {
  rule_.minimum = minimum;
  rule_.maximum = maximum;
  return *this;
}

Field& Field::pattern(std::string pattern) {
  rule_.pattern = std::move(pattern);
  return *this;
}

Field& Field::choices(std::vector<std::string> choices) {
  rule_.choices = std::move(choices);
  return *this;
}

Field& Field::or_words(std::vector<std::string> words) {
  if (rule_.type != FieldType::number)
    throw std::logic_error("field table: or_words on \"" + rule_.path + "\", not a number");
  rule_.choices = std::move(words);
  return *this;
}

Field& Field::items(std::optional<std::size_t> minimum, std::optional<std::size_t> maximum) {
  rule_.min_items = minimum;
  rule_.max_items = maximum;
  return *this;
}

Field& Field::unique() {
  rule_.unique_items = true;
  return *this;
}

Field& Field::exactly_one_of(std::vector<std::string> keys) {
  rule_.exactly_one_of = std::move(keys);
  return *this;
}

Field& Field::opaque() {
  rule_.opaque = true;
  return *this;
}

Field& Field::whole_campaign() {
  rule_.whole_campaign = true;
  return *this;
}

Field& Field::hint(std::string hint) {
  rule_.hint = std::move(hint);
  return *this;
}

FieldTable::FieldTable(std::vector<FieldRule> rules) : rules_(std::move(rules)) {
  if (rule("") == nullptr) rules_.insert(rules_.begin(), Field("", FieldType::object, "document"));
  // A rule whose parent is missing or not a container would never be reached: a table bug.
  for (const auto& field : rules_) {
    if (field.path.empty()) continue;
    const auto* parent = rule(parent_pattern(field.path));
    if (parent == nullptr ||
        (parent->type != FieldType::object && parent->type != FieldType::array)) {
      throw std::logic_error("field table: rule \"" + field.path +
                             "\" has no object or list parent");
    }
  }
}

const FieldRule* FieldTable::rule(std::string_view pattern) const {
  const auto found =
      std::find_if(rules_.begin(), rules_.end(), [&](const auto& r) { return r.path == pattern; });
  return found == rules_.end() ? nullptr : &*found;
}

const FieldRule* FieldTable::match(std::string_view concrete_path) const {
  if (concrete_path.empty()) return rule("");
  if (concrete_path.front() != '/') return nullptr;
  const auto segments = split_path(concrete_path);
  for (const auto& candidate : rules_) {
    if (candidate.path.empty()) continue;
    const auto pattern = split_path(candidate.path);
    if (pattern.size() != segments.size()) continue;
    bool same = true;
    for (std::size_t i = 0; i < pattern.size() && same; ++i) {
      same = pattern[i] == "*" || pattern[i] == unescape_path_segment(segments[i]);
    }
    if (same) return &candidate;
  }
  return nullptr;
}

std::vector<const FieldRule*> FieldTable::children(std::string_view pattern) const {
  std::vector<const FieldRule*> found;
  for (const auto& candidate : rules_) {
    if (!candidate.path.empty() && parent_pattern(candidate.path) == pattern)
      found.push_back(&candidate);
  }
  return found;
}

ValidationResult validate(const nlohmann::json& document, const FieldTable& table) {
  return validate_field(document, "", table, "");
}

ValidationResult validate_field(const nlohmann::json& value, std::string_view pattern,
                                const FieldTable& table, const std::string& error_path) {
  const auto* rule = table.rule(pattern);
  if (rule == nullptr)
    throw std::logic_error("field table has no rule \"" + std::string(pattern) + "\"");
  Checker checker(table);
  ValidationResult result;
  result.document = checker.check(value, *rule, error_path);
  result.errors = checker.take_errors();
  return result;
}

nlohmann::json to_json_schema(const FieldTable& table) {
  json schema = schema_of(*table.rule(""), table);
  schema["$schema"] = "https://json-schema.org/draft/2020-12/schema";
  return schema;
}

std::optional<std::string> closest_match(std::string_view name,
                                         const std::vector<std::string>& candidates) {
  const std::size_t tolerance = std::max<std::size_t>(1, name.size() / 3);
  std::optional<std::string> best;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  for (const auto& candidate : candidates) {
    const auto distance = edit_distance(name, candidate);
    if (distance <= tolerance && distance < best_distance) {
      best = candidate;
      best_distance = distance;
    }
  }
  return best;
}

std::string escape_path_segment(std::string_view segment) {
  std::string text;
  for (const char c : segment) {
    if (c == '~') {
      text += "~0";
    } else if (c == '/') {
      text += "~1";
    } else {
      text += c;
    }
  }
  return text;
}

std::string quote_value(const nlohmann::json& value) {
  if (value.is_number_float()) return format_number(value.get<double>());
  return value.dump();
}

std::string describe_value(const nlohmann::json& value) {
  if (value.is_string()) return "the string " + quote_value(value);
  if (value.is_number()) return "the number " + quote_value(value);
  if (value.is_boolean())
    return std::string("the boolean ") + (value.get<bool>() ? "true" : "false");
  if (value.is_object()) return "an object";
  if (value.is_array()) return "a list";
  return "null";
}

}  // namespace millflow::engine
