// The macro task on its own: how fast (particle-timesteps per second) on the first point of
// campaigns/quick.json and on a short piece of campaigns/cement_ball_mill.json's 4 m mill, and the
// mill physics of the tiny test mill (D = 0.2 m, 12 mm balls, 4 lifters): power against speed
// at J = 0.3 and against fill at 75% of critical (J <= 0.4: dem::build_mill's loose
// lattice holds too few balls for J = 0.5 in a mill only 17 balls wide). Not a unit test: minutes
// on 2 cores. Run from the repository root (it reads campaigns/*.json):
//   build/bench/bench_macro_physics --benchmark_filter=Quick     (timing only)
// Counters: power_kw, kw_per_t (per tonne of balls), bond_kw_per_t (Bond's correlation at the
// same D, J, phi_c), toe/shoulder (deg, see tasks/macro_measure.hpp), torque_arm_kw.
#include <benchmark/benchmark.h>

#include <chrono>

#include "tasks/campaign.hpp"
#include "tests/tasks/macro_fixtures.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

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

void run_and_report(benchmark::State& state, const json& params) {
  testing::ScratchDir scratch("bench_macro");
  json result;
  double seconds = 0.0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    result = testing::DirectRun{params, scratch.path() / "work", "bench", 2}.run().result;
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  const double steps = result["measure_end_s"].get<double>() / result["dt_s"].get<double>();
  state.counters["n_balls"] = result["n_balls"].get<double>();
  state.counters["particle_steps_per_s"] = steps * result["n_balls"].get<double>() / seconds;
  state.counters["fill"] = result["fill"].get<double>();
  state.counters["speed"] = result["speed_fraction"].get<double>();
  state.counters["power_kw"] = result["power"]["mean_kw"].get<double>();
  state.counters["torque_arm_kw"] = result["power"]["torque_arm_kw"].get<double>();
  state.counters["kw_per_t"] = result["power"]["kw_per_t_balls"].get<double>();
  state.counters["bond_kw_per_t"] = result["correlations"]["bond_kw_per_t"].get<double>();
  const json& charge = result["charge"];
  state.counters["toe"] =
      charge["toe_angle_deg"].is_number() ? charge["toe_angle_deg"].get<double>() : -999.0;
  state.counters["shoulder"] = charge["shoulder_angle_deg"].is_number()
                                   ? charge["shoulder_angle_deg"].get<double>()
                                   : -999.0;
}

void Quick_FirstPoint(benchmark::State& state) {
  run_and_report(state, first_point_params("quick.json"));
}
BENCHMARK(Quick_FirstPoint)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

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

json tiny_sweep_params(double fill, double speed) {
  json params = testing::tiny_macro_params(fill, speed);
  params["macro"].update(
      {{"warmup_revolutions", 1.5}, {"measure_revolutions", 2.0}, {"vtk_interval", 100.0}});
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

void Tiny_PowerVsFill(benchmark::State& state) {
  run_and_report(state, tiny_sweep_params(static_cast<double>(state.range(0)) / 100.0, 0.75));
}
BENCHMARK(Tiny_PowerVsFill)
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Arg(20)
    ->Arg(30)
    ->Arg(40);

}  // namespace
}  // namespace millflow::tasks

BENCHMARK_MAIN();
