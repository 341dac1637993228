#include "cli/cell.hpp"

#include <tbb/task_arena.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "engine/interrupt.hpp"
#include "tasks/cell_spec.hpp"

namespace millflow::cli {

namespace fs = std::filesystem;

namespace {

// One cell's status line (elapsed, ETA, percent done) and a line whenever it starts a new phase.
// The ETA is the engine's (engine/progress.hpp): the cost model's CPU-seconds to the caps, at
// the pace measured so far, the part done counting as finished work.
class CellProgress {
 public:
  CellProgress(engine::ProgressView& view, double estimate_s, int threads)
      : view_(view), estimate_s_(estimate_s), threads_(threads) {}

  void update(double fraction, std::string_view phase) {
    if (phase != phase_) {
      phase_ = phase;
      view_.message("shear cell: " + phase_);
    }
    const double elapsed = seconds_since_start();
    if (elapsed < next_refresh_s_) return;
    next_refresh_s_ = elapsed + kRefreshS;
    engine::ProgressSnapshot snapshot;
    snapshot.done_total_by_kind["shear_cell"] = {0, 1};
    snapshot.running = {
        {.key = "cell", .kind = "shear_cell", .fraction = fraction, .message = phase_}};
    snapshot.estimated_left_s = estimate_s_ * (1.0 - fraction);
    snapshot.estimated_tasks_left = 1;
    snapshot.finished_estimate_s = estimate_s_ * fraction;
    snapshot.finished_measured_s = elapsed;
    snapshot.elapsed_s = elapsed;
    snapshot.threads_per_task = threads_;
    snapshot.remaining = 1;
    view_.refresh(snapshot);
  }

 private:
  static constexpr double kRefreshS = 0.25;
  double seconds_since_start() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

  engine::ProgressView& view_;
  double estimate_s_;
  int threads_;
  std::string phase_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  double next_refresh_s_ = 0.0;
};

}  // namespace

void add_cell_command(CLI::App& app, std::optional<int>& exit_code) {
  auto* command = app.add_subcommand(
      "cell",
      "Run one shear cell from a spec file and print its result JSON (docs/shear_cells.md)");
  auto spec_file = std::make_shared<std::string>();
  auto out_dir = std::make_shared<std::string>("cell");
  auto threads = std::make_shared<int>(0);
  command->add_option("SPEC", *spec_file, "Cell spec JSON file")->required();
  command->add_option("--out", *out_dir, "Directory for the cell's files (default ./cell)");
  command->add_option("--threads", *threads, "Threads of the cell (default 0: all cores)")
      ->check(CLI::Range(0, 256));
  command->callback([&exit_code, spec_file, out_dir, threads] {
    exit_code = guarded([&] {
      const auto spec = tasks::load_cell_spec(*spec_file);
      const fs::path dir = output_directory(*out_dir);
      // stdout carries the result JSON alone; the log and the status line go to stderr.
      engine::LiveProgress live(stderr);
      engine::PlainProgress plain(stderr);
      engine::ProgressView& view = terminal_or_plain(live, plain);
      const LogThrough logging(view);
      tbb::task_arena arena(*threads > 0 ? *threads : tbb::task_arena::automatic);
      CellProgress progress(view, tasks::cell_spec_cost(spec).core_seconds_at_caps,
                            arena.max_concurrency());
      // Ctrl-C, SIGTERM or SIGHUP: the cell saves its checkpoint and returns (another signal half a
      // second or more later exits at once, engine/interrupt.hpp).
      engine::install_interrupt_handlers();
      const engine::StopWatcher watcher(engine::interrupt_requested);
      const tasks::CellRunHooks hooks{
          .log = [&view](std::string_view line) { view.message(std::string(line)); },
          .progress = [&progress](double fraction,
                                  std::string_view phase) { progress.update(fraction, phase); },
          .stop = watcher.token()};
      std::optional<nlohmann::json> result;
      arena.execute([&] { result = tasks::run_cell_spec(spec, dir, hooks); });
      view.finish();
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
