#include "dem/mill_setup.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dem/packing.hpp"

namespace millflow::dem {

double critical_speed(double mill_diameter, double ball_diameter, double gravity) {
  return std::sqrt(2.0 * gravity / (mill_diameter - ball_diameter));
}

void validate(const MillSetup& setup) {
  validate(setup.shell);
  auto fail = [](const std::string& what) { throw std::invalid_argument("mill: " + what); };
  if (!(setup.ball_diameter > 0.0)) fail(fmt::format("ball diameter = {} m must be > 0", setup.ball_diameter));
  if (!(setup.ball_diameter < 0.5 * setup.shell.radius)) {
    fail(fmt::format("ball diameter = {} m must be less than a quarter of the mill diameter {} m",
                     setup.ball_diameter, 2 * setup.shell.radius));
  }
  if (!(setup.fill > 0.0 && setup.fill <= 0.9)) fail(fmt::format("fill J = {} is outside (0, 0.9]", setup.fill));
  if (!(setup.packing > 0.0 && setup.packing < 0.75)) fail(fmt::format("packing = {} is outside (0, 0.75)", setup.packing));
  if (!(setup.speed_fraction >= 0.0)) fail(fmt::format("speed fraction = {} must be >= 0", setup.speed_fraction));
}

System build_mill(const MillSetup& setup) {
  validate(setup);
  MaterialTable table;
  const MaterialId media = table.add(setup.media);
  const MaterialId liner = table.add(setup.liner);
  table.set_interaction(media, media, setup.ball_ball);
  table.set_interaction(media, liner, setup.ball_liner);

  const double radius = setup.shell.radius;
  Domain domain;
  domain.lo = Vec3(-radius, -radius, 0.0);
  domain.hi = Vec3(radius, radius, setup.shell.length);
  domain.periodic = {false, false, !setup.shell.end_walls};
  System system(std::move(table), domain, Vec3(0.0, -setup.gravity, 0.0));
  system.add_wall(Wall{.name = "shell", .material = liner, .shape = MillWall{.shell = setup.shell}});

  const double ball_radius = 0.5 * setup.ball_diameter;
  const std::size_t wanted = balls_for_fill(setup.shell, setup.fill, setup.ball_diameter, setup.packing);
  Rng rng(setup.seed);
  const auto sites = mill_lattice_sites(setup.shell, 0.0, ball_radius, 1.1 * setup.ball_diameter, Vec3(0, -1, 0), 0.8, rng);
  if (sites.size() < wanted) {
    throw std::invalid_argument(fmt::format(
        "mill: fill J = {} needs {} balls but a loose lattice holds only {}; lower the fill", setup.fill, wanted, sites.size()));
  }
  for (std::size_t b = 0; b < wanted; ++b) {
    system.add_particle({.position = sites[b], .radius = ball_radius, .material = media});
  }
  system.rng() = rng;
  spdlog::info("mill: D = {} m, slice L = {} m, {} lifters; {} balls of {} m for J = {} (bed packing {}); "
               "critical speed {:.4g} rad/s ({:.4g} rpm)",
               2 * radius, setup.shell.length, setup.shell.lifter_count, wanted, setup.ball_diameter, setup.fill,
               setup.packing, critical_speed(2 * radius, setup.ball_diameter, setup.gravity),
               critical_speed(2 * radius, setup.ball_diameter, setup.gravity) * 60.0 / (2 * std::numbers::pi));
  return system;
}

double settle_charge(System& system, double max_time, double kinetic_per_ball) {
  const double start = system.time();
  const std::size_t check_every = 200;
  while (system.time() - start < max_time) {
    system.step(check_every);
    if (system.energy().kinetic < kinetic_per_ball * static_cast<double>(system.size())) break;
  }
  return system.time() - start;
}

void set_mill_speed(System& system, double angular_velocity) {
  std::get<MillWall>(system.wall(0).shape).angular_velocity = angular_velocity;
}

}  // namespace millflow::dem
