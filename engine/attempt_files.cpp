#include "engine/attempt_files.hpp"

#include <tbb/task_arena.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <mutex>
#include <sstream>

#include "engine/canonical_json.hpp"
#include "engine/files.hpp"
#include "engine/interrupt.hpp"
#include "engine/validation.hpp"
#include "util/durable_file.hpp"
#include "util/sha256.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
using nlohmann::json;
namespace {

constexpr int kSpecFormat = 1;

std::string read_text(const fs::path& file) {
  // /dev/zero or a named pipe would be read until memory runs out, or forever.
  if (fs::exists(file) && !fs::is_regular_file(file))
    throw std::runtime_error(file.string() + " is not a regular file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Durable (temp, fsync, rename): after a crash the file is whole or absent.
void write_file_atomically(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  util::write_file_durably(file, text);
}

json input_json(const TaskInput& input) {
  json artifacts = json::object();
  for (const auto& [name, file] : input.artifacts) artifacts[name] = file.string();
  return {
      {"key", input.key}, {"kind", input.kind}, {"result", input.result}, {"artifacts", artifacts}};
}

TaskInput input_from(const json& value) {
  TaskInput input{value.at("key").get<std::string>(),
                  value.at("kind").get<std::string>(),
                  value.at("result"),
                  {}};
  for (const auto& [name, file] : value.at("artifacts").items())
    input.artifacts[name] = file.get<std::string>();
  return input;
}

json children_json(const std::vector<ChildTask>& children) {
  json list = json::array();
  for (const auto& child : children) {
    list.push_back(
        {{"kind", child.kind}, {"params", child.params}, {"extra_upstream", child.extra_upstream}});
  }
  return list;
}

std::vector<ChildTask> children_from(const json& list) {
  std::vector<ChildTask> children;
  for (const auto& child : list) {
    children.push_back(ChildTask{child.at("kind").get<std::string>(), child.at("params"),
                                 child.at("extra_upstream").get<std::vector<std::string>>()});
  }
  return children;
}

// Writes result.json and the artifact copies; returns the completion marker naming them.
json write_outputs(const fs::path& output_dir, const TaskOutcome& outcome) {
  const std::string result_text = canonical_json(
      json{{"result", outcome.result}, {"children", children_json(outcome.children)}});
  write_file_atomically(output_dir / "result.json", result_text);
  json artifacts = json::array();
  for (size_t i = 0; i < outcome.artifacts.size(); ++i) {
    const std::string file = "artifacts/" + std::to_string(i);
    const fs::path target = output_dir / file;
    local_file_system().copy_durably(outcome.artifacts[i].file, target);
    artifacts.push_back({{"name", outcome.artifacts[i].name},
                         {"file", file},
                         {"sha256", util::sha256_file_hex(target)},
                         {"size", static_cast<std::int64_t>(fs::file_size(target))}});
  }
  return {{"status", "done"},
          {"result_sha256", util::sha256_hex(result_text)},
          {"artifacts", artifacts}};
}

}  // namespace

void write_attempt_spec(const AttemptSpec& spec, const fs::path& file) {
  json inputs = json::array();
  for (const auto& input : spec.inputs) inputs.push_back(input_json(input));
  const json document = {{"millflow_attempt", kSpecFormat},
                         {"key", spec.task.key},
                         {"kind", spec.task.kind},
                         {"version", spec.task.version},
                         {"params", spec.task.params},
                         {"upstream", spec.task.upstream},
                         {"inputs", inputs},
                         {"attempt", spec.attempt},
                         {"threads", spec.threads},
                         {"work_dir", spec.work_dir.string()},
                         {"output_dir", spec.output_dir.string()}};
  write_file_atomically(file, document.dump());
}

AttemptSpec read_attempt_spec(const fs::path& file) {
  json document;
  try {
    document = json::parse(read_text(file));
  } catch (const std::exception& error) {
    throw InvalidInput({{"", "task-spec file " + file.string() + " cannot be read: " + error.what(),
                         "pass a spec file written by the millflow coordinator"}});
  }
  // Any JSON at all may arrive here (an array, a string, the format as text): compare, never cast.
  const bool versioned = document.is_object() && document.contains("millflow_attempt") &&
                         document.at("millflow_attempt") == kSpecFormat;
  if (!versioned) {
    throw InvalidInput(
        {{"/millflow_attempt",
          file.string() + " is not a version " + std::to_string(kSpecFormat) + " task-spec file",
          "run the millflow that wrote it"}});
  }
  try {
    AttemptSpec spec;
    spec.task = TaskSpec{document.at("key").get<std::string>(),
                         document.at("kind").get<std::string>(),
                         document.at("version").get<std::string>(),
                         document.at("params"),
                         document.at("upstream").get<std::vector<std::string>>(),
                         {}};
    for (const auto& input : document.at("inputs")) spec.inputs.push_back(input_from(input));
    spec.attempt = document.at("attempt").get<int>();
    spec.threads = document.at("threads").get<int>();
    spec.work_dir = document.at("work_dir").get<std::string>();
    spec.output_dir = document.at("output_dir").get<std::string>();
    return spec;
  } catch (const json::exception& error) {
    throw InvalidInput({{"", "task-spec file " + file.string() + " is incomplete: " + error.what(),
                         "pass a spec file written by the millflow coordinator"}});
  }
}

int execute_attempt(const KindRegistry& kinds, const fs::path& spec_file,
                    const std::function<bool()>& stop_requested, std::ostream& log) {
  std::mutex log_mutex;
  auto log_line = [&](std::string_view message) {
    std::lock_guard lock(log_mutex);
    log << message << std::endl;
  };
  AttemptSpec spec;
  const TaskKind* kind = nullptr;
  try {
    spec = read_attempt_spec(spec_file);
    kind = &kinds.get(spec.task.kind);
    if (kind->version != spec.task.version) {
      throw InvalidInput({{"/version",
                           "task kind " + kind->name + " is version " + kind->version +
                               " in this millflow, the spec wants " + spec.task.version,
                           "run jobs with the same millflow build as the coordinator"}});
    }
  } catch (const std::exception& error) {
    log_line(std::string("millflow exec: ") + error.what());
    return kExecBadSpec;
  }
  const auto started = std::chrono::steady_clock::now();
  json marker;
  int code = kExecDone;
  try {
    StopWatcher watcher(stop_requested);
    TaskContext context{.key = spec.task.key,
                        .params = spec.task.params,
                        .inputs = spec.inputs,
                        .work_dir = spec.work_dir,
                        .threads = spec.threads,
                        .attempt = spec.attempt,
                        .stop = watcher.token(),
                        .progress = [](double, std::string_view) {},
                        .log = log_line};
    TaskOutcome outcome;
    tbb::task_arena arena(spec.threads);
    arena.execute([&] { outcome = kind->run(context); });
    if (outcome.interrupted) {
      marker = {{"status", "stopped"}};
      code = kExecStopped;
    } else {
      marker = write_outputs(spec.output_dir, outcome);
    }
  } catch (const std::exception& error) {
    log_line(std::string("millflow exec: the task failed: ") + error.what());
    marker = {{"status", "failed"}, {"error", error.what()}};
    code = kExecFailed;
  }
  marker["duration_s"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  write_file_atomically(spec.output_dir / "complete.json", marker.dump());
  return code;
}

std::optional<AttemptOutcome> read_attempt_outcome(const fs::path& output_dir,
                                                   const std::string& key, int attempt) {
  const fs::path marker_file = output_dir / "complete.json";
  if (!fs::exists(marker_file)) return std::nullopt;
  AttemptOutcome finished{key, attempt, std::nullopt, {}, 0.0};
  try {
    const json marker = json::parse(read_text(marker_file));
    finished.duration_s = marker.value("duration_s", 0.0);
    const std::string status = marker.at("status").get<std::string>();
    if (status == "failed") {
      finished.error = marker.value("error", std::string("the job reported a failure"));
    } else if (status == "stopped") {
      finished.outcome = TaskOutcome::stopped();
    } else {
      const std::string result_text = read_text(output_dir / "result.json");
      if (util::sha256_hex(result_text) != marker.at("result_sha256").get<std::string>()) {
        throw std::runtime_error("result.json does not match the SHA-256 of its completion marker");
      }
      const json body = json::parse(result_text);
      finished.outcome = TaskOutcome::with_result(body.at("result"));
      finished.outcome.children = children_from(body.at("children"));
      for (const auto& artifact : marker.at("artifacts")) {
        const fs::path file = output_dir / artifact.at("file").get<std::string>();
        if (util::sha256_file_hex(file) != artifact.at("sha256").get<std::string>()) {
          throw std::runtime_error("artifact " + file.string() +
                                   " does not match the SHA-256 of its completion marker");
        }
        finished.outcome.artifacts.push_back({artifact.at("name").get<std::string>(), file});
      }
    }
  } catch (const std::exception& error) {
    finished.outcome = {};
    finished.error = "the output in " + output_dir.string() + " is rejected: " + error.what();
  }
  return finished;
}

}  // namespace millflow::engine
