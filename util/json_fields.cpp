#include "util/json_fields.hpp"

#include <fmt/format.h>

#include <stdexcept>

namespace millflow::util {

using nlohmann::json;

bool JsonFields::contains(const std::string& pointer) const {
  return document_.contains(json::json_pointer(pointer));
}

const json& JsonFields::at(const std::string& pointer) const {
  const json::json_pointer where(pointer);
  if (!document_.contains(where)) refuse(pointer, "is missing");
  return document_.at(where);
}

double JsonFields::number(const std::string& pointer) const {
  const json& value = at(pointer);
  if (!value.is_number()) refuse(pointer, "is " + value.dump() + ", not a number");
  return value.get<double>();
}

std::optional<double> JsonFields::number_or_null(const std::string& pointer) const {
  if (at(pointer).is_null()) return std::nullopt;
  return number(pointer);
}

std::size_t JsonFields::count(const std::string& pointer) const {
  const json& value = at(pointer);
  if (!value.is_number_integer() || value.get<long long>() < 0)
    refuse(pointer, "is " + value.dump() + ", not a count");
  return value.get<std::size_t>();
}

std::string JsonFields::text(const std::string& pointer) const {
  const json& value = at(pointer);
  if (!value.is_string()) refuse(pointer, "is " + value.dump() + ", not a string");
  return value.get<std::string>();
}

std::optional<std::string> JsonFields::text_or_null(const std::string& pointer) const {
  if (at(pointer).is_null()) return std::nullopt;
  return text(pointer);
}

std::size_t JsonFields::array_size(const std::string& pointer) const {
  const json& value = at(pointer);
  if (!value.is_array()) refuse(pointer, "is not an array");
  return value.size();
}

std::vector<double> JsonFields::numbers(const std::string& pointer) const {
  std::vector<double> values;
  for (std::size_t i = 0; i < array_size(pointer); ++i)
    values.push_back(number(fmt::format("{}/{}", pointer, i)));
  return values;
}

std::vector<std::string> JsonFields::texts(const std::string& pointer) const {
  std::vector<std::string> values;
  for (std::size_t i = 0; i < array_size(pointer); ++i)
    values.push_back(text(fmt::format("{}/{}", pointer, i)));
  return values;
}

void JsonFields::refuse(const std::string& pointer, const std::string& problem) const {
  throw std::invalid_argument(fmt::format("{}: field {} {}; {}", owner_, pointer, problem, fix_));
}

}  // namespace millflow::util
