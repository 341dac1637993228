#include "cli/app.hpp"

#include <CLI/CLI.hpp>

#include "cli/demo.hpp"

namespace millflow::cli {

int run(int argc, char** argv) {
  CLI::App app{"millflow: multiscale DEM campaigns of grinding mills"};
  app.require_subcommand(1);
  add_demo_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  return exit_code();
}

}  // namespace millflow::cli
