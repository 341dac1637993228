// The engine's code version and host, recorded in every task's provenance.
#include "engine/version.hpp"

#include "millflow_build_info.hpp"

#include <unistd.h>

#include <array>

namespace millflow::engine {

const char* code_version() {
  return MILLFLOW_GIT_VERSION;
}

std::string host_name() {
  std::array<char, 256> name{};
  if (::gethostname(name.data(), name.size() - 1) != 0) return "unknown";
  return name.data();
}

}  // namespace millflow::engine
