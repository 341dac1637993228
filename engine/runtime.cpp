#include "engine/runtime.hpp"

#include <fmt/format.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <stop_token>
#include <unordered_map>

#include "engine/cache.hpp"
#include "engine/canonical_json.hpp"
#include "engine/validation.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

enum class State { pending, running, done, cached, failed, skipped, interrupted };

struct Node {
  TaskSpec spec;
  State state = State::pending;
  int waiting_on = 0;  // upstream tasks not done yet
  std::vector<std::string> downstream;
  int attempts_this_run = 0;
  bool held = false;                                     // beyond --until: stays pending
  std::optional<nlohmann::json> result;                  // loaded when a downstream task needs it
  std::optional<std::vector<StoredArtifact>> artifacts;  // likewise
  bool skipped_its_work = false;  // done or cached, and its result says so (RunSummary)
  std::optional<double> cost_s;   // its kind's cost model (engine/task.hpp), for the ETA
};

// What a worker reports back to the coordinating thread.
struct Event {
  enum class Type { finished, log } type = Type::finished;
  std::string key;
  int attempt = 0;
  std::optional<std::string> error;  // set when the attempt threw
  TaskOutcome outcome;
  std::vector<StoredArtifact> stored;
  std::vector<TaskSpec> children;
  double duration_s = 0.0;
  std::string message;  // log line

  static Event log_line(const std::string& key, std::string_view message) {
    Event event;
    event.type = Type::log;
    event.key = key;
    event.message = message;
    return event;
  }
  static Event finished(const std::string& key, int attempt) {
    Event event;
    event.key = key;
    event.attempt = attempt;
    return event;
  }
};

class EventQueue {
 public:
  void push(Event event) {
    std::lock_guard lock(mutex_);
    events_.push_back(std::move(event));
    ready_.notify_one();  // under the lock: the coordinator may return as soon as it sees the event
  }
  std::optional<Event> pop_for(double seconds) {
    std::unique_lock lock(mutex_);
    if (!ready_.wait_for(lock, std::chrono::duration<double>(seconds),
                         [&] { return !events_.empty(); })) {
      return std::nullopt;
    }
    Event event = std::move(events_.front());
    events_.pop_front();
    return event;
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<Event> events_;
};

// Progress reported by running tasks, read by the coordinator for the status line.
class ProgressBoard {
 public:
  void start(const std::string& key, const std::string& kind) {
    std::lock_guard lock(mutex_);
    running_[key] = RunningTask{key, kind, 0.0, {}};
  }
  void update(const std::string& key, double fraction, std::string_view message) {
    std::lock_guard lock(mutex_);
    auto found = running_.find(key);
    if (found == running_.end()) return;
    found->second.fraction = fraction;
    found->second.message = message;
  }
  void finish(const std::string& key) {
    std::lock_guard lock(mutex_);
    running_.erase(key);
  }
  std::vector<RunningTask> running() const {
    std::lock_guard lock(mutex_);
    std::vector<RunningTask> tasks;
    for (const auto& [key, task] : running_) tasks.push_back(task);
    return tasks;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::string, RunningTask> running_;
};

// Arenas of threads_per_task slots, reused from task to task (creating one per task costs more
// than a trivial task). An arena serves one task at a time, so nested parallelism stays inside
// its task and a waiting thread never picks up another task's work.
class ArenaPool {
 public:
  explicit ArenaPool(int threads) : threads_(threads) {}

  void execute(const std::function<void()>& body) {
    Lease lease(*this);
    lease.arena->execute(body);
  }

 private:
  struct Lease {
    explicit Lease(ArenaPool& pool) : pool(pool), arena(pool.take()) {}
    ~Lease() { pool.give_back(std::move(arena)); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ArenaPool& pool;
    std::unique_ptr<tbb::task_arena> arena;
  };

  std::unique_ptr<tbb::task_arena> take() {
    std::lock_guard lock(mutex_);
    if (free_.empty()) return std::make_unique<tbb::task_arena>(threads_);
    auto arena = std::move(free_.back());
    free_.pop_back();
    return arena;
  }
  void give_back(std::unique_ptr<tbb::task_arena> arena) {
    std::lock_guard lock(mutex_);
    free_.push_back(std::move(arena));
  }

  int threads_;
  std::mutex mutex_;
  std::vector<std::unique_ptr<tbb::task_arena>> free_;
};

// A result the store cannot hold (NaN or infinity: a simulation that diverged) fails its attempt,
// with the reason in the task's log; it must not reach the commit and stop the coordinator.
void require_storable(const nlohmann::json& result) {
  try {
    canonical_json(result);
  } catch (const InvalidInput& error) {
    const ValidationError& first = error.errors().front();
    throw std::runtime_error(fmt::format(
        "its result cannot be stored: {}: {} (a value that is not finite usually means the "
        "simulation diverged: check the task's parameters, e.g. a stiffness or time step)",
        first.path, first.problem));
  }
}

class Coordinator {
 public:
  Coordinator(RunEnvironment environment, std::int64_t campaign, const RunOptions& options)
      : env_(std::move(environment)),
        campaign_(campaign),
        options_(options),
        artifacts_(artifacts_dir(env_.store.path()), env_.files),
        judge_(artifacts_, options.force),
        work_root_(env_.jobs ? env_.jobs->work_root() : work_dir(env_.store.path())),
        arenas_(options.threads_per_task),
        started_(env_.clock.now()) {}
  // Launched tasks hold `this`: whatever ends the run early (the store unable to commit on a full
  // disk, a failing progress view), they are asked to stop and waited for before it goes. It was
  // destroyed under them: a crash.
  ~Coordinator() {
    stop_.request_stop();
    env_.launcher.wait_idle();
  }
  Coordinator(const Coordinator&) = delete;
  Coordinator& operator=(const Coordinator&) = delete;

  RunSummary run(const std::vector<TaskSpec>& planned) {
    stored_ = find_campaign_tasks(env_.store.connection(), campaign_);
    for (const auto& spec : planned) admit(spec);
    env_.store.add_members(campaign_, adopted_);
    adopted_.clear();
    stored_ = {};
    if (!options_.until.empty()) hold_beyond_until();
    remove_work_dirs_of_cached_tasks();
    loop();
    env_.launcher.wait_idle();
    return summarize();
  }

 private:
  // --- building the graph -------------------------------------------------------------------
  void admit(const TaskSpec& spec) {
    if (nodes_.count(spec.key) > 0) return;
    for (const auto& upstream : spec.upstream) admit_stored(upstream);
    Node& node = nodes_[spec.key];
    node.spec = spec;
    node.cost_s = estimate_cost(node.spec);
    bool upstream_failed = false;
    for (const auto& upstream : spec.upstream) {
      Node& parent = nodes_.at(upstream);
      parent.downstream.push_back(spec.key);
      if (parent.state == State::failed || parent.state == State::skipped) upstream_failed = true;
      if (parent.state != State::done && parent.state != State::cached) ++node.waiting_on;
    }
    decide(node);
    if (holding_ && node.spec.kind != options_.until && !may_expand(node.spec.kind)) {
      node.held = true;  // declared after the start: below a task that ran, beyond --until
    }
    if (node.state == State::pending && upstream_failed) {
      node.state = State::skipped;
      env_.store.mark_skipped({spec.key}, "an upstream task failed");
    } else if (node.state == State::pending && node.waiting_on == 0 && !reattach(node)) {
      ready_.push_back(spec.key);
    }
  }

  // A task left running by an earlier coordinator whose batch job was recorded: followed again
  // instead of being submitted twice (its job may still be queued, running or finished). A job
  // recorded while being submitted is looked up first; one the scheduler never got goes out again.
  bool reattach(Node& node) {
    if (!env_.jobs) return false;
    const auto stored = stored_task(node.spec.key);
    if (!stored || stored->status != TaskStatus::running) return false;
    const auto record = find_task(env_.store.connection(), node.spec.key);
    auto jobs = find_jobs(env_.store.connection(), node.spec.key);
    if (!record || jobs.empty() || jobs.back().attempt != record->attempts) return false;
    JobRecord& recorded = jobs.back();
    const auto followed = env_.jobs->reattach(recorded);
    if (!followed) {
      recorded.state = "NOT_SUBMITTED";
      env_.store.record_jobs({recorded});
      log(node.spec.key, "warn",
          fmt::format(
              "attempt {} was being submitted when its coordinator stopped, and {} knows no job {} "
              "and it left no output: submitting it again",
              record->attempts, recorded.executor, recorded.job_name));
      return false;
    }
    if (followed->job_id != recorded.job_id) env_.store.record_jobs({*followed});
    node.state = State::running;
    ++node.attempts_this_run;
    ++running_;
    board_.start(node.spec.key, node.spec.kind);
    report(node.spec.key,
           fmt::format("re-attached to job {} (attempt {})",
                       followed->job_id.empty() ? followed->job_name : followed->job_id,
                       record->attempts));
    return true;
  }

  void admit_stored(const std::string& key) {
    if (nodes_.count(key) > 0) return;
    auto record = find_task(env_.store.connection(), key);
    if (!record) throw std::logic_error("task " + key + " is referenced but not in the store");
    adopted_.push_back(key);
    admit(record->spec);
  }

  // The cache decision (engine/cache.hpp): a cached task is reused and its stored children
  // (declared by its result) join the graph; a done task that is not intact goes back to pending.
  void decide(Node& node) {
    const std::string key = node.spec.key;
    const auto stored = stored_task(key);
    const CacheDecision decision = judge_.decide(node.spec, stored);
    if (decision.cached()) {
      node.state = State::cached;
      node.skipped_its_work = stored->skipped_its_work;
      for (const auto& child : stored->children) admit_stored(child);
      return;
    }
    if (decision.reason == RunReason::forced) {
      log(key, "info", "runs again: --force names it");
    } else if (stored && stored->status == TaskStatus::done) {
      const std::string reason = decision.summary() + ": " + decision.detail;
      env_.store.mark_pending(key, reason);
      log(key, "warn", reason + "; the task runs again");
    }
  }

  // The task's cost from its kind's model, given what is known of the tasks above it; a model
  // that throws gives none (an estimate must never stop a run).
  std::optional<double> estimate_cost(const TaskSpec& spec) const {
    if (!env_.kinds.contains(spec.kind)) return std::nullopt;
    const CostModel& cost = env_.kinds.get(spec.kind).cost;
    if (!cost) return std::nullopt;
    const TaskLookup lookup = [this](const std::string& key) {
      const auto found = nodes_.find(key);
      if (found == nodes_.end()) return KnownTask{};
      const Node& node = found->second;
      return KnownTask{&node.spec, node.result ? &*node.result : nullptr};
    };
    try {
      return cost(spec, lookup);
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }

  std::optional<StoredTask> stored_task(const std::string& key) {
    if (auto found = stored_.find(key); found != stored_.end()) return found->second;
    return find_stored_task(env_.store.connection(), key);
  }

  bool may_expand(const std::string& kind) const {
    return env_.kinds.contains(kind) && env_.kinds.get(kind).may_expand;
  }

  // --until KIND: only tasks of KIND and the tasks they need run; the others stay pending.
  void hold_beyond_until() {
    std::vector<const TaskSpec*> graph;
    for (const auto& [key, node] : nodes_) graph.push_back(&node.spec);
    for (const auto& key : beyond_until(graph, env_.kinds, options_.until))
      nodes_.at(key).held = true;
    holding_ = true;
  }

  // --- the loop --------------------------------------------------------------------------
  void loop() {
    double last_refresh = 0.0;
    double last_poll = 0.0;
    std::optional<Event> event;
    while (true) {
      if (!stopping_ && options_.stop_requested()) {
        stopping_ = true;
        stop_.request_stop();
        log(std::nullopt, "warn",
            env_.jobs
                ? "stop requested: no new jobs; running jobs are left to `millflow resume`"
                : "stop requested: no new tasks; running tasks stop at their next checkpoint");
      }
      start(record_turn(event));
      event.reset();
      if ((running_ == 0 || (stopping_ && env_.jobs)) && (ready_.empty() || stopping_)) break;
      if (env_.jobs && env_.clock.now() - last_poll >= env_.jobs->poll_interval_s()) {
        poll_jobs();
        last_poll = env_.clock.now();
      }
      event = events_.pop_for(options_.refresh_s);
      if (env_.clock.now() - last_refresh >= options_.refresh_s) {
        env_.progress.refresh(snapshot());
        last_refresh = env_.clock.now();
      }
    }
    env_.progress.refresh(snapshot());
    env_.progress.finish();
  }

  bool can_launch() const {
    return !stopping_ && running_ < (env_.jobs ? env_.jobs->max_in_flight() : options_.jobs) &&
           !ready_.empty();
  }

  // One write transaction per turn of the loop: the outcome that just arrived and the launches it
  // made possible. A task is recorded running (its attempt counted) in a committed transaction
  // before it starts, so a task found 'running' after a crash is known to have been interrupted.
  std::vector<AttemptOrder> record_turn(std::optional<Event>& event) {
    if (!event && !can_launch()) return {};
    auto transaction = env_.store.transaction();
    if (event) handle(std::move(*event));
    std::vector<AttemptOrder> launches;
    while (can_launch()) {
      const std::string key = ready_.front();
      ready_.pop_front();
      if (!nodes_.at(key).held) launches.push_back(claim(key));
    }
    transaction.commit();
    remove_finished_work_dirs();
    return launches;
  }

  std::vector<TaskInput> inputs_of(const TaskSpec& spec) {
    std::vector<TaskInput> inputs;
    for (const auto& key : spec.upstream) {
      Node& upstream = nodes_.at(key);
      if (!upstream.result)
        upstream.result =
            find_result(env_.store.connection(), key).value_or(nlohmann::json::object());
      if (!upstream.artifacts) upstream.artifacts = find_artifacts(env_.store.connection(), key);
      TaskInput input{key, upstream.spec.kind, *upstream.result, {}};
      for (const auto& artifact : *upstream.artifacts)
        input.artifacts[artifact.name] = artifacts_.path_of(artifact.sha256);
      inputs.push_back(std::move(input));
    }
    return inputs;
  }

  AttemptOrder claim(const std::string& key) {
    Node& node = nodes_.at(key);
    node.state = State::running;
    ++node.attempts_this_run;
    ++running_;
    const int attempt = env_.store.mark_running(key);
    board_.start(key, node.spec.kind);
    env_.progress.task_event(node.spec.kind, key, fmt::format("started (attempt {})", attempt));
    return AttemptOrder{
        &node.spec, std::make_shared<const std::vector<TaskInput>>(inputs_of(node.spec)), attempt};
  }

  void start(const std::vector<AttemptOrder>& launches) {
    if (!env_.jobs) {
      for (const auto& launch : launches) {
        env_.launcher.launch(
            [this, launch] { attempt_task(*launch.spec, *launch.inputs, launch.attempt); });
      }
      return;
    }
    if (launches.empty()) return;
    const auto submitted = env_.jobs->submit(
        launches, [this](const std::vector<JobRecord>& jobs) { env_.store.record_jobs(jobs); });
    env_.store.record_jobs(submitted);
    for (const auto& job : submitted)
      report(job.task_key, fmt::format("submitted as {} job {}", job.executor, job.job_id));
  }

  // Records the jobs' new states and queues their outcomes as events, as if from a worker.
  void poll_jobs() {
    auto poll = env_.jobs->poll();
    env_.store.record_jobs(poll.changed);
    for (const auto& warning : poll.warnings) log(std::nullopt, "warn", warning);
    if (poll.unreachable && !stopping_) {
      stop_reason_ = *poll.unreachable +
                     ": the coordinator stops; its jobs keep running and `millflow resume` "
                     "re-attaches to them";
      log(std::nullopt, "error", stop_reason_);
      stopping_ = true;
      stop_.request_stop();
    }
    for (auto& finished : poll.finished) {
      Event event = Event::finished(finished.key, finished.attempt);
      event.error = std::move(finished.error);
      event.outcome = std::move(finished.outcome);
      event.duration_s = finished.duration_s;
      if (!event.error && !event.outcome.interrupted) {
        try {
          store_outputs(event.key, event);
        } catch (const std::exception& error) {
          event.error = error.what();
        }
      }
      events_.push(std::move(event));
    }
  }

  // Work directories of tasks committed done: removed after the commit (a power loss may still roll
  // it back, see store.hpp; the task then runs again from the start, which is correct).
  void remove_finished_work_dirs() {
    for (const auto& key : finished_work_) {
      std::error_code ignored;
      fs::remove_all(work_root_ / key, ignored);
    }
    finished_work_.clear();
  }

  // A coordinator killed between a task's commit and the removal of its work directory left the
  // directory behind (a macro run's can hold gigabytes); the task is cached and never runs again,
  // so nothing else would remove it.
  void remove_work_dirs_of_cached_tasks() {
    std::error_code missing;
    for (const auto& entry : fs::directory_iterator(work_root_, missing)) {
      const auto found = nodes_.find(entry.path().filename().string());
      if (found != nodes_.end() && found->second.state == State::cached)
        finished_work_.push_back(found->first);
    }
    remove_finished_work_dirs();
  }

  // Runs on a worker thread: everything it touches is either its own or thread-safe.
  void attempt_task(const TaskSpec& spec, const std::vector<TaskInput>& inputs, int attempt) {
    const double started = env_.clock.now();
    Event event = Event::finished(spec.key, attempt);
    try {
      const TaskKind& kind = env_.kinds.get(spec.kind);
      TaskContext context{
          .key = spec.key,
          .params = spec.params,
          .inputs = inputs,
          .work_dir = work_root_ / spec.key,
          .threads = options_.threads_per_task,
          .attempt = attempt,
          .stop = stop_.get_token(),
          .progress = [this, key = spec.key](
                          double fraction,
                          std::string_view message) { board_.update(key, fraction, message); },
          .log = [this, key = spec.key](
                     std::string_view message) { events_.push(Event::log_line(key, message)); }};
      arenas_.execute([&] { event.outcome = kind.run(context); });
      if (!event.outcome.interrupted) store_outputs(spec.key, event);
    } catch (const std::exception& error) {
      event.error = error.what();
    }
    event.duration_s = env_.clock.now() - started;
    events_.push(std::move(event));
  }

  void store_outputs(const std::string& key, Event& event) const {
    require_storable(event.outcome.result);
    for (const auto& artifact : event.outcome.artifacts)
      event.stored.push_back(artifacts_.put(artifact.name, artifact.file));
    for (auto& child : event.outcome.children) {
      std::vector<std::string> upstream{key};
      upstream.insert(upstream.end(), child.extra_upstream.begin(), child.extra_upstream.end());
      event.children.push_back(make_task_spec(child.kind, env_.kinds.get(child.kind).version,
                                              std::move(child.params), std::move(upstream)));
    }
  }

  // --- outcomes ----------------------------------------------------------------------------
  void handle(Event event) {
    if (event.type == Event::Type::log) {
      // A task marks the lines that matter (e.g. a checkpoint it had to discard) "warning: ":
      // the line's level says so, without the marker (the console would print it twice).
      if (event.message.starts_with(kTaskWarning))
        log(event.key, "warn", event.message.substr(kTaskWarning.size()));
      else
        log(event.key, "info", event.message);
      return;
    }
    --running_;
    board_.finish(event.key);
    ++finished_this_run_;
    if (!event.error && !event.outcome.interrupted) {
      const Node& node = nodes_.at(event.key);
      if (node.cost_s) {
        finished_estimate_s_ += *node.cost_s;
        finished_measured_s_ += event.duration_s;
      } else {
        auto& timing = snapshot_timings_[node.spec.kind];
        timing.first += event.duration_s;
        ++timing.second;
      }
    }
    if (event.error) {
      handle_failure(event);
    } else if (event.outcome.interrupted) {
      handle_interruption(event);
    } else {
      handle_success(event);
    }
  }

  void handle_success(Event& event) {
    Node& node = nodes_.at(event.key);
    env_.store.commit_done(campaign_, event.key, event.outcome.result, event.stored, event.children,
                           event.duration_s);
    node.state = State::done;
    node.result = std::move(event.outcome.result);
    node.skipped_its_work = node.result->is_object() && node.result->contains("skipped");
    node.artifacts = std::move(event.stored);
    ++done_;
    report(event.key, skipped_its_work(node)
                          ? fmt::format("skipped its work in {:.3f} s: {}", event.duration_s,
                                        (*node.result)["skipped"].dump())
                          : fmt::format("done in {:.3f} s", event.duration_s));
    finished_work_.push_back(event.key);
    for (const auto& downstream : node.downstream) {
      Node& below = nodes_.at(downstream);
      if (below.state == State::pending) below.cost_s = estimate_cost(below.spec);  // knows more
      if (--below.waiting_on == 0 && below.state == State::pending) ready_.push_back(downstream);
    }
    for (const auto& child : event.children) admit(child);
  }

  // Without a stop request only a batch job stops early: its scheduler signalled it before the
  // time limit and it checkpointed. It goes out again (not a failed attempt) and continues.
  void handle_interruption(const Event& event) {
    Node& node = nodes_.at(event.key);
    if (!stopping_) {
      env_.store.mark_finished(event.key, TaskStatus::interrupted, event.attempt,
                               "checkpointed before its time limit", event.duration_s);
      node.state = State::pending;
      --node.attempts_this_run;
      ready_.push_back(event.key);
      report(event.key, "checkpointed before its time limit; submitted again to continue");
      return;
    }
    node.state = State::interrupted;
    env_.store.mark_finished(event.key, TaskStatus::interrupted, event.attempt,
                             "stopped on request", event.duration_s);
    report(event.key, "interrupted");
  }

  void handle_failure(const Event& event) {
    Node& node = nodes_.at(event.key);
    env_.store.mark_finished(event.key, TaskStatus::failed, event.attempt, *event.error,
                             event.duration_s);
    log(event.key, "error", fmt::format("attempt {} failed: {}", event.attempt, *event.error));
    if (node.attempts_this_run <= options_.retries && !stopping_) {
      node.state = State::pending;
      ready_.push_back(event.key);
      report(event.key,
             fmt::format("failed (attempt {}), retrying: {}", event.attempt, *event.error));
      return;
    }
    node.state = State::failed;
    ++failed_;
    report(event.key, "failed: " + *event.error);
    skip_descendants(node);
  }

  void skip_descendants(const Node& failed) {
    std::vector<std::string> skipped;
    std::vector<std::string> frontier = failed.downstream;
    while (!frontier.empty()) {
      const std::string key = frontier.back();
      frontier.pop_back();
      Node& node = nodes_.at(key);
      if (node.state != State::pending) continue;
      node.state = State::skipped;
      skipped.push_back(key);
      frontier.insert(frontier.end(), node.downstream.begin(), node.downstream.end());
    }
    env_.store.mark_skipped(
        skipped, fmt::format("upstream task {} ({}) failed", failed.spec.key, failed.spec.kind));
  }

  // --- reporting ---------------------------------------------------------------------------
  void log(const std::optional<std::string>& key, const std::string& level,
           const std::string& message) {
    env_.store.append_log(key, level, message);
    if (!env_.log) return;
    const std::string who =
        key ? nodes_.at(*key).spec.kind + " " + key->substr(0, 12) + ": " : std::string();
    if (level == "error")
      env_.log->error("{}{}", who, message);
    else if (level == "warn")
      env_.log->warn("{}{}", who, message);
    else
      env_.log->info("{}{}", who, message);
  }

  void report(const std::string& key, const std::string& what) {
    const Node& node = nodes_.at(key);
    env_.progress.task_event(node.spec.kind, key, what);
    if (env_.log) env_.log->info("{} {}: {}", node.spec.kind, key.substr(0, 12), what);
  }

  ProgressSnapshot snapshot() const {
    ProgressSnapshot snapshot;
    snapshot.running = board_.running();
    std::unordered_map<std::string, double> running_fraction;
    for (const auto& task : snapshot.running)
      running_fraction[task.key] = std::clamp(task.fraction, 0.0, 1.0);
    int remaining = 0;
    for (const auto& [key, node] : nodes_) {
      auto& counts = snapshot.done_total_by_kind[node.spec.kind];
      ++counts.second;
      if (skipped_its_work(node))
        ++snapshot.skipped_by_kind[node.spec.kind];
      else if (node.state == State::done || node.state == State::cached)
        ++counts.first;
      if (node.state == State::pending || node.state == State::running) {
        ++remaining;
        // The time left counts what runs: not the tasks held beyond --until.
        if (!node.held && node.cost_s) {
          const auto running = running_fraction.find(key);
          snapshot.estimated_left_s +=
              *node.cost_s * (1.0 - (running == running_fraction.end() ? 0.0 : running->second));
          ++snapshot.estimated_tasks_left;
        } else if (!node.held) {
          ++snapshot.remaining_by_kind[node.spec.kind];
        }
      }
      if (node.state == State::skipped) ++snapshot.skipped_by_kind[node.spec.kind];
    }
    snapshot.task_seconds_by_kind = snapshot_timings_;
    snapshot.finished_estimate_s = finished_estimate_s_;
    snapshot.finished_measured_s = finished_measured_s_;
    snapshot.jobs = env_.jobs ? env_.jobs->max_in_flight() : options_.jobs;
    snapshot.threads_per_task = options_.threads_per_task;
    snapshot.elapsed_s = env_.clock.now() - started_;
    snapshot.finished_this_run = finished_this_run_;
    snapshot.remaining = remaining;
    return snapshot;
  }

  // Done (or cached), but its result says it skipped its work (RunSummary).
  static bool skipped_its_work(const Node& node) {
    return (node.state == State::done || node.state == State::cached) && node.skipped_its_work;
  }

  RunSummary summarize() const {
    RunSummary summary;
    summary.total = static_cast<int>(nodes_.size());
    summary.done = done_;
    summary.failed = failed_;
    summary.stopped = stopping_;
    summary.stop_reason = stop_reason_;
    for (const auto& [key, node] : nodes_) {
      if (node.state == State::cached) ++summary.cached;
      if (node.state == State::skipped) ++summary.skipped;
      if (skipped_its_work(node))
        ++(node.state == State::done ? summary.skipped_their_work_done
                                     : summary.skipped_their_work_cached);
      if (node.state == State::interrupted) ++summary.interrupted;
      if (node.state == State::pending) ++(node.held ? summary.held_back : summary.not_started);
      if (node.state == State::running) ++summary.detached;
    }
    return summary;
  }

  RunEnvironment env_;
  std::int64_t campaign_;
  RunOptions options_;
  ArtifactStore artifacts_;
  CacheJudge judge_;
  fs::path work_root_;
  ArenaPool arenas_;
  double started_;
  std::unordered_map<std::string, StoredTask> stored_;  // read at the start, then released
  bool holding_ = false;                                // --until is in force
  std::unordered_map<std::string, Node> nodes_;
  std::vector<std::string> adopted_;  // stored tasks that joined this campaign's graph
  std::deque<std::string> ready_;
  std::vector<std::string> finished_work_;  // done in the open transaction; work dirs go after it
  EventQueue events_;
  ProgressBoard board_;
  std::stop_source stop_;
  bool stopping_ = false;
  std::string stop_reason_;
  int running_ = 0;
  int done_ = 0;
  int failed_ = 0;
  int finished_this_run_ = 0;
  // Per kind: task seconds and count of the attempts without a cost estimate that finished well
  // in this run (the ETA); the estimates and seconds of those with one.
  std::map<std::string, std::pair<double, int>> snapshot_timings_;
  double finished_estimate_s_ = 0.0, finished_measured_s_ = 0.0;
};

}  // namespace

int RunSummary::exit_code() const {
  if (stopped) return 130;
  return failed > 0 ? 1 : 0;
}

std::string RunSummary::describe() const {
  std::string text =
      fmt::format("{} tasks: {} done, {} cached, {} failed, {} skipped", total,
                  done - skipped_their_work_done, cached - skipped_their_work_cached, failed,
                  skipped + skipped_their_work_done + skipped_their_work_cached);
  if (interrupted > 0 || not_started > 0) {
    text += fmt::format(", {} interrupted, {} not started", interrupted, not_started);
  }
  if (held_back > 0) text += fmt::format(", {} held back by --until", held_back);
  if (detached > 0)
    text += fmt::format(", {} left running as batch jobs (resume re-attaches)", detached);
  if (!stop_reason.empty()) text += "; stopped: " + stop_reason;
  return text;
}

RunSummary run_campaign(RunEnvironment environment, std::int64_t campaign,
                        const std::vector<TaskSpec>& planned, const RunOptions& options) {
  Coordinator coordinator(std::move(environment), campaign, options);
  return coordinator.run(planned);
}

}  // namespace millflow::engine
