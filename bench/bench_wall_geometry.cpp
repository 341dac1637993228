// Cost of the analytic mill wall per particle and step: sphere_mill_contacts for spheres spread
// over the mill's cross-section (most far from the wall) and for spheres in the ring next to the
// shell, where the lifter tests run.
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "dem/wall_geometry.hpp"

namespace {

using millflow::dem::MillShell;
using millflow::dem::SurfaceContact;
using millflow::dem::Vec3;

const MillShell kMill{0.5, 0.5, 20, {0.04, 0.06, 15.0}, true};
constexpr double kBallRadius = 0.02;

// Centres uniform in the annulus rho in [rho_min, R - r] (by area) and z in [r, L - r].
std::vector<Vec3> centres_in_ring(double rho_min, std::size_t count) {
  std::mt19937_64 rng(12345);
  const double rho_max = kMill.radius - kBallRadius;
  std::uniform_real_distribution<double> area(rho_min * rho_min, rho_max * rho_max);
  std::uniform_real_distribution<double> angle(0.0, 2.0 * std::numbers::pi);
  std::uniform_real_distribution<double> axial(kBallRadius, kMill.length - kBallRadius);
  std::vector<Vec3> centres(count);
  for (Vec3& c : centres) {
    const double rho = std::sqrt(area(rng)), psi = angle(rng);
    c = Vec3(rho * std::cos(psi), rho * std::sin(psi), axial(rng));
  }
  return centres;
}

void run(benchmark::State& state, const std::vector<Vec3>& centres) {
  std::vector<SurfaceContact> contacts;
  double theta = 0.0;
  for (auto _ : state) {
    contacts.clear();
    // As in a time step: the mill's pose once, then every sphere.
    const millflow::dem::MillPose pose = millflow::dem::mill_pose(kMill, theta);
    for (const Vec3& c : centres) {
      millflow::dem::sphere_mill_contacts(kMill, pose, c, kBallRadius, contacts);
    }
    benchmark::DoNotOptimize(contacts.data());
    theta += 1e-4;
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(centres.size()));
  state.counters["contacts_per_sphere"] =
      static_cast<double>(contacts.size()) / static_cast<double>(centres.size());
}

void BM_WholeCrossSection(benchmark::State& state) {
  run(state, centres_in_ring(0.0, 10000));
}
void BM_NearShellRing(benchmark::State& state) {
  run(state, centres_in_ring(kMill.radius - kMill.lifter.height - kBallRadius, 10000));
}

BENCHMARK(BM_WholeCrossSection);
BENCHMARK(BM_NearShellRing);

}  // namespace

BENCHMARK_MAIN();
