#pragma once
// Errors in user input (campaign files, command-line values). Every error names the JSON path,
// what is wrong, and how to fix it; all errors of one input are collected and reported together.
#include <stdexcept>
#include <string>
#include <vector>

namespace millflow::engine {

struct ValidationError {
  // JSON pointer-like path, e.g. "/mill/lifters/count" ("" for the document), or the command-line
  // option or argument at fault ("--db", "SQL").
  std::string path;
  std::string problem;  // what is wrong, with the offending value
  std::string fix;      // how to fix it (may be empty)

  // "<path>: <problem>" plus "; <fix>" when a fix is given, control characters written as
  // \u0000 ... \u001f and \u007f. Tests assert this exact text.
  std::string message() const;
};

class InvalidInput : public std::runtime_error {
 public:
  explicit InvalidInput(std::vector<ValidationError> errors);
  const std::vector<ValidationError>& errors() const { return errors_; }

 private:
  std::vector<ValidationError> errors_;
};

}  // namespace millflow::engine
