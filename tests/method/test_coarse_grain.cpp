// Coarse-graining: conservation, analytic flows (rigid rotation, simple shear), the contact stress
// of two pressed particles against the virial, collision rates, determinism, and real mill frames.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstring>
#include <numbers>

#include "dem/rng.hpp"
#include "method/coarse_grain.hpp"
#include "tests/tasks/mill_frames.hpp"

namespace millflow::tasks {
namespace {

using Eigen::Vector3d;

dem::Float3 f3(const Vector3d& v) {
  return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

void add_particle(dem::FlowFrame& frame, const Vector3d& x, const Vector3d& v, double radius) {
  frame.position.push_back(f3(x));
  frame.velocity.push_back(f3(v));
  frame.angular_velocity.push_back({0.0f, 0.0f, 0.0f});
  frame.radius.push_back(static_cast<float>(radius));
  frame.material.push_back(0);
}

method::CoarseGrainSettings settings(int cells, double width) {
  method::CoarseGrainSettings s;
  s.grid = method::CrossSectionGrid{.nx = cells, .ny = cells, .half_width = 0.1};
  s.slice_length = 0.04;
  s.kernel_width = width;
  s.media_density = 7800.0;
  s.event_window = 2.0;
  s.categories = {"steel-steel", "steel-wall:shell"};
  return s;
}

method::CoarseFields grain(const method::CoarseGrainSettings& s,
                           const std::vector<dem::FlowFrame>& frames) {
  return method::coarse_grain(s, 1, [&](std::size_t) { return frames; });
}

// Particles on a square lattice of spacing `a` where `inside(x, y)`, moving with `velocity(x)`.
template <class Inside, class Velocity>
dem::FlowFrame lattice(double a, double radius, Inside inside, Velocity velocity) {
  dem::FlowFrame frame;
  for (double y = -0.1 + a / 2; y < 0.1; y += a) {
    for (double x = -0.1 + a / 2; x < 0.1; x += a) {
      if (inside(x, y)) add_particle(frame, {x, y, 0.0}, velocity(Vector3d(x, y, 0.0)), radius);
    }
  }
  return frame;
}

TEST(CoarseGrain, SolidFractionIntegratesToTheParticleVolumeEvenNextToTheShell) {
  dem::Rng rng(7);
  std::vector<dem::FlowFrame> frames(2);
  double volume = 0.0;
  for (auto& frame : frames) {
    for (int p = 0; p < 300; ++p) {
      const double r = 0.095 * std::sqrt(rng.uniform()),
                   angle = 2 * std::numbers::pi * rng.uniform();
      add_particle(frame, {r * std::cos(angle), r * std::sin(angle), 0.01}, Vector3d::Zero(),
                   0.004);
      volume += 4.0 / 3.0 * std::numbers::pi * std::pow(double{0.004f}, 3) / 2.0;
    }
  }
  const method::CoarseFields f = grain(settings(30, 0.008), frames);
  EXPECT_NEAR(f.media_volume, volume, 1e-12 * volume);
  EXPECT_NEAR(f.solid_volume(), volume, 1e-9 * volume);
  for (std::size_t c = 0; c < f.grid.size(); ++c) {
    if (!f.grid.inside_mill(c)) {
      EXPECT_EQ(f.solid_fraction[c], 0.0) << "cell " << c << " lies outside the shell";
    }
  }
}

TEST(CoarseGrain, RigidRotationHasTheShellVelocityAndNoShear) {
  const double omega = 3.0, edge = 0.09, w = 0.005;
  const auto rotation = [&](const Vector3d& x) {
    return Vector3d(-omega * x.y(), omega * x.x(), 0.0);
  };
  const auto frame = lattice(
      0.0025, 0.001, [&](double x, double y) { return std::hypot(x, y) < edge; }, rotation);
  const method::CoarseFields f = grain(settings(40, w), {frame, frame});
  int checked = 0;
  for (std::size_t c = 0; c < f.grid.size(); ++c) {
    const Vector3d centre(f.grid.x_of(c), f.grid.y_of(c), 0.0);
    if (centre.norm() > edge - 7 * w) continue;  // the kernel-weighted mean velocity is exact here
    ++checked;
    EXPECT_LT((f.velocity[c] - rotation(centre)).norm(), 1e-4 * omega * edge) << "cell " << c;
    EXPECT_LT(f.shear_rate[c], 1e-4 * omega) << "cell " << c;
    // Fluctuations about the mean field at each ball, not at the cell: no spurious temperature.
    EXPECT_LT(f.granular_temperature[c], 1e-6 * std::pow(omega * edge, 2)) << "cell " << c;
  }
  EXPECT_GT(checked, 300);
}

TEST(CoarseGrain, SimpleShearGivesItsShearRateAndNoStress) {
  const double gdot = 12.0, half = 0.06, w = 0.005;
  const auto shear = [&](const Vector3d& x) { return Vector3d(gdot * x.y(), 0.0, 0.0); };
  const auto frame = lattice(
      0.0025, 0.001, [&](double x, double y) { return std::abs(x) < half && std::abs(y) < half; },
      shear);
  const method::CoarseFields f = grain(settings(40, w), {frame});
  int checked = 0;
  for (std::size_t c = 0; c < f.grid.size(); ++c) {
    if (std::abs(f.grid.x_of(c)) > half - 7 * w || std::abs(f.grid.y_of(c)) > half - 7 * w)
      continue;
    ++checked;
    EXPECT_NEAR(f.shear_rate[c], gdot, 1e-4 * gdot) << "cell " << c;
    EXPECT_NEAR(f.strain_rate[c](0, 1), gdot / 2, 1e-4 * gdot) << "cell " << c;
    EXPECT_LT(f.pressure[c], 1e-6 * f.density[c] * std::pow(gdot * half, 2)) << "cell " << c;
  }
  EXPECT_GT(checked, 80);
}

TEST(CoarseGrain, ShearPlaneTractionOfASimpleShearIsOnTheLayers) {
  // u = gdot y: the layers are normal to y whatever the sign of gdot, so the plane's normal
  // stress is -sigma_yy (not -sigma_xx) and its shear stress |sigma_xy|.
  for (const double gdot : {5.0, -5.0}) {
    Eigen::Matrix3d gradient = Eigen::Matrix3d::Zero();
    gradient(0, 1) = gdot;
    const Eigen::Matrix3d strain_rate = 0.5 * (gradient + gradient.transpose());
    Eigen::Matrix3d stress = Eigen::Matrix3d::Zero();
    stress(0, 0) = -300.0;
    stress(1, 1) = -200.0;
    stress(2, 2) = -250.0;
    stress(0, 1) = stress(1, 0) = -gdot * 16.0;
    const method::ShearPlaneTraction traction =
        method::shear_plane_traction(gradient, strain_rate, stress);
    EXPECT_NEAR(traction.normal, 200.0, 1e-9) << gdot;
    EXPECT_NEAR(traction.shear, 80.0, 1e-9) << gdot;
  }
}

TEST(CoarseGrain, TwoPressedParticlesGiveTheVirialPressure) {
  const double d = 0.01, force = 100.0, w = 0.015;
  dem::FlowFrame frame;
  add_particle(frame, {-d / 2, 0.0, 0.0}, Vector3d::Zero(), d / 2);
  add_particle(frame, {d / 2, 0.0, 0.0}, Vector3d::Zero(), d / 2);
  frame.contact_a = {0};
  frame.contact_b = {1};
  frame.contact_with_wall = {0};
  frame.contact_point = {{0.0f, 0.0f, 0.0f}};
  frame.contact_force = {{static_cast<float>(-force), 0.0f, 0.0f}};  // b pushes a towards -x
  frame.contact_branch = {{static_cast<float>(d), 0.0f, 0.0f}};
  const method::CoarseGrainSettings s = settings(41, w);  // a cell centred on the contact
  const method::CoarseFields f = grain(s, {frame});

  // The integral of the pressure is the virial sum f.b / 3; compressive is positive.
  const double virial = force * d / 3.0;
  EXPECT_NEAR(f.integral(f.pressure), virial, 1e-6 * virial);
  // At the contact: the virial times the line kernel's mean along the branch.
  const double peak = 1.0 / (2 * std::numbers::pi * w * w * (1 - std::exp(-4.5)));
  const double line_mean =
      std::sqrt(2 * std::numbers::pi) * w / d * std::erf(d / (2 * std::sqrt(2.0) * w));
  const std::size_t centre = s.grid.index(20, 20);
  EXPECT_NEAR(f.pressure[centre], virial / s.slice_length * peak * line_mean,
              0.01 * f.pressure[centre]);
  EXPECT_LT(f.contact_stress[centre](0, 0), 0.0);
  EXPECT_NEAR(f.contact_stress[centre](1, 1), 0.0, 1e-12);
}

TEST(CoarseGrain, CollisionRatesAndPowerPerCategoryIntegrateToTheEvents) {
  dem::FlowFrame frame;
  add_particle(frame, {0.0, -0.05, 0.0}, Vector3d::Zero(), 0.005);
  frame.event_time = {0.1, 0.2, 0.3};
  frame.event_point = {{0.0f, -0.05f, 0.0f}, {0.01f, -0.09f, 0.0f}, {-0.02f, -0.04f, 0.0f}};
  frame.event_impact_energy = {1.0f, 1.0f, 1.0f};
  frame.event_dissipated = {0.5f, 0.25f, 0.125f};
  frame.event_category = {0, 1, 0};
  frame.event_with_wall = {0, 1, 0};
  const method::CoarseFields f = grain(settings(20, 0.01), {frame});  // the events span 2 s
  EXPECT_NEAR(f.integral(f.collision_frequency), 3 / 2.0, 1e-12);
  EXPECT_NEAR(f.integral(f.collision_frequency_by_category[1]), 1 / 2.0, 1e-12);
  EXPECT_NEAR(f.integral(f.dissipation), 0.875 / 2.0, 1e-12);
  EXPECT_NEAR(f.integral(f.dissipation_by_category[0]), 0.625 / 2.0, 1e-12);
}

TEST(CoarseGrain, RefusesAKernelThatCanMissEveryCellAndParticlesOutsideTheMill) {
  dem::FlowFrame frame;
  add_particle(frame, {0.0, 0.0, 0.0}, Vector3d::Zero(), 0.005);
  EXPECT_THROW(grain(settings(20, 0.004), {frame}), std::invalid_argument);  // cells of 10 mm
  add_particle(frame, {0.2, 0.0, 0.0}, Vector3d::Zero(), 0.005);
  EXPECT_THROW(grain(settings(20, 0.01), {frame}), std::invalid_argument);
}

TEST(CoarseGrain, SameBitsAtOneAndTwoThreads) {
  std::vector<std::vector<dem::FlowFrame>> segments(6);
  dem::Rng rng(3);
  for (auto& segment : segments) {
    for (int f = 0; f < 2; ++f) {
      dem::FlowFrame frame;
      for (int p = 0; p < 200; ++p) {
        const double r = 0.09 * std::sqrt(rng.uniform()), a = -std::numbers::pi * rng.uniform();
        add_particle(frame, {r * std::cos(a), r * std::sin(a), 0.0},
                     {rng.uniform(), rng.uniform(), rng.uniform()}, 0.004);
      }
      segment.push_back(frame);
    }
  }
  auto run = [&](int threads) {
    method::CoarseFields f;
    tbb::task_arena(threads).execute([&] {
      f = method::coarse_grain(settings(24, 0.01), segments.size(),
                               [&](std::size_t k) { return segments[k]; });
    });
    return method::cell_arrays(f);
  };
  const auto one = run(1), two = run(2);
  ASSERT_EQ(one.size(), two.size());
  for (std::size_t a = 0; a < one.size(); ++a) {
    EXPECT_EQ(0, std::memcmp(one[a].values.data(), two[a].values.data(),
                             one[a].values.size() * sizeof(double)))
        << one[a].name;
  }
}

TEST(CoarseGrain, RealMillFramesConserveTheMediaVolumeWithinOnePercent) {
  const auto& sample = testing::small_mill_sample();
  method::CoarseGrainSettings s = settings(20, 1.5 * 0.01);
  s.categories = sample.macro_result.at("categories").get<std::vector<std::string>>();
  const method::CoarseFields f = method::coarse_grain(
      s, sample.segments.size(),
      [&](std::size_t k) { return dem::read_flow_segment(sample.segments[k]); });
  const double balls = sample.macro_result.at("n_balls").get<double>() * 4.0 / 3.0 *
                       std::numbers::pi * std::pow(0.005, 3);
  EXPECT_NEAR(f.media_volume, balls, 1e-5 * balls);
  EXPECT_NEAR(f.solid_volume(), balls, 0.01 * balls);
  EXPECT_EQ(f.frame_count, 24u);
}

}  // namespace
}  // namespace millflow::tasks
