#include "cli/demo.hpp"

#include <numbers>

#include <fmt/format.h>
#include <tbb/task_arena.h>

#include "cli/number_checks.hpp"
#include "dem/mill_setup.hpp"
#include "util/sphere.hpp"

namespace millflow::cli {
namespace {

int g_exit_code = 0;

struct DemoOptions {
  double fill = 0.3;
  double speed_fraction = 0.75;
  int threads = 0;
  double revolutions = 2.0;
};

// A 1 m mill slice (4 ball diameters long, periodic ends) with 40 mm steel balls and four lifters.
dem::MillSetup demo_mill(const DemoOptions& options) {
  dem::MillSetup setup;
  setup.shell = dem::MillShell{
      .radius = 0.5,
      .length = 0.16,
      .lifter_count = 4,
      .lifter = dem::LifterProfile{.height = 0.05, .base_width = 0.08, .face_angle_deg = 15.0},
      .end_walls = false};
  setup.ball_diameter = 0.04;
  const double ball_mass = util::sphere_mass(7800.0, 0.04);
  const double zeta = dem::damping_ratio_for_restitution(0.3);
  setup.ball_ball = {
      .restitution = 0.3,
      .friction = 0.75,
      .normal_stiffness = dem::stiffness_for_collision_duration(5e-4, ball_mass / 2, zeta)};
  setup.ball_liner = {
      .restitution = 0.3,
      .friction = 0.75,
      .normal_stiffness = dem::stiffness_for_collision_duration(5e-4, ball_mass, zeta)};
  setup.fill = options.fill;
  setup.speed_fraction = options.speed_fraction;
  return setup;
}

void run_demo(const DemoOptions& options) {
  const dem::MillSetup setup = demo_mill(options);
  dem::System system = dem::build_mill(setup);
  system.set_time_step_from_collisions(20);
  const double omega =
      options.speed_fraction * dem::critical_speed(2 * setup.shell.radius, setup.ball_diameter);
  const double revolution = 2 * std::numbers::pi / omega;
  double ball_mass = 0.0;
  for (double m : system.masses()) ball_mass += m;
  fmt::print(
      "millflow demo: D = 1 m slice of {} m, {} balls of 40 mm ({:.1f} kg), J = {}, {:.0f}% of "
      "critical "
      "({:.2f} rad/s), dt = {:.3g} s\n",
      setup.shell.length, system.size(), ball_mass, setup.fill, 100 * options.speed_fraction, omega,
      system.time_step());
  dem::settle_charge(system, 0.5, 1e-5);
  dem::set_mill_speed(system, omega);
  system.step(static_cast<std::size_t>(0.5 * revolution / system.time_step()));  // spin-up

  // Power draw = -torque on the shell x omega; energy-based mean over whole revolutions.
  for (int rev = 0; rev < static_cast<int>(options.revolutions); ++rev) {
    const double work_start = system.wall_load(0).work;
    const double start = system.time();
    system.step(static_cast<std::size_t>(revolution / system.time_step()));
    const double power_w = (system.wall_load(0).work - work_start) / (system.time() - start);
    fmt::print(
        "  revolution {}: power draw {:.3f} kW = {:.2f} kW/m of mill length = {:.2f} kW/t of "
        "balls\n",
        rev + 1, power_w / 1e3, power_w / 1e3 / setup.shell.length, power_w / ball_mass);
  }
}

}  // namespace

void add_demo_command(CLI::App& app) {
  static DemoOptions options;
  auto* demo = app.add_subcommand(
      "demo", "Run a built-in DEM mill slice (1 m, 40 mm balls) and print its power draw");
  demo->add_option("--fill", options.fill, "Mill filling J (fraction of mill volume)")
      ->check(finite_between(0.05, 0.5));
  demo->add_option("--speed", options.speed_fraction, "Speed as a fraction of critical speed")
      ->check(finite_between(0.1, 1.5));
  demo->add_option("--revolutions", options.revolutions, "Revolutions to measure")
      ->check(finite_between(1.0, 20.0));
  demo->add_option("--threads", options.threads, "Worker threads (0: all cores)")
      ->check(CLI::Range(0, 256));
  demo->callback([] {
    tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
    try {
      arena.execute([] { run_demo(options); });
      g_exit_code = 0;
    } catch (const std::exception& e) {  // a failed run, named, not an abort
      fmt::print(stderr, "millflow demo: {}\n", e.what());
      g_exit_code = 1;
    }
  });
}

int exit_code() {
  return g_exit_code;
}

}  // namespace millflow::cli
