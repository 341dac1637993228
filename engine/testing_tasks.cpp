#include "engine/testing_tasks.hpp"

#include <fmt/format.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <set>
#include <thread>

#include "engine/files.hpp"
#include "engine/json_text.hpp"
#include "engine/validation.hpp"

namespace millflow::engine {
namespace {

std::atomic<int> g_running_sleeps{0};
std::atomic<int> g_max_running_sleeps{0};

std::int64_t integer_param(const nlohmann::json& params, const char* name, std::int64_t fallback) {
  if (!params.contains(name)) return fallback;
  if (!params[name].is_number_integer()) {
    throw InvalidInput(
        {{std::string("/params/") + name, "must be an integer, got " + params[name].dump(), ""}});
  }
  return params[name].get<std::int64_t>();
}

// Sleeps in small steps; false when a stop was requested first.
bool sleep_unless_stopped(TaskContext& context, std::int64_t ms) {
  for (std::int64_t slept = 0; slept < ms; slept += 2) {
    if (context.stop.stop_requested()) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(std::min<std::int64_t>(2, ms - slept)));
    if (ms > 0) context.progress(static_cast<double>(slept) / static_cast<double>(ms), "sleeping");
  }
  return !context.stop.stop_requested();
}

TaskOutcome run_sleep(TaskContext& context) {
  const int now = g_running_sleeps.fetch_add(1) + 1;
  int seen = g_max_running_sleeps.load();
  while (now > seen && !g_max_running_sleeps.compare_exchange_weak(seen, now)) {
  }
  const std::int64_t ms = integer_param(context.params, "ms", 0);
  const bool finished = sleep_unless_stopped(context, ms);
  g_running_sleeps.fetch_sub(1);
  if (!finished) return TaskOutcome::stopped();
  return TaskOutcome::with_result({{"slept_ms", ms}});
}

struct StepsCheckpoint {
  std::int64_t step = 0;
  std::uint64_t state = 0;
};

// The saved state, or none (step 0) when there is no file; one that cannot be read is logged as
// a warning and the task starts again, as the DEM kinds do.
StepsCheckpoint read_steps_checkpoint(const std::filesystem::path& file, TaskContext& context) {
  StepsCheckpoint checkpoint;
  std::ifstream in(file);
  if (in && !(in >> checkpoint.step >> checkpoint.state)) {
    context.log(fmt::format("{}the checkpoint {} cannot be read; starting again from step 0",
                            kTaskWarning, file.string()));
    return {};
  }
  return checkpoint;
}

void write_steps_checkpoint(const std::filesystem::path& file, const StepsCheckpoint& checkpoint) {
  const auto temporary = file.string() + ".tmp";
  std::ofstream(temporary) << checkpoint.step << ' ' << checkpoint.state << '\n';
  std::filesystem::rename(temporary, file);
}

// A long task in miniature: a chain of steps whose end state depends on every step, checkpointed
// after each, so a run stopped and continued gives what one run gives only if the checkpoint works.
TaskOutcome run_steps(TaskContext& context) {
  const std::int64_t steps = integer_param(context.params, "steps", 1);
  const std::int64_t step_ms = integer_param(context.params, "step_ms", 0);
  std::filesystem::create_directories(context.work_dir);
  const auto file = context.work_dir / "steps.checkpoint";
  StepsCheckpoint checkpoint = read_steps_checkpoint(file, context);
  if (checkpoint.step > 0)
    context.log(fmt::format("continuing from step {} of {}", checkpoint.step, steps));
  while (checkpoint.step < steps) {
    if (!sleep_unless_stopped(context, step_ms)) {
      context.log(fmt::format("stopped at step {} of {}", checkpoint.step, steps));
      return TaskOutcome::stopped();
    }
    checkpoint.state = checkpoint.state * 6364136223846793005ULL + 1442695040888963407ULL +
                       static_cast<std::uint64_t>(checkpoint.step);
    ++checkpoint.step;
    write_steps_checkpoint(file, checkpoint);
  }
  return TaskOutcome::with_result(
      {{"steps", steps}, {"state", fmt::format("{:016x}", checkpoint.state)}});
}

TaskOutcome run_fail(TaskContext& context) {
  const std::int64_t failures = integer_param(context.params, "failures", 0);
  if (context.attempt <= failures) {
    if (context.params.value("non_finite", false))  // fails by a result the store refuses
      return TaskOutcome::with_result({{"value", std::numeric_limits<double>::quiet_NaN()}});
    throw std::runtime_error(
        fmt::format("planned failure: attempt {} of a task that fails its first {}",
                    context.attempt, failures));
  }
  return TaskOutcome::with_result({{"failures", failures}});
}

void trace_start(const std::string& key) {
  const char* trace = std::getenv("MILLFLOW_TEST_TRACE");
  if (trace == nullptr || *trace == '\0') return;
  std::ofstream(trace, std::ios::app) << key << '\n';
}

std::int64_t read_sum_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::int64_t value = 0;
  if (!(in >> value)) throw std::runtime_error("cannot read sum artifact " + file.string());
  return value;
}

TaskOutcome run_sum(TaskContext& context) {
  trace_start(context.key);
  std::int64_t total = integer_param(context.params, "value", 0);
  for (const auto& input : context.inputs) {
    if (!input.result.contains("sum")) continue;
    const auto upstream_sum = input.result["sum"].get<std::int64_t>();
    if (auto file = input.artifacts.find("sum.txt");
        file != input.artifacts.end() && read_sum_file(file->second) != upstream_sum) {
      throw std::runtime_error("input artifact sum.txt of " + input.key +
                               " disagrees with its result");
    }
    total += upstream_sum;
  }
  if (!sleep_unless_stopped(context, integer_param(context.params, "sleep_ms", 0)))
    return TaskOutcome::stopped();
  auto outcome = TaskOutcome::with_result({{"sum", total}});
  if (context.params.contains("skipped")) outcome.result["skipped"] = context.params["skipped"];
  if (context.params.value("artifact", false)) {
    std::filesystem::create_directories(context.work_dir);
    const auto file = context.work_dir / "sum.txt";
    std::ofstream(file) << total << '\n';
    outcome.artifacts.push_back({"sum.txt", file});
  }
  return outcome;
}

TaskOutcome run_fanout(TaskContext& context) {
  const std::int64_t value = integer_param(context.params, "value", 0);
  auto outcome = TaskOutcome::with_result({{"sum", value}});
  for (std::int64_t i = 0; i < integer_param(context.params, "children", 0); ++i) {
    outcome.children.push_back(ChildTask{"sum", {{"value", i}}, {}});
  }
  return outcome;
}

// Validates a millflow-test document, collecting every error.
nlohmann::json load_test_campaign(const std::filesystem::path& file) {
  const nlohmann::json document = parse_json_text(read_input_file(file)).document;
  std::vector<ValidationError> errors;
  if (!document.contains("name") || !document["name"].is_string()) {
    errors.push_back({"/name", "missing or not a string", "add \"name\": \"<campaign name>\""});
  }
  if (!document.contains("tasks") || !document["tasks"].is_array()) {
    errors.push_back(
        {"/tasks", "missing or not an array", "add \"tasks\": [{\"id\": ..., \"kind\": ...}]"});
    throw InvalidInput(errors);
  }
  KindRegistry kinds;
  add_testing_kinds(kinds);
  std::set<std::string> ids;
  for (size_t i = 0; i < document["tasks"].size(); ++i) {
    const auto& task = document["tasks"][i];
    const std::string path = "/tasks/" + std::to_string(i);
    const std::string id = task.value("id", "");
    if (id.empty())
      errors.push_back({path + "/id", "missing or empty", "give each task a unique string id"});
    if (!kinds.contains(task.value("kind", ""))) {
      errors.push_back({path + "/kind",
                        "unknown kind " + task.value("kind", nlohmann::json()).dump(),
                        "use sleep, fail, steps, sum or fanout"});
    }
    if (task.contains("params") && !task["params"].is_object()) {
      errors.push_back({path + "/params", "must be an object", ""});
    }
    for (const auto& after : task.value("after", nlohmann::json::array())) {
      if (!after.is_string() || ids.count(after.get<std::string>()) == 0) {
        errors.push_back({path + "/after", after.dump() + " is not the id of an earlier task",
                          "list earlier tasks only"});
      }
    }
    if (!ids.insert(id).second && !id.empty())
      errors.push_back({path + "/id", "duplicate id \"" + id + "\"", ""});
  }
  if (!errors.empty()) throw InvalidInput(errors);
  return document;
}

void plan_test_campaign(const nlohmann::json& document, Plan& plan) {
  std::map<std::string, std::string> key_of;
  for (const auto& task : document["tasks"]) {
    std::vector<std::string> upstream;
    for (const auto& after : task.value("after", nlohmann::json::array()))
      upstream.push_back(key_of.at(after.get<std::string>()));
    key_of[task["id"].get<std::string>()] =
        plan.add(task["kind"].get<std::string>(), task.value("params", nlohmann::json::object()),
                 std::move(upstream));
  }
}

}  // namespace

void add_testing_kinds(KindRegistry& kinds) {
  kinds.add({"sleep", "1", run_sleep});
  kinds.add({"fail", "1", run_fail});
  kinds.add({"steps", "1", run_steps});
  kinds.add({"sum", "1", run_sum});
  kinds.add({"fanout", "1", run_fanout, true});
}

void add_testing(Registry& registry) {
  add_testing_kinds(registry.kinds);
  registry.add_format({"millflow-test", load_test_campaign, plan_test_campaign});
}

int take_max_concurrent_sleeps() {
  return g_max_running_sleeps.exchange(0);
}

}  // namespace millflow::engine
