#include "cli/app.hpp"

#include <CLI/CLI.hpp>

#include "cli/cell.hpp"
#include "cli/commands.hpp"
#include "cli/demo.hpp"
#include "engine/testing_tasks.hpp"
#include "tasks/millflow.hpp"

namespace millflow::cli {

int run(int argc, char** argv) {
  CLI::App app{"millflow: multiscale DEM campaigns of grinding mills"};
  app.require_subcommand(1);
  engine::Registry registry;
  engine::add_testing(registry);
  tasks::register_millflow(registry);
  std::optional<int> engine_exit_code;
  add_engine_commands(app, registry, engine_exit_code);
  add_demo_command(app);
  add_cell_command(app, engine_exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  return engine_exit_code.value_or(exit_code());
}

}  // namespace millflow::cli
