#pragma once
// A tiny macro task for the tests: a 0.2 m mill slice with four lifters and ~220 balls of 12 mm,
// soft contacts (t_c = 1 ms, dt = 50 us), so a run of 1.5 revolutions takes a few seconds.
#include <tbb/task_arena.h>
#include <unistd.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <stop_token>
#include <string>
#include <vector>

#include "engine/task.hpp"
#include "tasks/macro.hpp"

namespace millflow::tasks::testing {

inline nlohmann::json tiny_macro_params(double fill = 0.3, double speed_fraction = 0.75) {
  return nlohmann::json::parse(R"({
    "materials": {"steel": {"density": 7800}},
    "interactions": [{"materials": ["steel", "steel"], "restitution": 0.5, "friction": 0.5,
                      "stiffness": {"collision_time": 0.001},
                      "tangential_stiffness_ratio": 0.2857142857, "tangential_damping_ratio": 0.5}],
    "dem": {"steps_per_collision": 20, "neighbor_skin_fraction": 0.3, "seed": 7},
    "mill": {"diameter": 0.2, "length": 0.036, "axial_ends": "periodic", "liner_material": "steel",
             "lifters": {"count": 4, "height": 0.01, "base_width": 0.012, "face_angle_deg": 10}},
    "media": {"material": "steel", "diameter": 0.012},
    "macro": {"fill": 0.3, "speed_fraction": 0.75, "settle_time": 0.15, "warmup_revolutions": 0.5,
              "measure_revolutions": 1.0, "sample_interval": 0.02, "vtk_interval": 0.25,
              "checkpoint_interval_s": 60}
  })")
      .patch(nlohmann::json::array(
          {{{"op", "replace"}, {"path", "/macro/fill"}, {"value", fill}},
           {{"op", "replace"}, {"path", "/macro/speed_fraction"}, {"value", speed_fraction}}}));
}

// Runs the macro task function directly, as the engine would, on `threads` threads.
// `on_progress` sees every progress report (a test may request a stop from it).
struct DirectRun {
  nlohmann::json params;
  std::filesystem::path work_dir;
  std::string key = "tiny-macro";
  int threads = 2;
  std::vector<std::string>* log_lines = nullptr;  // the task's log lines, when given

  engine::TaskOutcome run(std::stop_token stop = {},
                          std::function<void(double, std::string_view)> on_progress = {}) const {
    const std::vector<engine::TaskInput> inputs;
    engine::TaskContext context{.key = key,
                                .params = params,
                                .inputs = inputs,
                                .work_dir = work_dir,
                                .threads = threads,
                                .stop = stop,
                                .progress =
                                    [&](double fraction, std::string_view message) {
                                      if (on_progress) on_progress(fraction, message);
                                    },
                                .log =
                                    [this](std::string_view line) {
                                      if (log_lines) log_lines->emplace_back(line);
                                    }};
    std::filesystem::create_directories(work_dir);
    engine::TaskOutcome outcome;
    tbb::task_arena arena(threads);
    arena.execute([&] { outcome = run_macro(context); });
    return outcome;
  }
};

// A fresh directory under the system temp dir, removed when the object goes away.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name)
      : path_(std::filesystem::temp_directory_path() /
              ("millflow_" + name + "_" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace millflow::tasks::testing
