#pragma once
// Task kinds, task specifications and task keys.
//
// A task is a kind (name + version), canonical parameters and the keys of its upstream tasks.
// Its key is the SHA-256 (hex) of the tagged text
//     millflow-task 1
//     kind:<name>
//     version:<version>
//     params:<canonical JSON>
//     upstream:<key>,<key>,...
// so changing a parameter re-keys that task and every task below it (a Merkle chain). The exact
// text is stored beside the key so `millflow explain` can show what was hashed.
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stop_token>
#include <string>
#include <string_view>
#include <vector>

namespace millflow::engine {

struct TaskSpec {
  std::string key;
  std::string kind;
  std::string version;
  nlohmann::json params;
  std::vector<std::string> upstream;  // keys, in the order the task sees its inputs
  std::string key_text;               // exactly what was hashed into key
};

// Builds the spec and its key. Throws InvalidInput for parameters with no canonical spelling.
TaskSpec make_task_spec(std::string kind, std::string version, nlohmann::json params,
                        std::vector<std::string> upstream);

// The parameters' canonical JSON inside a key text make_task_spec wrote (the store reads a
// task's parameters from there: they are what its key was hashed from).
std::string_view key_text_params(std::string_view key_text);

// One finished upstream task as its downstream task sees it.
struct TaskInput {
  std::string key;
  std::string kind;
  nlohmann::json result;
  std::map<std::string, std::filesystem::path> artifacts;  // name -> verified file in the store
};

// A child task declared by a result: the DAG grows below the task that declared it. The parent
// is the child's first upstream task, followed by `extra_upstream`.
struct ChildTask {
  std::string kind;
  nlohmann::json params;
  std::vector<std::string> extra_upstream;
};

struct ProducedArtifact {
  std::string name;            // unique within the task, e.g. "trajectory.vtk"
  std::filesystem::path file;  // written by the task (usually inside its work directory)
};

struct TaskOutcome {
  bool interrupted = false;  // stopped at a checkpoint on request; runs again on resume
  nlohmann::json result = nlohmann::json::object();
  std::vector<ProducedArtifact> artifacts;
  std::vector<ChildTask> children;

  static TaskOutcome stopped() {
    TaskOutcome outcome;
    outcome.interrupted = true;
    return outcome;
  }
  static TaskOutcome with_result(nlohmann::json result) {
    TaskOutcome outcome;
    outcome.result = std::move(result);
    return outcome;
  }
};

// What a running task gets. Thread-safe to use from the task's own threads.
// A task's log line starting with this is a warning: the coordinator logs it at warn level, which
// is also printed on the terminal, without the marker.
inline constexpr std::string_view kTaskWarning = "warning: ";

struct TaskContext {
  std::string key;
  const nlohmann::json& params;
  const std::vector<TaskInput>& inputs;  // in the order of TaskSpec::upstream
  // Private to the task and kept across attempts (checkpoints). The engine does not create it
  // (most tasks never write a file): create_directories(work_dir) before writing into it.
  std::filesystem::path work_dir;
  int threads = 1;       // size of the task's own arena
  int attempt = 1;       // 1 for the first attempt ever, counted in the store
  std::stop_token stop;  // poll at checkpoints; return TaskOutcome::stopped()
  std::function<void(double fraction, std::string_view message)> progress;
  std::function<void(std::string_view message)> log;  // goes to the store and the campaign log
};

using RunFunction = std::function<TaskOutcome(TaskContext&)>;

// A task of the DAG as a cost model sees it: its spec, and its result once it is known.
struct KnownTask {
  const TaskSpec* spec = nullptr;
  const nlohmann::json* result = nullptr;  // null until the task finished (or was read)
};
// The tasks of the DAG by key (a KnownTask with a null spec for an unknown key).
using TaskLookup = std::function<KnownTask(const std::string& key)>;
// What a task is expected to cost, in CPU-seconds of one core, from its own spec and the tasks
// above it; none when the model cannot tell. The engine uses it for the ETA (engine/progress.hpp).
using CostModel = std::function<std::optional<double>(const TaskSpec&, const TaskLookup&)>;

struct TaskKind {
  std::string name;
  std::string version;
  RunFunction run;          // throws on failure
  bool may_expand = false;  // its result may declare child tasks (dry runs show them as pending)
  CostModel cost = {};      // may be empty: the ETA then uses the kind's finished task times
};

// Kinds by name. The engine registers its test kinds; tasks/ registers the method's kinds.
class KindRegistry {
 public:
  void add(TaskKind kind);  // throws std::logic_error for a duplicate name
  const TaskKind& get(const std::string& name) const;  // throws InvalidInput for an unknown name
  // Gives a registered kind its cost model; throws std::logic_error for an unknown name.
  void set_cost_model(const std::string& name, CostModel cost);
  bool contains(const std::string& name) const { return kinds_.count(name) > 0; }
  std::string names() const;  // "a, b, c"

 private:
  std::map<std::string, TaskKind> kinds_;
};

// The initial DAG of a campaign, built by a planner: tasks in an order where upstream comes first.
class Plan {
 public:
  explicit Plan(const KindRegistry& kinds) : kinds_(&kinds) {}

  // Adds a task (or finds the identical one) and returns its key.
  const std::string& add(const std::string& kind, nlohmann::json params,
                         std::vector<std::string> upstream = {});

  const std::vector<TaskSpec>& tasks() const { return tasks_; }
  const KindRegistry& kinds() const { return *kinds_; }

 private:
  const KindRegistry* kinds_;
  std::vector<TaskSpec> tasks_;
  std::map<std::string, std::size_t> index_;
};

}  // namespace millflow::engine
