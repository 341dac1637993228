#include "engine/sweep.hpp"

#include <cmath>
#include <cstdlib>
#include <optional>

#include <fmt/format.h>

namespace millflow::engine {
namespace {

using nlohmann::json;

// Caps that keep a typo (a step of 1e-9) from generating millions of tasks. Validation builds
// every point's document: 40,000 points of the default campaign took 10 GB and 2 minutes.
constexpr std::size_t max_values_per_axis = 10000;
constexpr std::size_t max_points = 10000;

const std::vector<std::string> sweep_keys = {"product", "zip"};
const std::vector<std::string> range_keys = {"start", "stop", "num", "step"};
const char* const values_fix =
    "write a list [v1, v2, ...], a linspace {\"start\": a, \"stop\": b, \"num\": n} or a range "
    "{\"start\": a, \"stop\": b, \"step\": s}";

// One axis of the sweep: a product entry (one path) or a zip group (several paths in step).
struct Axis {
  std::vector<std::string> paths;
  std::vector<std::vector<json>> values;  // values[path][position]
  std::size_t size() const { return values.front().size(); }
};

bool is_prefix_path(const std::string& shorter, const std::string& longer) {
  return longer.size() >= shorter.size() && longer.compare(0, shorter.size(), shorter) == 0 &&
         (longer.size() == shorter.size() || longer[shorter.size()] == '/');
}

std::vector<std::string> table_paths(const FieldTable& table) {
  std::vector<std::string> paths;
  for (const auto& rule : table.rules()) {
    if (!rule.path.empty()) paths.push_back(rule.path);
  }
  return paths;
}

// Reads the sweep block, validating every part of it; errors are collected, never thrown.
class SweepReader {
 public:
  SweepReader(const json& document, const FieldTable& table) : document_(document), table_(table) {}

  std::vector<Axis> read(const json& sweep) {
    std::vector<Axis> axes;
    if (!sweep.is_object()) {
      error("/sweep", "expected an object, got " + describe_value(sweep),
            "write {\"product\": {...}, \"zip\": [...]}");
      return axes;
    }
    for (const auto& [key, value] : sweep.items()) {
      if (key == "product") {
        read_product(value, axes);
      } else if (key == "zip") {
        read_zip(value, axes);
      } else {
        const auto suggestion = closest_match(key, sweep_keys);
        error("/sweep/" + escape_path_segment(key), "unknown field \"" + key + "\"",
              suggestion ? "did you mean \"" + *suggestion + "\"?"
                         : "allowed fields here: \"product\", \"zip\"");
      }
    }
    return axes;
  }

  std::vector<ValidationError> take_errors() { return std::move(errors_); }

 private:
  void error(std::string path, std::string problem, std::string fix) {
    errors_.push_back({std::move(path), std::move(problem), std::move(fix)});
  }

  void read_product(const json& product, std::vector<Axis>& axes) {
    if (!product.is_object()) {
      error("/sweep/product", "expected an object, got " + describe_value(product),
            "map each swept path to its values, e.g. {\"/macro/fill\": [0.2, 0.3]}");
      return;
    }
    for (const auto& [path, spec] : product.items()) {
      auto values = read_entry(path, spec, "/sweep/product/" + escape_path_segment(path));
      if (values) axes.push_back({{path}, {std::move(*values)}});
    }
  }

  void read_zip(const json& zip, std::vector<Axis>& axes) {
    if (!zip.is_array()) {
      error("/sweep/zip", "expected a list, got " + describe_value(zip),
            "write a list of groups, e.g. [{\"/a\": [1, 2], \"/b\": [3, 4]}]");
      return;
    }
    for (std::size_t g = 0; g < zip.size(); ++g) {
      const auto group_path = "/sweep/zip/" + std::to_string(g);
      if (!zip[g].is_object() || zip[g].empty()) {
        error(group_path,
              zip[g].is_object() ? "empty zip group"
                                 : "expected an object, got " + describe_value(zip[g]),
              "map each path of the group to its values, e.g. {\"/a\": [1, 2], \"/b\": [3, 4]}");
        continue;
      }
      Axis axis;
      bool complete = true;
      for (const auto& [path, spec] : zip[g].items()) {
        auto values = read_entry(path, spec, group_path + "/" + escape_path_segment(path));
        complete = complete && values.has_value();
        if (values) {
          axis.paths.push_back(path);
          axis.values.push_back(std::move(*values));
        }
      }
      if (complete && equal_lengths(axis, group_path)) axes.push_back(std::move(axis));
    }
  }

  bool equal_lengths(const Axis& axis, const std::string& group_path) {
    for (std::size_t i = 1; i < axis.paths.size(); ++i) {
      if (axis.values[i].size() == axis.values[0].size()) continue;
      error(group_path,
            fmt::format("lists of different lengths: \"{}\" has {} values, \"{}\" has {}",
                        axis.paths[0], axis.values[0].size(), axis.paths[i], axis.values[i].size()),
            "give every path of a zip group the same number of values");
      return false;
    }
    return true;
  }

  // The validated, normalized values of one swept path, or nothing when it has errors.
  std::optional<std::vector<json>> read_entry(const std::string& path, const json& spec,
                                              const std::string& error_path) {
    const auto* rule = swept_field(path, error_path);
    auto raw = read_values(spec, error_path);
    if (rule == nullptr || !raw) return std::nullopt;
    std::vector<json> values;
    bool valid = true;
    for (std::size_t i = 0; i < raw->size(); ++i) {
      auto result =
          validate_field((*raw)[i], rule->path, table_, error_path + "/" + std::to_string(i));
      valid = valid && result.ok();
      for (auto& e : result.errors) errors_.push_back(std::move(e));
      values.push_back(std::move(result.document));
    }
    if (!valid) return std::nullopt;
    return values;
  }

  // The rule of a swept path, checking that the path is a field the document holds and that no
  // other entry of the sweep covers it.
  const FieldRule* swept_field(const std::string& path, const std::string& error_path) {
    if (path.empty() || path.front() != '/') {
      error(error_path, "\"" + path + "\" is not a JSON path",
            "start it at the document root: \"/" + path + "\"");
      return nullptr;
    }
    const auto* rule = table_.match(path);
    if (rule == nullptr) {
      const auto suggestion = closest_match(path, table_paths(table_));
      error(error_path, "\"" + path + "\" is not a field of this file",
            suggestion ? "did you mean \"" + *suggestion + "\"?"
                       : "sweep a field the schema defines");
      return nullptr;
    }
    // Its values would pass unchecked (the block's own checks read the file's, not a point's),
    // and a sweep block in a point changes nothing.
    if (rule->opaque) {
      error(error_path, "\"" + path + "\" cannot be swept",
            "sweep the fields of the file, not the sweep block");
      return nullptr;
    }
    for (std::string owner = path; !owner.empty(); owner = owner.substr(0, owner.rfind('/'))) {
      if (const auto* owner_rule = table_.match(owner); owner_rule && owner_rule->whole_campaign) {
        error(error_path,
              "\"" + path +
                  "\" holds one value for the whole campaign; a sweep would change it "
                  "to no effect",
              "sweep the fields of the runs (mill, macro, shear_cell, ...) or write one file "
              "per value");
        return nullptr;
      }
    }
    if (!holds(path)) {
      error(error_path, "\"" + path + "\" is not set in this file",
            "set it outside the sweep first, or sweep a field that is set");
      return nullptr;
    }
    for (const auto& earlier : swept_paths_) {
      if (earlier == path) {
        error(error_path, "\"" + path + "\" is swept more than once",
              "sweep each field in one place only");
        return nullptr;
      }
      if (is_prefix_path(earlier, path) || is_prefix_path(path, earlier)) {
        error(error_path, "\"" + path + "\" overlaps \"" + earlier + "\", swept elsewhere",
              "sweep each field in one place only");
        return nullptr;
      }
    }
    swept_paths_.push_back(path);
    return rule;
  }

  bool holds(const std::string& path) const {
    try {
      return document_.contains(json::json_pointer(path));
    } catch (const json::exception&) {
      return false;  // a malformed pointer ("~2") or a non-numeric index into a list
    }
  }

  std::optional<std::vector<json>> read_values(const json& spec, const std::string& error_path) {
    if (spec.is_array()) {
      if (spec.empty()) {
        error(error_path, "empty list of values", "give at least one value");
        return std::nullopt;
      }
      return std::vector<json>(spec.begin(), spec.end());
    }
    if (spec.is_object()) return read_range(spec, error_path);
    error(error_path, "expected a list of values or a range, got " + describe_value(spec),
          values_fix);
    return std::nullopt;
  }

  std::optional<std::vector<json>> read_range(const json& spec, const std::string& error_path) {
    bool valid = true;
    for (const auto& [key, value] : spec.items()) {
      if (std::find(range_keys.begin(), range_keys.end(), key) != range_keys.end()) continue;
      const auto suggestion = closest_match(key, range_keys);
      error(error_path + "/" + escape_path_segment(key), "unknown field \"" + key + "\"",
            suggestion ? "did you mean \"" + *suggestion + "\"?" : values_fix);
      valid = false;
    }
    const auto start = range_number(spec, "start", error_path);
    const auto stop = range_number(spec, "stop", error_path);
    if (spec.contains("num") == spec.contains("step")) {
      error(error_path,
            spec.contains("num") ? "sets \"num\" and \"step\" together"
                                 : "sets neither \"num\" nor \"step\"",
            "give exactly one of them: \"num\" (number of values) or \"step\" (spacing)");
      valid = false;
    }
    if (!valid || !start || !stop) return std::nullopt;
    if (!std::isfinite(*stop - *start)) {  // the values between would come out NaN
      error(error_path,
            fmt::format("the span from start {} to stop {} is beyond a double", quote_value(*start),
                        quote_value(*stop)),
            "narrow the range");
      return std::nullopt;
    }
    const auto generated = spec.contains("num")
                               ? range_by_count(spec.at("num"), *start, *stop, error_path)
                               : range_by_step(spec, *start, *stop, error_path);
    if (!generated) return std::nullopt;
    return std::vector<json>(generated->begin(), generated->end());
  }

  std::optional<double> range_number(const json& spec, const char* key,
                                     const std::string& error_path) {
    if (!spec.contains(key)) {
      error(error_path + "/" + key, "required field is missing",
            std::string("add \"") + key + "\", a number");
      return std::nullopt;
    }
    if (!spec.at(key).is_number()) {
      error(error_path + "/" + key, "expected a number, got " + describe_value(spec.at(key)),
            std::string("give \"") + key + "\" as a number");
      return std::nullopt;
    }
    return spec.at(key).get<double>();
  }

  std::optional<std::vector<double>> range_by_count(const json& num, double start, double stop,
                                                    const std::string& error_path) {
    const bool integral =
        num.is_number_integer() ||
        (num.is_number_float() && std::floor(num.get<double>()) == num.get<double>());
    if (!integral || num.get<double>() < 1 || num.get<double>() > double(max_values_per_axis)) {
      error(error_path + "/num", quote_value(num) + " is not a valid number of values",
            fmt::format("give an integer in [1, {}]", max_values_per_axis));
      return std::nullopt;
    }
    return linspace(start, stop, num.get<long long>());
  }

  std::optional<std::vector<double>> range_by_step(const json& spec, double start, double stop,
                                                   const std::string& error_path) {
    const auto step = range_number(spec, "step", error_path);
    if (!step) return std::nullopt;
    if (*step == 0.0 || (stop - start) / *step < 0.0) {
      error(error_path + "/step",
            fmt::format("step {} never reaches stop {} from start {}", quote_value(*step),
                        quote_value(stop), quote_value(start)),
            *step == 0.0 ? "use a non-zero step" : "flip the sign of the step");
      return std::nullopt;
    }
    if ((stop - start) / *step >= double(max_values_per_axis)) {
      error(
          error_path + "/step",
          fmt::format("step {} makes more than {} values", quote_value(*step), max_values_per_axis),
          "use a larger step");
      return std::nullopt;
    }
    return arange_inclusive(start, stop, *step);
  }

  const json& document_;
  const FieldTable& table_;
  std::vector<std::string> swept_paths_;
  std::vector<ValidationError> errors_;
};

struct ReadSweep {
  std::vector<Axis> axes;
  std::vector<ValidationError> errors;
};

ReadSweep read_sweep(const json& document, const FieldTable& table) {
  if (!document.is_object() || !document.contains("sweep")) return {};
  SweepReader reader(document, table);
  ReadSweep sweep;
  sweep.axes = reader.read(document.at("sweep"));
  sweep.errors = reader.take_errors();
  std::size_t points = 1;
  for (const auto& axis : sweep.axes) points *= axis.size();
  if (sweep.errors.empty() && points > max_points) {
    sweep.errors.push_back({"/sweep",
                            fmt::format("makes {} points, more than {}", points, max_points),
                            "split the study into several files"});
  }
  return sweep;
}

json values_schema() {
  const json number = {{"type", "number"}};
  json linspace_form = {
      {"type", "object"},
      {"properties",
       {{"start", number}, {"stop", number}, {"num", {{"type", "integer"}, {"minimum", 1}}}}},
      {"required", {"start", "stop", "num"}},
      {"additionalProperties", false}};
  json range_form = {{"type", "object"},
                     {"properties",
                      {{"start", number},
                       {"stop", number},
                       {"step", {{"type", "number"}, {"not", {{"const", 0}}}}}}},
                     {"required", {"start", "stop", "step"}},
                     {"additionalProperties", false}};
  return {{"description",
           "values of a swept field: a list, a linspace {start, stop, num} (both ends included) or "
           "a range "
           "{start, stop, step} (stop included when reached)"},
          {"oneOf", {{{"type", "array"}, {"minItems", 1}}, linspace_form, range_form}}};
}

}  // namespace

std::vector<ValidationError> check_sweep(const nlohmann::json& document, const FieldTable& table) {
  return read_sweep(document, table).errors;
}

std::vector<SweepPoint> expand_sweep(const nlohmann::json& document, const FieldTable& table) {
  auto sweep = read_sweep(document, table);
  if (!sweep.errors.empty()) throw InvalidInput(std::move(sweep.errors));
  json base = document;
  if (base.is_object()) base.erase("sweep");
  std::size_t count = 1;
  for (const auto& axis : sweep.axes) count *= axis.size();
  std::vector<SweepPoint> points;
  points.reserve(count);
  for (std::size_t index = 0; index < count; ++index) {
    SweepPoint point{base, {}};
    // Mixed-radix digits of the point index, the last axis varying fastest.
    std::size_t stride = count;
    for (const auto& axis : sweep.axes) {
      stride /= axis.size();
      const auto position = (index / stride) % axis.size();
      for (std::size_t p = 0; p < axis.paths.size(); ++p) {
        point.document[json::json_pointer(axis.paths[p])] = axis.values[p][position];
        point.coordinates.push_back({axis.paths[p], axis.values[p][position]});
      }
    }
    points.push_back(std::move(point));
  }
  return points;
}

double round_significant(double value, int digits) {
  if (value == 0.0 || !std::isfinite(value)) return value;
  // strtod, not stod: stod throws on a subnormal result (1e-320), which is a valid value.
  return std::strtod(fmt::format("{:.{}g}", value, digits).c_str(), nullptr);
}

std::vector<double> linspace(double start, double stop, long long num) {
  std::vector<double> values;
  if (num == 1) return {round_significant(start)};
  for (long long i = 0; i < num; ++i) {
    const double value = i + 1 == num ? stop : start + (stop - start) * double(i) / double(num - 1);
    values.push_back(round_significant(value));
  }
  return values;
}

std::vector<double> arange_inclusive(double start, double stop, double step) {
  // Count the steps with a 1e-9 relative allowance, so 0.6..0.9 by 0.1 includes 0.9.
  const double steps = (stop - start) / step;
  const auto last = static_cast<long long>(std::floor(steps * (1.0 + 1e-9) + 1e-12));
  std::vector<double> values;
  for (long long i = 0; i <= last; ++i)
    values.push_back(round_significant(start + double(i) * step));
  return values;
}

nlohmann::json sweep_json_schema() {
  const json path_names = {{"pattern", "^/"}};
  return {{"type", "object"},
          {"description",
           "parameter study: the Cartesian product of the product axes and the zip groups"},
          {"properties",
           {{"product",
             {{"type", "object"},
              {"description", "one axis per swept field (JSON pointer -> values)"},
              {"propertyNames", path_names},
              {"additionalProperties", values_schema()}}},
            {"zip",
             {{"type", "array"},
              {"description", "groups of fields swept together; each group is one axis"},
              {"items",
               {{"type", "object"},
                {"minProperties", 1},
                {"propertyNames", path_names},
                {"additionalProperties", values_schema()}}}}}}},
          {"additionalProperties", false}};
}

}  // namespace millflow::engine
