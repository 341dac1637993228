#pragma once
// Typed reads from one JSON document by JSON pointer, for a reader that validates another
// program's (or an older version's) output: a missing or ill-typed value throws
// std::invalid_argument "<owner>: field <pointer> <problem>; <fix>", so the message names the
// document, the field and what was expected.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace millflow::util {

class JsonFields {
 public:
  JsonFields(std::string owner, const nlohmann::json& document,
             std::string fix = "re-run that task with a matching version")
      : owner_(std::move(owner)), fix_(std::move(fix)), document_(document) {}

  const nlohmann::json& at(const std::string& pointer) const;
  double number(const std::string& pointer) const;
  std::optional<double> number_or_null(const std::string& pointer) const;
  std::size_t count(const std::string& pointer) const;  // a non-negative integer
  std::string text(const std::string& pointer) const;
  std::optional<std::string> text_or_null(const std::string& pointer) const;
  std::size_t array_size(const std::string& pointer) const;
  std::vector<double> numbers(const std::string& pointer) const;
  std::vector<std::string> texts(const std::string& pointer) const;
  bool contains(const std::string& pointer) const;
  [[noreturn]] void refuse(const std::string& pointer, const std::string& problem) const;

 private:
  std::string owner_, fix_;
  const nlohmann::json& document_;
};

}  // namespace millflow::util
