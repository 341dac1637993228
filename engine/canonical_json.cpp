#include "engine/canonical_json.hpp"

#include <fmt/format.h>

#include <cmath>

#include "engine/validation.hpp"

namespace millflow::engine {
namespace {

void append_string(std::string& out, const std::string& text) {
  out += '"';
  for (const char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\b':
        out += "\\b";
        break;
      case '\f':
        out += "\\f";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += fmt::format("\\u{:04x}", static_cast<unsigned char>(c));
        } else {
          out += c;
        }
    }
  }
  out += '"';
}

void append_float(std::string& out, double value, const std::string& path) {
  if (!std::isfinite(value)) {
    throw InvalidInput({{path, fmt::format("{} is not a finite number", value),
                         "use a finite number (JSON has no NaN or infinity)"}});
  }
  if (value == 0.0) value = 0.0;                // folds -0.0 into 0.0
  std::string text = fmt::format("{}", value);  // shortest representation that round-trips
  if (text.find_first_of(".e") == std::string::npos) text += ".0";
  out += text;
}

void append_value(std::string& out, const nlohmann::json& value, const std::string& path) {
  using Type = nlohmann::json::value_t;
  switch (value.type()) {
    case Type::null:
      out += "null";
      return;
    case Type::boolean:
      out += value.get<bool>() ? "true" : "false";
      return;
    case Type::number_integer:
      out += fmt::format("{}", value.get<std::int64_t>());
      return;
    case Type::number_unsigned:
      out += fmt::format("{}", value.get<std::uint64_t>());
      return;
    case Type::number_float:
      append_float(out, value.get<double>(), path);
      return;
    case Type::string:
      append_string(out, value.get_ref<const std::string&>());
      return;
    case Type::array: {
      out += '[';
      for (std::size_t i = 0; i < value.size(); ++i) {
        if (i > 0) out += ',';
        append_value(out, value[i], path + "/" + std::to_string(i));
      }
      out += ']';
      return;
    }
    case Type::object: {
      out += '{';
      bool first = true;
      for (const auto& [key, member] : value.items()) {  // nlohmann's map keeps keys sorted
        if (!first) out += ',';
        first = false;
        append_string(out, key);
        out += ':';
        append_value(out, member, path + "/" + key);
      }
      out += '}';
      return;
    }
    case Type::binary:
    case Type::discarded:
      break;
  }
  throw InvalidInput({{path, "value has no JSON spelling", "use only JSON values"}});
}

}  // namespace

std::string canonical_json(const nlohmann::json& value) {
  std::string out;
  append_value(out, value, "");
  return out;
}

namespace {

void add_leaves(const nlohmann::json& value, const std::string& path,
                std::map<std::string, std::string>& leaves) {
  if (value.is_object() && !value.empty()) {
    for (const auto& [key, member] : value.items()) add_leaves(member, path + "/" + key, leaves);
  } else {
    leaves[path.empty() ? "/" : path] = canonical_json(value);
  }
}

}  // namespace

std::map<std::string, std::string> json_leaves(const nlohmann::json& value) {
  std::map<std::string, std::string> leaves;
  add_leaves(value, "", leaves);
  return leaves;
}

}  // namespace millflow::engine
