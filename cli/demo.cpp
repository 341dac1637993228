#include "cli/demo.hpp"

#include <cstdio>

namespace millflow::cli {
namespace {
int g_exit_code = 0;
}

void add_demo_command(CLI::App& app) {
  auto* demo = app.add_subcommand("demo", "Run a built-in DEM mill slice and print its power draw");
  demo->callback([] {
    std::puts("millflow demo: the DEM library is not built yet");
    g_exit_code = 1;
  });
}

int exit_code() { return g_exit_code; }

}  // namespace millflow::cli
