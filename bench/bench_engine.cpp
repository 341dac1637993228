// Engine overhead with trivial tasks: a 10,000-task campaign end to end (launch record, run,
// commit per task) and its fully cached resubmission.
//   ./build/bench/bench_engine
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>

#include "engine/campaign.hpp"
#include "engine/testing_tasks.hpp"

namespace {

namespace fs = std::filesystem;
using millflow::engine::Campaign;
using millflow::engine::Registry;

constexpr int kTasks = 10000;

// Independent trivial sum tasks, every tenth one below the previous tenth (some edges).
Campaign trivial_campaign() {
  nlohmann::json tasks = nlohmann::json::array();
  for (int i = 0; i < kTasks; ++i) {
    nlohmann::json task = {{"id", std::to_string(i)}, {"kind", "sum"}, {"params", {{"value", i}}}};
    if (i >= 10 && i % 10 == 0) task["after"] = {std::to_string(i - 10)};
    tasks.push_back(task);
  }
  return Campaign{
      "bench", "millflow-test", {{"format", "millflow-test"}, {"name", "bench"}, {"tasks", tasks}}};
}

fs::path scratch_db() {
  const fs::path dir = fs::temp_directory_path() / ("millflow-bench-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir / "bench.db";
}

Registry registry() {
  Registry result;
  millflow::engine::add_testing(result);
  return result;
}

void BM_TrivialCampaignEndToEnd(benchmark::State& state) {
  const auto campaign = trivial_campaign();
  const auto kinds = registry();
  millflow::engine::SubmitOptions options;
  options.run.jobs = 2;
  for (auto _ : state) {
    state.PauseTiming();
    const fs::path db = scratch_db();
    state.ResumeTiming();
    const auto summary = millflow::engine::submit_campaign(kinds, campaign, db, options);
    if (summary.done != kTasks) state.SkipWithError("not every task ran");
    state.PauseTiming();
    fs::remove_all(db.parent_path());
    state.ResumeTiming();
  }
  state.counters["us_per_task"] = benchmark::Counter(
      static_cast<double>(kTasks) * static_cast<double>(state.iterations()),
      benchmark::Counter::kIsRate | benchmark::Counter::kInvert, benchmark::Counter::kIs1000);
}
BENCHMARK(BM_TrivialCampaignEndToEnd)->Unit(benchmark::kMillisecond)->Iterations(2)->UseRealTime();

void BM_FullyCachedResubmission(benchmark::State& state) {
  const auto campaign = trivial_campaign();
  const auto kinds = registry();
  millflow::engine::SubmitOptions options;
  options.run.jobs = 2;
  const fs::path db = scratch_db();
  millflow::engine::submit_campaign(kinds, campaign, db, options);
  for (auto _ : state) {
    const auto summary = millflow::engine::submit_campaign(kinds, campaign, db, options);
    if (summary.cached != kTasks) state.SkipWithError("resubmission was not fully cached");
  }
  fs::remove_all(db.parent_path());
}
BENCHMARK(BM_FullyCachedResubmission)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
