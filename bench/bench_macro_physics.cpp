// The macro task on its own: how fast (particle-timesteps per second) on the macro runs of
// campaigns/quick.json and on a short piece of campaigns/cement_ball_mill.json's 4 m mill, and the
// mill physics: power against fill at 75% of critical on quick.json's 1 m mill (40 mm balls, 4
// lifters, a 0.15 m slice), and against speed at J = 0.3 and fill at 75% of critical on the tiny
// test mill (D = 0.2 m, 12 mm balls, 4 lifters). Not a unit test: minutes on 2 cores. Run from the
// repository root (it reads campaigns/*.json):
//   build/bench/bench_macro_physics --benchmark_filter=Quick_Macro     (timing only)
//   build/bench/bench_macro_physics --benchmark_filter=Quick_PowerVsFill   (~25 min)
//   build/bench/bench_macro_physics --benchmark_filter=Tiny_Power          (the tiny mill: speed
//   and fill, ~2 min) build/bench/bench_macro_physics --benchmark_filter=Cement4m_PowerAtJ30 (the 4
//   m mill's kW/t, ~15 min)
// Counters: power_kw, kw_per_t (per tonne of balls), bond_kw_per_t (Bond's correlation at the
// same D, J, phi_c), hogg_kw (Hogg-Fuerstenau's power for this slice's ball mass, repose 35 deg),
// power_sem_kw (the standard error of power_kw from quarter-revolution means), toe/shoulder (deg,
// see method/macro_measure.hpp), torque_arm_kw, wall_s (the run's wall time),
// particle_steps_per_s (wall clock, 2 threads; per core: divide by 2), particle_steps_per_cpu_s
// (per CPU-second the process used: per core on a machine shared with other work).
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <numeric>
#include <string>
#include <vector>

#include "tasks/campaign.hpp"
#include "tests/tasks/macro_fixtures.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

// The standard error of the mean power, kW, from the means of `groups` equal runs of consecutive
// blocks of power.csv (a quarter revolution each: one lifter passage), taken as independent.
double power_standard_error_kw(const std::filesystem::path& power_csv,
                               std::size_t blocks_per_group) {
  std::ifstream in(power_csv);
  std::string line;
  std::getline(in, line);  // header
  std::vector<double> powers;
  while (std::getline(in, line)) powers.push_back(std::stod(line.substr(line.find(',') + 1)));
  std::vector<double> means;
  for (std::size_t g = 0; (g + 1) * blocks_per_group <= powers.size(); ++g) {
    const auto first = powers.begin() + static_cast<std::ptrdiff_t>(g * blocks_per_group);
    means.push_back(
        std::accumulate(first, first + static_cast<std::ptrdiff_t>(blocks_per_group), 0.0) /
        static_cast<double>(blocks_per_group));
  }
  if (means.size() < 2) return 0.0;
  const double mean =
      std::accumulate(means.begin(), means.end(), 0.0) / static_cast<double>(means.size());
  double square = 0.0;
  for (double m : means) square += (m - mean) * (m - mean);
  return std::sqrt(square / static_cast<double>(means.size() - 1) /
                   static_cast<double>(means.size())) /
         1000.0;
}

void run_and_report(benchmark::State& state, const json& params) {
  testing::ScratchDir scratch("bench_macro");
  json result;
  double seconds = 0.0, cpu_seconds = 0.0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();  // the process's CPU time, all threads
    result = testing::DirectRun{params, scratch.path() / "work", "bench", 2}.run().result;
    cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  const double steps = result["measure_end_s"].get<double>() / result["dt_s"].get<double>();
  state.counters["n_balls"] = result["n_balls"].get<double>();
  state.counters["particle_steps_per_s"] = steps * result["n_balls"].get<double>() / seconds;
  state.counters["particle_steps_per_cpu_s"] =
      steps * result["n_balls"].get<double>() / cpu_seconds;
  state.counters["fill"] = result["fill"].get<double>();
  state.counters["speed"] = result["speed_fraction"].get<double>();
  state.counters["power_kw"] = result["power"]["mean_kw"].get<double>();
  state.counters["torque_arm_kw"] = result["power"]["torque_arm_kw"].get<double>();
  state.counters["kw_per_t"] = result["power"]["kw_per_t_balls"].get<double>();
  state.counters["bond_kw_per_t"] = result["correlations"]["bond_kw_per_t"].get<double>();
  state.counters["hogg_kw"] = result["correlations"]["hogg_fuerstenau_kw_per_t"].get<double>() *
                              result["ball_mass_kg"].get<double>() / 1000.0;
  state.counters["wall_s"] = seconds;
  // tasks/macro.cpp closes 200 power blocks per revolution.
  state.counters["power_sem_kw"] =
      power_standard_error_kw(scratch.path() / "work" / "power.csv", 50);
  const json& charge = result["charge"];
  state.counters["toe"] =
      charge["toe_angle_deg"].is_number() ? charge["toe_angle_deg"].get<double>() : -999.0;
  state.counters["shoulder"] = charge["shoulder_angle_deg"].is_number()
                                   ? charge["shoulder_angle_deg"].get<double>()
                                   : -999.0;
}

// The first point of a campaign file, with the slices the macro task reads. (The planner passes
// tasks::macro_params, which also drops the materials the mill does not use.)
json first_point_params(const char* campaign) {
  const auto point = expand(load_campaign(std::filesystem::path("campaigns") / campaign)).at(0);
  json params;
  for (const char* slice : {"materials", "interactions", "dem", "mill", "media", "macro"}) {
    params[slice] = point.document.at(slice);
  }
  return params;
}

// quick.json's four macro runs (fill x speed; the sweep's powder loads share them), as a campaign
// runs them: each on 2 threads.
void Quick_Macro(benchmark::State& state) {
  const double fills[] = {0.2, 0.35}, speeds[] = {0.65, 0.8};
  json params = first_point_params("quick.json");
  params["macro"]["fill"] = fills[state.range(0) / 2];
  params["macro"]["speed_fraction"] = speeds[state.range(0) % 2];
  run_and_report(state, params);
}
BENCHMARK(Quick_Macro)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime()->DenseRange(0, 3);

// Power against fill at 75% of critical on quick.json's mill: one revolution of warm-up, three
// measured. Arguments: J in %, dem.seed (quick.json's is 1; a second seed repeats the fills around
// the peak with another bed).
json quick_power_params(double fill) {
  json params = first_point_params("quick.json");
  params["macro"].update({{"fill", fill},
                          {"speed_fraction", 0.75},
                          {"warmup_revolutions", 1.0},
                          {"measure_revolutions", 3.0},
                          {"vtk_interval", 100.0}});
  return params;
}

void Quick_PowerVsFill(benchmark::State& state) {
  json params = quick_power_params(static_cast<double>(state.range(0)) / 100.0);
  params["dem"]["seed"] = state.range(1);
  run_and_report(state, params);
}
BENCHMARK(Quick_PowerVsFill)
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->ArgsProduct({{20, 30, 35, 40, 45, 50, 55, 60}, {1}})
    ->ArgsProduct({{45, 50, 55}, {2}});

// Throughput only: 0.1 s of settling and a sliver of measurement of the 4 m mill.
void Cement4m_Throughput(benchmark::State& state) {
  json params = first_point_params("cement_ball_mill.json");
  params["macro"].update({{"settle_time", 0.1},
                          {"warmup_revolutions", 0.0},
                          {"measure_revolutions", 0.01},
                          {"vtk_interval", 100.0}});
  run_and_report(state, params);
}
BENCHMARK(Cement4m_Throughput)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// Specific power of the 4 m mill at J = 0.3 and 75% of critical, the reference point for
// the classical correlations (Bond grows with D^0.3): 1 revolution of warm-up, 2 measured.
void Cement4m_PowerAtJ30(benchmark::State& state) {
  json params = first_point_params("cement_ball_mill.json");
  params["macro"].update({{"fill", 0.3},
                          {"speed_fraction", 0.75},
                          {"warmup_revolutions", 1.0},
                          {"measure_revolutions", 2.0},
                          {"vtk_interval", 100.0}});
  run_and_report(state, params);
}
BENCHMARK(Cement4m_PowerAtJ30)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

json tiny_sweep_params(double fill, double speed, double warmup_revolutions = 1.5) {
  json params = testing::tiny_macro_params(fill, speed);
  params["macro"].update({{"warmup_revolutions", warmup_revolutions},
                          {"measure_revolutions", 2.0},
                          {"vtk_interval", 100.0}});
  return params;
}

void Tiny_PowerVsSpeed(benchmark::State& state) {
  run_and_report(state, tiny_sweep_params(0.3, static_cast<double>(state.range(0)) / 100.0));
}
BENCHMARK(Tiny_PowerVsSpeed)
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Arg(30)
    ->Arg(50)
    ->Arg(65)
    ->Arg(75)
    ->Arg(85)
    ->Arg(95)
    ->Arg(110)
    ->Arg(150);

// At and above critical speed the charge takes many revolutions to climb onto the shell (1.5
// revolutions of warm-up leave it still tumbling): the same mill with 10 revolutions of warm-up.
void Tiny_PowerAboveCritical(benchmark::State& state) {
  run_and_report(state, tiny_sweep_params(0.3, static_cast<double>(state.range(0)) / 100.0, 10.0));
}
BENCHMARK(Tiny_PowerAboveCritical)
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Arg(75)
    ->Arg(95)
    ->Arg(110)
    ->Arg(150)
    ->Arg(200);

void Tiny_PowerVsFill(benchmark::State& state) {
  run_and_report(state, tiny_sweep_params(static_cast<double>(state.range(0)) / 100.0, 0.75));
}
BENCHMARK(Tiny_PowerVsFill)
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Arg(20)
    ->Arg(30)
    ->Arg(40)
    ->Arg(50)
    ->Arg(60);

// The time step's share of the power: the same mills at dem.steps_per_collision 20 (the
// campaigns'), 40, 80 and 160 (the tiny mill, seeds 7 and 8) and 20, 40, 80 (quick.json's at J =
// 0.35, seeds 1 and 2). A collision's restitution carries a first-order error with where its end
// falls between steps (tests/dem/test_physics_collisions.cpp), and the power is dissipation.
// Arguments: dem.steps_per_collision, dem.seed.
void run_at_resolution(benchmark::State& state, json params) {
  params["dem"]["steps_per_collision"] = state.range(0);
  params["dem"]["seed"] = state.range(1);
  run_and_report(state, params);
}

void Tiny_PowerVsResolution(benchmark::State& state) {
  run_at_resolution(state, tiny_sweep_params(0.3, 0.75));
}
BENCHMARK(Tiny_PowerVsResolution)
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->ArgsProduct({{20, 40, 80, 160}, {7, 8}});

void Quick_PowerVsResolution(benchmark::State& state) {
  run_at_resolution(state, quick_power_params(0.35));
}
BENCHMARK(Quick_PowerVsResolution)
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->ArgsProduct({{20, 40, 80}, {1, 2}});

}  // namespace
}  // namespace millflow::tasks

BENCHMARK_MAIN();
