#include "cli/app.hpp"

#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>

#include "cli/cell.hpp"
#include "cli/commands.hpp"
#include "cli/demo.hpp"
#include "cli/estimate.hpp"
#include "millflow_build_info.hpp"
#include "tasks/millflow.hpp"

namespace millflow::cli {

int run(int argc, char** argv, const std::function<void(engine::Registry&)>& extend) {
  CLI::App app{"millflow: multiscale DEM campaigns of grinding mills"};
  app.require_subcommand(1);
  // Log lines go to stderr; stdout carries only what a command answers (tables, paths, CSV).
  spdlog::set_default_logger(spdlog::stderr_color_mt("millflow"));
  app.set_version_flag("--version",
                       fmt::format("millflow {} (git {}, instruction set {})", MILLFLOW_VERSION,
                                   MILLFLOW_GIT_VERSION, MILLFLOW_INSTRUCTION_SET));
  engine::Registry registry;
  tasks::register_millflow(registry);
  if (extend) extend(registry);
  std::optional<int> engine_exit_code;
  add_engine_commands(app, registry, engine_exit_code);
  add_demo_command(app);
  add_cell_command(app, engine_exit_code);
  add_estimate_command(app, registry, engine_exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  return engine_exit_code.value_or(exit_code());
}

}  // namespace millflow::cli
