#pragma once
// Provenance of the running build and machine.
#include <string>

namespace millflow::engine {

const char* code_version();  // git describe of the build
std::string host_name();

}  // namespace millflow::engine
