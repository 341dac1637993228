#include "engine/slurm_executor.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <set>

#include "engine/artifacts.hpp"
#include "engine/attempt_files.hpp"
#include "util/durable_file.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

std::string shell_quoted(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// "1234_5" -> "1234": squeue lists every element of an array asked for by its base id.
std::string array_id_of(const std::string& job_id) {
  return job_id.substr(0, job_id.find('_'));
}

std::string state_from_marker(const AttemptOutcome& outcome) {
  if (outcome.error) return "FAILED";
  return outcome.outcome.interrupted ? "STOPPED" : "COMPLETED";
}

}  // namespace

bool slurm_state_is_active(const std::string& state) {
  static const std::set<std::string> kActive = {
      "PENDING",   "CONFIGURING", "RUNNING",      "COMPLETING", "SUSPENDED",
      "REQUEUED",  "REQUEUE_FED", "REQUEUE_HOLD", "RESIZING",   "SIGNALING",
      "STAGE_OUT", "STOPPED",     "RESV_DEL_HOLD"};
  return kActive.count(state) > 0;
}

SlurmExecutor::SlurmExecutor(SlurmSettings settings, SlurmCommands& commands)
    : settings_(std::move(settings)), commands_(commands) {
  settings_.max_in_flight = std::max(1, settings_.max_in_flight);
}

SlurmResources SlurmExecutor::resources_of(const std::string& kind) const {
  SlurmResources resources{settings_.time_limit, settings_.memory, settings_.cpus_per_task};
  const auto own = settings_.per_kind.find(kind);
  if (own == settings_.per_kind.end()) return resources;
  if (!own->second.time_limit.empty()) resources.time_limit = own->second.time_limit;
  if (!own->second.memory.empty()) resources.memory = own->second.memory;
  if (own->second.cpus_per_task > 0) resources.cpus_per_task = own->second.cpus_per_task;
  return resources;
}

std::vector<std::string> SlurmExecutor::sbatch_options(int count, const fs::path& batch_dir,
                                                       const std::string& kind) const {
  const SlurmResources resources = resources_of(kind);
  const int throttle = std::min(count, settings_.max_in_flight);
  std::vector<std::string> options = {
      "--parsable",
      fmt::format("--array=0-{}%{}", count - 1, throttle),
      "--job-name=" + job_name_of(batch_dir),
      "--output=" + (batch_dir / "%a.out").string(),
      "--error=" + (batch_dir / "%a.err").string(),
      "--chdir=" + settings_.run_dir.string(),
      fmt::format("--signal=B:USR1@{}", settings_.checkpoint_signal_s),
      fmt::format("--cpus-per-task={}", resources.cpus_per_task),
  };
  const std::pair<const char*, const std::string*> optional[] = {
      {"--partition=", &settings_.partition},
      {"--account=", &settings_.account},
      {"--time=", &resources.time_limit},
      {"--mem=", &resources.memory}};
  for (const auto& [flag, value] : optional) {
    if (!value->empty()) options.push_back(flag + *value);
  }
  options.insert(options.end(), settings_.extra_args.begin(), settings_.extra_args.end());
  return options;
}

std::string SlurmExecutor::job_name_of(const fs::path& batch_dir) {
  return "millflow-" + batch_dir.filename().string();
}

fs::path SlurmExecutor::new_batch_dir() {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
  const fs::path dir =
      settings_.run_dir / "batches" / fmt::format("{}-{}-{}", ms, ::getpid(), batches_++);
  fs::create_directories(dir);
  return dir;
}

std::vector<TaskInput> SlurmExecutor::staged(const std::vector<TaskInput>& inputs) const {
  const ArtifactStore stage(settings_.run_dir / "inputs");
  std::vector<TaskInput> copies = inputs;
  for (auto& input : copies) {
    for (auto& [name, file] : input.artifacts) file = stage.path_of(stage.put(name, file).sha256);
  }
  return copies;
}

void SlurmExecutor::write_batch_script(const fs::path& batch_dir) const {
  util::write_file_durably(
      batch_dir / "job.sh",
      "#!/bin/sh\n"
      "# millflow: array element i runs the task attempt of <i>.json; it never opens the "
      "database.\n"
      "exec " +
          shell_quoted(settings_.program.string()) + " exec " + shell_quoted(batch_dir.string()) +
          "/\"${SLURM_ARRAY_TASK_ID}.json\"\n");
}

std::vector<JobRecord> SlurmExecutor::submit(const std::vector<AttemptOrder>& attempts,
                                             const RecordJobs& record_before_sending) {
  // One array per kind with resources of its own (an array's elements share them), in the
  // order the kinds first appear; the other kinds together.
  std::vector<std::string> groups;
  std::map<std::string, std::vector<AttemptOrder>> by_group;
  for (const AttemptOrder& order : attempts) {
    const std::string group = settings_.per_kind.count(order.spec->kind) ? order.spec->kind : "";
    if (!by_group.count(group)) groups.push_back(group);
    by_group[group].push_back(order);
  }
  std::vector<JobRecord> jobs;
  for (const std::string& group : groups) {
    const auto submitted = submit_array(by_group[group], group, record_before_sending);
    jobs.insert(jobs.end(), submitted.begin(), submitted.end());
  }
  return jobs;
}

std::vector<JobRecord> SlurmExecutor::submit_array(const std::vector<AttemptOrder>& attempts,
                                                   const std::string& kind,
                                                   const RecordJobs& record_before_sending) {
  if (attempts.empty()) return {};
  const int threads = resources_of(kind).cpus_per_task;
  std::vector<JobRecord> jobs;
  try {
    const fs::path batch = new_batch_dir();
    for (size_t i = 0; i < attempts.size(); ++i) {
      const TaskSpec& task = *attempts[i].spec;
      const std::string element = std::to_string(i);
      const AttemptSpec spec{task,    staged(*attempts[i].inputs), attempts[i].attempt,
                             threads, work_root() / task.key,      batch / element};
      write_attempt_spec(spec, batch / (element + ".json"));
      jobs.push_back(JobRecord{task.key, spec.attempt, "slurm", "", "SUBMITTING",
                               job_name_of(batch), spec.output_dir, batch / (element + ".out"),
                               batch / (element + ".err")});
    }
    write_batch_script(batch);
    record_before_sending(jobs);
    const std::string array_id = commands_.sbatch(
        sbatch_options(static_cast<int>(attempts.size()), batch, kind), batch / "job.sh");
    for (size_t i = 0; i < jobs.size(); ++i) {
      jobs[i].job_id = array_id + "_" + std::to_string(i);
      jobs[i].state = "PENDING";
      track(jobs[i]);
    }
  } catch (const std::exception& error) {
    for (auto& job : jobs) {
      job.state = "NOT_SUBMITTED";
      refused_.changed.push_back(job);
    }
    for (const auto& order : attempts) {
      refused_.finished.push_back(
          AttemptOutcome{order.spec->key,
                         order.attempt,
                         std::string("could not submit the Slurm job: ") + error.what(),
                         {},
                         0.0});
    }
    return {};
  }
  return jobs;
}

void SlurmExecutor::track(const JobRecord& job) {
  tracked_[job.output_dir] = Tracked{job, std::chrono::steady_clock::now(), 0};
}

std::string SlurmExecutor::find_id_by_name(const JobRecord& job) {
  auto found = squeue_by_name_.find(job.job_name);
  if (found == squeue_by_name_.end())
    found = squeue_by_name_.emplace(job.job_name, commands_.squeue_named(job.job_name)).first;
  const std::string element =
      "_" + job.output_dir.filename().string();  // output dirs are <batch>/<element>
  for (const auto& [id, state] : found->second) {
    if (id.size() > element.size() &&
        id.compare(id.size() - element.size(), element.size(), element) == 0)
      return id;
  }
  return {};
}

std::optional<JobRecord> SlurmExecutor::reattach(const JobRecord& recorded) {
  JobRecord job = recorded;
  if (job.job_id.empty()) {
    job.job_id = find_id_by_name(job);
    // Without an id or a marker Slurm never got the job (or forgot it before anything was written).
    if (job.job_id.empty() && !fs::exists(job.output_dir / "complete.json")) return std::nullopt;
  }
  track(job);
  return job;
}

std::optional<AttemptOutcome> SlurmExecutor::settle(Tracked& tracked,
                                                    const std::string& state) const {
  JobRecord& job = tracked.job;
  if (auto outcome = read_attempt_outcome(job.output_dir, job.task_key, job.attempt)) {
    job.state = state_from_marker(*outcome);  // says more than FAILED for a checkpointed job
    return outcome;
  }
  // A marker written just before the job ended may reach a shared filesystem late: wait one poll.
  if (++tracked.polls_without_marker_after_end < 2) return std::nullopt;
  const std::string how = state == "VANISHED" ? "vanished from squeue" : "ended " + state;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - tracked.since).count();
  return AttemptOutcome{job.task_key,
                        job.attempt,
                        fmt::format("Slurm job {} {} without a completion marker (its stderr: {})",
                                    job.job_id, how, job.stderr_file.string()),
                        {},
                        seconds};
}

std::optional<std::map<std::string, std::string>> SlurmExecutor::squeue_tracked(Poll& result) {
  std::set<std::string> arrays;
  for (const auto& [dir, tracked] : tracked_) {
    if (!tracked.job.job_id.empty()) arrays.insert(array_id_of(tracked.job.job_id));
  }
  try {
    auto states = commands_.squeue({arrays.begin(), arrays.end()});
    squeue_failures_ = 0;
    return states;
  } catch (const std::exception& error) {
    ++squeue_failures_;
    if (squeue_failures_ >= settings_.max_squeue_failures) {
      result.unreachable = fmt::format(
          "squeue failed {} times in a row (executor.slurm.max_squeue_failures), last: {}",
          squeue_failures_, error.what());
    } else {
      result.warnings.push_back(
          fmt::format("squeue failed ({} of {} failures in a row before the coordinator stops), "
                      "polling again: {}",
                      squeue_failures_, settings_.max_squeue_failures, error.what()));
    }
    return std::nullopt;
  }
}

JobExecutor::Poll SlurmExecutor::poll() {
  Poll result = std::move(refused_);
  refused_ = {};
  for (auto it = tracked_.begin(); it != tracked_.end();) {
    JobRecord& job = it->second.job;
    if (auto outcome = read_attempt_outcome(job.output_dir, job.task_key, job.attempt)) {
      job.state = state_from_marker(*outcome);
      result.changed.push_back(job);
      result.finished.push_back(std::move(*outcome));
      it = tracked_.erase(it);
    } else {
      ++it;
    }
  }
  if (tracked_.empty()) return result;
  const auto states = squeue_tracked(result);
  if (!states) return result;
  for (auto it = tracked_.begin(); it != tracked_.end();) {
    JobRecord& job = it->second.job;
    const auto found = states->find(job.job_id);
    const std::string state = found == states->end() ? "VANISHED" : found->second;
    const std::string before = job.state;
    job.state = state;
    std::optional<AttemptOutcome> outcome;
    if (!slurm_state_is_active(state)) outcome = settle(it->second, state);
    if (job.state != before) result.changed.push_back(job);
    if (outcome) {
      result.finished.push_back(std::move(*outcome));
      it = tracked_.erase(it);
    } else {
      ++it;
    }
  }
  return result;
}

}  // namespace millflow::engine
