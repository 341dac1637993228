#include "dem/mill_setup.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dem/packing.hpp"
#include "util/sphere.hpp"

namespace millflow::dem {

double critical_speed(double mill_diameter, double ball_diameter, double gravity) {
  return std::sqrt(2.0 * gravity / (mill_diameter - ball_diameter));
}

void validate(const MillSetup& setup) {
  validate(setup.shell);
  auto fail = [](const std::string& what) { throw std::invalid_argument("mill: " + what); };
  auto check_diameter = [&](double diameter, const std::string& what) {
    if (!(diameter > 0.0)) fail(fmt::format("{} = {} m must be > 0", what, diameter));
    if (!(diameter < 0.5 * setup.shell.radius)) {
      fail(fmt::format("{} = {} m must be less than a quarter of the mill diameter {} m", what,
                       diameter, 2 * setup.shell.radius));
    }
  };
  if (setup.size_distribution.empty()) check_diameter(setup.ball_diameter, "ball diameter");
  for (std::size_t i = 0; i < setup.size_distribution.size(); ++i) {
    const BallSizeClass& size = setup.size_distribution[i];
    check_diameter(size.diameter, fmt::format("diameter of ball size class {}", i));
    if (!(size.mass_fraction > 0.0 && std::isfinite(size.mass_fraction))) {
      fail(fmt::format("mass fraction of ball size class {} = {} must be a finite number > 0", i,
                       size.mass_fraction));
    }
  }
  if (!(setup.fill > 0.0 && setup.fill <= 0.9))
    fail(fmt::format("fill J = {} is outside (0, 0.9]", setup.fill));
  if (!(setup.packing > 0.0 && setup.packing < 0.75))
    fail(fmt::format("packing = {} is outside (0, 0.75)", setup.packing));
  if (!(setup.speed_fraction >= 0.0))
    fail(fmt::format("speed fraction = {} must be >= 0", setup.speed_fraction));
}

std::vector<BallSizeClass> ball_size_classes(const MillSetup& setup) {
  if (setup.size_distribution.empty())
    return {BallSizeClass{.diameter = setup.ball_diameter, .mass_fraction = 1.0}};
  double total = 0.0;
  for (const BallSizeClass& size : setup.size_distribution) total += size.mass_fraction;
  std::vector<BallSizeClass> classes = setup.size_distribution;
  for (BallSizeClass& size : classes) size.mass_fraction /= total;
  return classes;
}

double mean_ball_diameter(const MillSetup& setup) {
  double mean = 0.0;
  for (const BallSizeClass& size : ball_size_classes(setup))
    mean += size.mass_fraction * size.diameter;
  return mean;
}

double reference_ball_mass(const MillSetup& setup) {
  return util::sphere_mass(setup.media.density, mean_ball_diameter(setup));
}

std::vector<std::size_t> balls_per_class(const MillSetup& setup) {
  const double solid_volume =
      setup.fill * mill_free_cross_section_area(setup.shell) * setup.shell.length * setup.packing;
  std::vector<std::size_t> counts;
  for (const BallSizeClass& size : ball_size_classes(setup)) {
    const double ball_volume = util::sphere_volume_of_diameter(size.diameter);
    counts.push_back(
        static_cast<std::size_t>(std::llround(size.mass_fraction * solid_volume / ball_volume)));
  }
  return counts;
}

namespace {

// The radii of every ball, in the order they are placed (lowest site first): classes shuffled
// together so the bed starts mixed.
std::vector<double> ball_radii(const MillSetup& setup, Rng& rng) {
  const auto classes = ball_size_classes(setup);
  const auto counts = balls_per_class(setup);
  std::vector<double> radii;
  for (std::size_t c = 0; c < classes.size(); ++c)
    radii.insert(radii.end(), counts[c], 0.5 * classes[c].diameter);
  if (classes.size() > 1) {
    for (std::size_t i = radii.size(); i > 1; --i) {  // Fisher-Yates with the portable generator
      const auto j = static_cast<std::size_t>(rng.uniform() * static_cast<double>(i));
      std::swap(radii[i - 1], radii[std::min(j, i - 1)]);
    }
  }
  return radii;
}

Material liner_material(const MillSetup& setup) {
  Material liner = setup.liner;
  if (liner.name == setup.media.name) liner.name += "_liner";
  return liner;
}

}  // namespace

System build_mill(const MillSetup& setup) {
  validate(setup);
  MaterialTable table;
  const MaterialId media = table.add(setup.media);
  const MaterialId liner = table.add(liner_material(setup));
  table.set_interaction(media, media, setup.ball_ball);
  table.set_interaction(media, liner, setup.ball_liner);

  const double radius = setup.shell.radius;
  Domain domain;
  domain.lo = Vec3(-radius, -radius, 0.0);
  domain.hi = Vec3(radius, radius, setup.shell.length);
  domain.periodic = {false, false, !setup.shell.end_walls};
  System system(std::move(table), domain, Vec3(0.0, -setup.gravity, 0.0));
  system.add_wall(
      Wall{.name = "shell", .material = liner, .shape = MillWall{.shell = setup.shell}});

  double largest = 0.0;
  for (const BallSizeClass& size : ball_size_classes(setup))
    largest = std::max(largest, size.diameter);
  Rng rng(setup.seed);
  const auto sites =
      mill_lattice_sites(setup.shell, 0.0, 0.5 * largest, 1.1 * largest, Vec3(0, -1, 0), 0.8, rng);
  const std::vector<double> radii = ball_radii(setup, rng);
  if (sites.size() < radii.size()) {
    throw std::invalid_argument(fmt::format(
        "mill: fill J = {} needs {} balls but a close-packed lattice holds only {}; lower the fill",
        setup.fill, radii.size(), sites.size()));
  }
  for (std::size_t b = 0; b < radii.size(); ++b) {
    system.add_particle({.position = sites[b], .radius = radii[b], .material = media});
  }
  system.rng() = rng;
  const double mean_diameter = mean_ball_diameter(setup);
  const double omega_c = critical_speed(2 * radius, mean_diameter, setup.gravity);
  spdlog::info(
      "mill: D = {} m, slice L = {} m, {} lifters; {} balls (mass-weighted mean diameter {} m) for "
      "J = {} "
      "(bed packing {}); critical speed {:.4g} rad/s ({:.4g} rpm)",
      2 * radius, setup.shell.length, setup.shell.lifter_count, radii.size(), mean_diameter,
      setup.fill, setup.packing, omega_c, omega_c * 60.0 / (2 * std::numbers::pi));
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
