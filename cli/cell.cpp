#include "cli/cell.hpp"

#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "engine/interrupt.hpp"
#include "tasks/cell_spec.hpp"

namespace millflow::cli {

namespace fs = std::filesystem;

void add_cell_command(CLI::App& app, std::optional<int>& exit_code) {
  auto* command = app.add_subcommand(
      "cell",
      "Run one shear cell from a spec file and print its result JSON (docs/shear_cells.md)");
  auto spec_file = std::make_shared<std::string>();
  auto out_dir = std::make_shared<std::string>("cell");
  command->add_option("SPEC", *spec_file, "Cell spec JSON file")->required();
  command->add_option("--out", *out_dir, "Directory for the cell's files (default ./cell)");
  command->callback([&exit_code, spec_file, out_dir] {
    exit_code = guarded([&] {
      // stdout carries the result JSON alone.
      spdlog::set_default_logger(spdlog::stderr_logger_mt("cell"));
      const auto spec = tasks::load_cell_spec(*spec_file);
      const fs::path dir = output_directory(*out_dir);
      // Ctrl-C or SIGTERM: the cell saves its checkpoint and returns (a second signal exits at
      // once).
      engine::install_interrupt_handlers();
      const engine::StopWatcher watcher(engine::interrupt_requested);
      const auto result = tasks::run_cell_spec(
          spec, dir, [](std::string_view line) { std::cerr << line << '\n'; }, watcher.token());
      if (!result) {
        std::cerr << "millflow: interrupted; the cell's checkpoint is in " << dir.string()
                  << ": the same command continues it\n";
        return 130;
      }
      std::cout << result->dump(2) << '\n';
      return 0;
    });
  });
}

}  // namespace millflow::cli
