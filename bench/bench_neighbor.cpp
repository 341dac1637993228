// Neighbour-list build time for a packed bidisperse bed: 10 mm media balls with powder filling the
// voids, size ratio 1, 5, 10, 20, solid fraction 0.5, periodic box. Multi-level cell lists against
// the single uniform grid sized for the media (the baseline the design rules out), at 1 and 2
// threads.
//
// Arguments: size ratio, multilevel (0/1), threads.
#include <benchmark/benchmark.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "dem/neighbor_search.hpp"

namespace {

using millflow::dem::Domain;
using millflow::dem::NeighborSearch;
using millflow::dem::Vec3;

constexpr double kMediaDiameter = 0.010;
constexpr double kMediaFraction = 0.35;                   // media solid fraction
constexpr double kPowderFraction = 0.15;                  // powder solid fraction: 0.5 in all
constexpr double kSphereFactor = std::numbers::pi / 6.0;  // sphere volume / d^3

struct Bed {
  Domain domain;
  std::vector<Vec3> positions;
  std::vector<double> radii;
};

// Occupied sites of a simple cubic lattice of per_axis^3 sites for balls of diameter `diameter`:
// each site is kept with probability `keep` (site_to_ball gets its ball index, or -1) and moved
// by up to 45% of the gap between
// neighbouring balls along every axis, so balls never overlap and many nearly touch.
std::vector<Vec3> lattice(int per_axis, double spacing, double diameter, double keep,
                          std::mt19937_64& rng, std::vector<int>* site_to_ball = nullptr) {
  const double jitter = 0.45 * (spacing - diameter);
  std::uniform_real_distribution<double> shift(-jitter, jitter), unit(0.0, 1.0);
  std::vector<Vec3> balls;
  for (int i = 0; i < per_axis; ++i) {
    for (int j = 0; j < per_axis; ++j) {
      for (int k = 0; k < per_axis; ++k) {
        const Vec3 site =
            spacing * Vec3(i + 0.5, j + 0.5, k + 0.5) + Vec3(shift(rng), shift(rng), shift(rng));
        const bool kept = unit(rng) < keep;
        if (site_to_ball) site_to_ball->push_back(kept ? static_cast<int>(balls.size()) : -1);
        if (kept) balls.push_back(site);
      }
    }
  }
  return balls;
}

Domain periodic_cube(double side) {
  Domain d;
  d.hi = Vec3::Constant(side);
  d.periodic = {true, true, true};
  return d;
}

// Same-size balls at solid fraction 0.5 on a full jittered lattice, per_axis^3 of them.
Bed monodisperse_bed(int per_axis, std::mt19937_64& rng) {
  const double spacing =
      kMediaDiameter * std::cbrt(kSphereFactor / (kMediaFraction + kPowderFraction));
  Bed bed{periodic_cube(per_axis * spacing), {}, {}};
  bed.positions = lattice(per_axis, spacing, kMediaDiameter, 1.0, rng);
  bed.radii.assign(bed.positions.size(), 0.5 * kMediaDiameter);
  return bed;
}

// Media on a coarse lattice of per_axis^3 sites, powder on a fine one, both spaced at 1.05
// diameters and partly occupied for the target solid fractions; powder sites overlapping a media
// ball are left empty.
Bed bidisperse_bed(double ratio, int per_axis, std::mt19937_64& rng) {
  constexpr double kSpacing = 1.05;  // lattice spacing / diameter
  const double full_fraction = kSphereFactor / (kSpacing * kSpacing * kSpacing);
  const double media_spacing = kSpacing * kMediaDiameter;
  const double side = per_axis * media_spacing;
  Bed bed{periodic_cube(side), {}, {}};
  std::vector<int> site_to_media;
  bed.positions = lattice(per_axis, media_spacing, kMediaDiameter, kMediaFraction / full_fraction,
                          rng, &site_to_media);
  bed.radii.assign(bed.positions.size(), 0.5 * kMediaDiameter);

  const double d_powder = kMediaDiameter / ratio;
  // A media ball stays inside its lattice cell, so only the 27 cells around a powder site can
  // hold one that overlaps it.
  const auto clears_media = [&](const Vec3& site) {
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        for (int dk = -1; dk <= 1; ++dk) {
          const auto cell = [&](int axis, int delta) {
            const int c = static_cast<int>(site[axis] / media_spacing) + delta;
            return (c % per_axis + per_axis) % per_axis;
          };
          const int m = site_to_media[static_cast<std::size_t>(
              (cell(0, di) * per_axis + cell(1, dj)) * per_axis + cell(2, dk))];
          if (m >= 0 &&
              bed.domain.separation(bed.positions[static_cast<std::size_t>(m)], site).norm() <
                  0.5 * (kMediaDiameter + d_powder)) {
            return false;
          }
        }
      }
    }
    return true;
  };
  // Fraction of the box where a powder centre clears every media ball.
  const double free_fraction = 1.0 - kMediaFraction * std::pow(1.0 + 1.0 / ratio, 3);
  const double keep = kPowderFraction / free_fraction / full_fraction;
  const int powder_per_axis = static_cast<int>(side / (kSpacing * d_powder));
  for (const Vec3& site : lattice(powder_per_axis, side / powder_per_axis, d_powder, keep, rng)) {
    if (clears_media(site)) {
      bed.positions.push_back(site);
      bed.radii.push_back(0.5 * d_powder);
    }
  }
  return bed;
}

// Media sites per axis chosen for 20k-75k particles, so that the single-grid baseline still runs
// in seconds.
Bed packed_bed(int ratio) {
  std::mt19937_64 rng(2024);
  switch (ratio) {
    case 1:
      return monodisperse_bed(37, rng);
    case 5:
      return bidisperse_bed(5.0, 11, rng);
    case 10:
      return bidisperse_bed(10.0, 6, rng);
    default:
      return bidisperse_bed(static_cast<double>(ratio), 2, rng);
  }
}

void BM_NeighborBuild(benchmark::State& state) {
  const int ratio = static_cast<int>(state.range(0));
  const bool multilevel = state.range(1) != 0;
  const int threads = static_cast<int>(state.range(2));
  const Bed bed = packed_bed(ratio);
  const double skin = 0.1 * kMediaDiameter / ratio;  // a tenth of the powder diameter
  NeighborSearch search({skin, multilevel});
  tbb::task_arena arena(threads);
  for (auto _ : state) {
    arena.execute([&] { search.build(bed.domain, bed.positions, bed.radii); });
    benchmark::DoNotOptimize(search.pairs().data());
  }
  double solid = 0.0;
  for (const double r : bed.radii) solid += 8.0 * kSphereFactor * r * r * r;
  const auto& stats = search.last_build_stats();
  const auto n = static_cast<double>(bed.positions.size());
  state.counters["particles"] = n;
  state.counters["solid_fraction"] = solid / bed.domain.length().prod();
  state.counters["levels"] = static_cast<double>(stats.levels);
  state.counters["pairs"] = static_cast<double>(search.pairs().size());
  state.counters["cells_visited"] = static_cast<double>(stats.cells_visited);
  state.counters["candidates"] = static_cast<double>(stats.candidates_tested);
  // Seconds per particle per build (printed with an SI prefix: "n" is ns per particle).
  state.counters["s_per_particle"] = benchmark::Counter(
      n, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

BENCHMARK(BM_NeighborBuild)
    ->ArgNames({"ratio", "multilevel", "threads"})
    ->ArgsProduct({{1, 5, 10, 20}, {1, 0}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
