// Shear cells: the mu(I) table of a media-only cell, and the cost of powder cells.
//
// BM_MuOfI/<1000 I>: a 5 x 6 x 5 rough-wall cell of 10 mm steel balls under 1 kPa, contact
// friction 0.5, restitution 0.5, soft contacts (k_n = 100 p d); warm-up 3 strains with the
// wall-speed controller, 3 strains measured. Counters: measured I, mu, the Jop-Forterre-Pouliquen
// mu(I) of glass beads for comparison, media solid fraction, bulk / nominal shear rate.
//
// BM_PowderCellCost/<ratio %>/<load %>/<size-scaled stiffness 0|1>: the default 6 x 8 x 6 cell
// (~300 media) with powder; dt and particle-timesteps per second over 100 steps from the loose
// placement (compaction of a powder cell alone takes minutes here), and the projected cost of
// one strain at I = 0.1. Powder stiffness: 1 = k_n ~ d_eff (size_scaled_stiffness),
// 0 = every pair as stiff as media-media (shorter dt: t_c ~ sqrt(m / k)).
#include <benchmark/benchmark.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>

#include "dem/shear_cell.hpp"

namespace {

using millflow::dem::ShearCell;
using millflow::dem::ShearCellSetup;
using millflow::dem::size_scaled_stiffness;
using millflow::dem::Vec3;

ShearCellSetup cell_setup(double inertial_number, double ratio, double load, bool size_scaled) {
  ShearCellSetup s;
  s.media_diameter = 0.01;
  s.media = {"steel", 7800.0};
  s.powder = {"clinker", 3000.0};
  s.normal_stress = 1000.0;
  const double k = 100.0 * s.normal_stress * s.media_diameter;
  const double d = s.media_diameter, dp = ratio * d;
  s.media_media = {.restitution = 0.5, .friction = 0.5, .normal_stiffness = k};
  s.media_powder = {.restitution = 0.5,
                    .friction = 0.5,
                    .normal_stiffness = size_scaled ? size_scaled_stiffness(k, d, d, dp) : k};
  s.powder_powder = {.restitution = 0.5,
                     .friction = 0.5,
                     .normal_stiffness = size_scaled ? size_scaled_stiffness(k, d, dp, dp) : k};
  s.powder_diameter_ratio = ratio;
  s.powder_load = load;
  s.shear_rate = inertial_number * std::sqrt(s.normal_stress / s.media.density) / d;
  return s;
}

double jop_forterre_pouliquen(double i) {
  return 0.38 + (0.64 - 0.38) / (0.279 / i + 1.0);
}

void BM_MuOfI(benchmark::State& state) {
  spdlog::set_level(spdlog::level::warn);
  ShearCellSetup setup = cell_setup(state.range(0) / 1000.0, 0.2, 0.0, true);
  setup.size_diameters = Vec3(5, 6, 5);
  for (auto _ : state) {
    ShearCell cell(setup);
    cell.warm_up(3.0, 3);
    const auto m = cell.measure(3.0);
    state.counters["I"] = m.inertial_number;
    state.counters["mu"] = m.friction;
    state.counters["mu_JFP"] = jop_forterre_pouliquen(m.inertial_number);
    state.counters["phi"] = m.media_solid_fraction;
    state.counters["bulk/nominal"] = m.bulk_shear_rate / m.nominal_shear_rate;
    state.counters["p_N_target"] = m.normal_stress / setup.normal_stress;
    state.counters["steady_dev"] = m.steady_state_deviation;
    state.counters["energy_err"] = m.energy_balance_error;
    state.counters["psteps_per_s"] = m.particle_steps_per_second;
  }
}
BENCHMARK(BM_MuOfI)->Arg(10)->Arg(30)->Arg(100)->Arg(300)->Iterations(1)->Unit(benchmark::kSecond);

void BM_PowderCellCost(benchmark::State& state) {
  spdlog::set_level(spdlog::level::warn);
  const ShearCellSetup setup =
      cell_setup(0.1, state.range(0) / 100.0, state.range(1) / 100.0, state.range(2) != 0);
  for (auto _ : state) {
    ShearCell cell(setup);
    const std::size_t steps = 100;
    const auto start = std::chrono::steady_clock::now();
    cell.system().step(steps);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double rate = static_cast<double>(steps * cell.system().size()) / seconds;
    const double steps_per_strain = 1.0 / (setup.shear_rate * cell.system().time_step());
    state.counters["media"] = static_cast<double>(cell.media_count());
    state.counters["powder"] = static_cast<double>(cell.powder_count());
    state.counters["dt_us"] = cell.system().time_step() * 1e6;
    state.counters["psteps_per_s"] = rate;
    state.counters["s_per_strain"] =
        steps_per_strain * static_cast<double>(cell.system().size()) / rate;
  }
}
BENCHMARK(BM_PowderCellCost)
    ->Args({20, 0, 1})
    ->Args({20, 50, 1})
    ->Args({20, 50, 0})
    ->Args({10, 50, 1})
    ->Args({10, 50, 0})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
