// The Slurm executor against a fake cluster (FakeSlurm): the sbatch text of a job array, how
// Slurm states map to outcomes, re-attaching on resume (also to jobs whose id a dying coordinator
// never recorded), squeue failures ridden out or stopping the coordinator, rejected outputs,
// retries after TIMEOUT and resubmission after a checkpoint. The fake runs each array element in
// this process exactly as a job would (execute_attempt on its spec file); a real Slurm is
// tests/slurm/.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <utility>

#include "engine/attempt_files.hpp"
#include "engine/slurm_executor.hpp"
#include "engine/store.hpp"
#include "support_engine.hpp"

namespace millflow::engine::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const Registry& registry() {
  static const Registry instance = testing_registry();
  return instance;
}

// Thrown by the fake cluster to kill the coordinator at a chosen point: not a std::exception, so
// nothing on the way catches it, as nothing runs after a SIGKILL.
struct CoordinatorKilled {};

// A cluster that runs a pending element when squeue is asked about it: `fate` runs it (or not)
// and returns the state Slurm then reports. `hold` keeps every element pending.
class FakeSlurm final : public SlurmCommands {
 public:
  struct Array {
    std::vector<std::string> options;
    fs::path script;
  };
  using Fate = std::function<std::string(const fs::path& spec_file)>;
  enum class Kill { never, before_sbatch, after_sbatch };
  static constexpr const char* kSqueueError =
      "squeue failed (exit 1): slurm_load_jobs error: Unable to contact slurm controller";

  std::string sbatch(const std::vector<std::string>& options, const fs::path& script) override {
    if (refuse)
      throw std::runtime_error("Batch job submission failed: Invalid partition name specified");
    if (kill == Kill::before_sbatch) {
      kill = Kill::never;
      throw CoordinatorKilled{};  // sbatch never reached the controller
    }
    arrays.push_back({options, script});
    const std::string id = std::to_string(100 + arrays.size() - 1);
    for (int i = 0; i < elements_of(options); ++i) states[id + "_" + std::to_string(i)] = "PENDING";
    if (std::exchange(kill, Kill::never) == Kill::after_sbatch)
      throw CoordinatorKilled{};  // the id is lost
    return id;
  }

  std::map<std::string, std::string> squeue(const std::vector<std::string>& job_ids) override {
    ++squeue_calls;
    if (squeue_failures > 0) {
      --squeue_failures;
      throw std::runtime_error(kSqueueError);
    }
    if (!hold) run_pending();
    return states_where([&](const std::string& array) {
      return std::find(job_ids.begin(), job_ids.end(), array) != job_ids.end();
    });
  }

  std::map<std::string, std::string> squeue_named(const std::string& job_name) override {
    ++squeue_calls;
    return states_where([&](const std::string& array) {
      const auto& options = arrays.at(std::stoul(array) - 100).options;
      return std::find(options.begin(), options.end(), "--job-name=" + job_name) != options.end();
    });
  }

  std::map<std::string, std::string> states_where(
      const std::function<bool(const std::string& array)>& wanted) const {
    std::map<std::string, std::string> known;
    for (const auto& [element, state] : states) {
      if (wanted(element.substr(0, element.find('_')))) known[element] = state;
    }
    return known;
  }

  void run_pending() {
    for (auto& [element, state] : states) {
      if (state != "PENDING") continue;
      const size_t array = std::stoul(element.substr(0, element.find('_'))) - 100;
      state = fate(arrays.at(array).script.parent_path() /
                   (element.substr(element.find('_') + 1) + ".json"));
    }
  }

  static int elements_of(const std::vector<std::string>& options) {
    for (const auto& option : options) {
      if (option.rfind("--array=0-", 0) == 0) return std::stoi(option.substr(10)) + 1;
    }
    return 0;
  }

  // Runs the attempt as `millflow exec` would; Slurm reports COMPLETED for exit 0, else FAILED.
  static std::string run_job(const fs::path& spec_file, bool checkpoint_signal = false) {
    std::ostringstream log;
    const int code = execute_attempt(
        registry().kinds, spec_file, [=] { return checkpoint_signal; }, log);
    return code == kExecDone ? "COMPLETED" : "FAILED";
  }

  Fate fate = [](const fs::path& spec_file) { return run_job(spec_file); };
  std::vector<Array> arrays;
  std::map<std::string, std::string> states;
  bool hold = false;
  bool refuse = false;
  Kill kill = Kill::never;  // at the next sbatch
  int squeue_failures = 0;  // the next squeue calls that fail
  int squeue_calls = 0;
};

SlurmSettings settings_for(const ScratchDir& dir) {
  SlurmSettings settings;
  settings.run_dir = dir.path() / "run";
  settings.program = "/opt/millflow/bin/millflow";
  settings.poll_interval_s = 0.0;
  return settings;
}

RunSummary run_on(
    FakeSlurm& cluster, const ScratchDir& dir, const Campaign& campaign, int retries = 0,
    std::function<bool()> stop = [] { return false; }, int max_squeue_failures = 30) {
  SlurmSettings settings = settings_for(dir);
  settings.max_squeue_failures = max_squeue_failures;
  SlurmExecutor executor(settings, cluster);
  SubmitOptions options;
  options.run.retries = retries;
  options.run.refresh_s = 0.002;
  options.run.stop_requested = std::move(stop);
  options.jobs = &executor;
  return submit_campaign(registry(), campaign, dir.db(), options);
}

std::string read_file(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<std::string> column(const fs::path& db, const std::string& sql) {
  auto connection = open_read_only(db);
  auto rows = connection.prepare(sql);
  std::vector<std::string> values;
  while (rows.step()) values.push_back(rows.text(0));
  return values;
}

json chain_of_sums() {
  return json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}, {"artifact", true}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}}}},
       {{"id", "c"},
        {"kind", "sum"},
        {"params", {{"value", 4}, {"artifact", true}}},
        {"after", {"a", "b"}}},
       {{"id", "f"},
        {"kind", "fanout"},
        {"params", {{"children", 2}, {"value", 8}}},
        {"after", {"c"}}}});
}

TEST(SlurmExecutor, SubmitsReadyAttemptsAsOneThrottledArray) {
  ScratchDir dir;
  FakeSlurm cluster;
  SlurmSettings settings = settings_for(dir);
  settings.partition = "short";
  settings.account = "mills";
  settings.time_limit = "90";
  settings.memory = "4G";
  settings.cpus_per_task = 4;
  settings.extra_args = {"--qos=low"};
  settings.max_in_flight = 2;
  settings.checkpoint_signal_s = 120;
  SlurmExecutor executor(settings, cluster);
  const std::vector<TaskSpec> specs = {make_task_spec("sum", "1", {{"value", 1}}, {}),
                                       make_task_spec("sum", "1", {{"value", 2}}, {}),
                                       make_task_spec("sum", "1", {{"value", 3}}, {})};
  const auto no_inputs = std::make_shared<const std::vector<TaskInput>>();
  std::vector<JobRecord> recorded_before_sbatch;
  const auto jobs = executor.submit(
      {{&specs[0], no_inputs, 1}, {&specs[1], no_inputs, 1}, {&specs[2], no_inputs, 2}},
      [&](const std::vector<JobRecord>& recorded) {
        EXPECT_TRUE(cluster.arrays.empty());
        recorded_before_sbatch = recorded;
      });

  ASSERT_EQ(cluster.arrays.size(), 1u);
  const fs::path batch = cluster.arrays[0].script.parent_path();
  EXPECT_EQ(batch.parent_path(), settings.run_dir / "batches");
  const std::string name = "millflow-" + batch.filename().string();
  const std::vector<std::string> expected = {"--parsable",
                                             "--array=0-2%2",
                                             "--job-name=" + name,
                                             "--output=" + (batch / "%a.out").string(),
                                             "--error=" + (batch / "%a.err").string(),
                                             "--chdir=" + settings.run_dir.string(),
                                             "--signal=B:USR1@120",
                                             "--cpus-per-task=4",
                                             "--partition=short",
                                             "--account=mills",
                                             "--time=90",
                                             "--mem=4G",
                                             "--qos=low"};
  EXPECT_EQ(cluster.arrays[0].options, expected);
  EXPECT_NE(read_file(cluster.arrays[0].script)
                .find("exec '/opt/millflow/bin/millflow' exec '" + batch.string() +
                      "'/\"${SLURM_ARRAY_TASK_ID}.json\""),
            std::string::npos);

  ASSERT_EQ(jobs.size(), 3u);
  ASSERT_EQ(recorded_before_sbatch.size(), 3u);
  for (size_t i = 0; i < jobs.size(); ++i) {
    EXPECT_EQ(recorded_before_sbatch[i].job_id, "");
    EXPECT_EQ(recorded_before_sbatch[i].state, "SUBMITTING");
    EXPECT_EQ(recorded_before_sbatch[i].job_name, name);
    EXPECT_EQ(recorded_before_sbatch[i].output_dir, jobs[i].output_dir);
    EXPECT_EQ(jobs[i].job_id, "100_" + std::to_string(i));
    EXPECT_EQ(jobs[i].state, "PENDING");
    EXPECT_EQ(jobs[i].job_name, name);
    EXPECT_EQ(jobs[i].task_key, specs[i].key);
    EXPECT_EQ(jobs[i].stdout_file, batch / (std::to_string(i) + ".out"));
    const AttemptSpec spec = read_attempt_spec(batch / (std::to_string(i) + ".json"));
    EXPECT_EQ(spec.task.key, specs[i].key);
    EXPECT_EQ(spec.threads, 4);
    EXPECT_EQ(spec.work_dir, settings.run_dir / "work" / specs[i].key);
    EXPECT_EQ(spec.output_dir, batch / std::to_string(i));
  }
  EXPECT_EQ(jobs[2].attempt, 2);
}

TEST(SlurmExecutor, KindsWithResourcesOfTheirOwnGoOutAsArraysOfTheirOwn) {
  ScratchDir dir;
  FakeSlurm cluster;
  SlurmSettings settings = settings_for(dir);
  settings.time_limit = "30";
  settings.memory = "2G";
  settings.cpus_per_task = 1;
  settings.per_kind["fail"] = {.time_limit = "1-00:00:00", .memory = "64G", .cpus_per_task = 16};
  settings.per_kind["fanout"] = {.time_limit = "", .memory = "8G", .cpus_per_task = 0};
  SlurmExecutor executor(settings, cluster);
  const std::vector<TaskSpec> specs = {make_task_spec("sum", "1", {{"value", 1}}, {}),
                                       make_task_spec("fail", "1", {{"failures", 0}}, {}),
                                       make_task_spec("sum", "1", {{"value", 2}}, {}),
                                       make_task_spec("fanout", "1", {{"value", 3}}, {})};
  const auto no_inputs = std::make_shared<const std::vector<TaskInput>>();
  const auto jobs = executor.submit({{&specs[0], no_inputs, 1},
                                     {&specs[1], no_inputs, 1},
                                     {&specs[2], no_inputs, 1},
                                     {&specs[3], no_inputs, 1}},
                                    [](const std::vector<JobRecord>&) {});
  ASSERT_EQ(cluster.arrays.size(), 3u);  // the sums together, then fail, then fanout
  auto option = [&](std::size_t array, const std::string& flag) {
    for (const auto& o : cluster.arrays[array].options) {
      if (o.rfind(flag, 0) == 0) return o.substr(flag.size());
    }
    return std::string("(none)");
  };
  const std::vector<std::vector<std::string>> expected = {
      {"0-1%2", "30", "2G", "1"}, {"0-0%1", "1-00:00:00", "64G", "16"}, {"0-0%1", "30", "8G", "1"}};
  for (std::size_t a = 0; a < 3; ++a) {
    EXPECT_EQ((std::vector<std::string>{option(a, "--array="), option(a, "--time="),
                                        option(a, "--mem="), option(a, "--cpus-per-task=")}),
              expected[a])
        << a;
  }
  ASSERT_EQ(jobs.size(), 4u);
  const std::vector<std::string> keys = {jobs[0].task_key, jobs[1].task_key, jobs[2].task_key,
                                         jobs[3].task_key};
  EXPECT_EQ(keys,
            (std::vector<std::string>{specs[0].key, specs[2].key, specs[1].key, specs[3].key}));
  const fs::path fail_batch = cluster.arrays[1].script.parent_path();
  EXPECT_EQ(read_attempt_spec(fail_batch / "0.json").threads, 16);  // the kind's CPUs
}

TEST(SlurmExecutor, ActiveStatesKeepWaitingEndedOnesSettle) {
  for (const char* state : {"PENDING", "RUNNING", "COMPLETING", "SUSPENDED", "REQUEUED"}) {
    EXPECT_TRUE(slurm_state_is_active(state)) << state;
  }
  for (const char* state :
       {"COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED"}) {
    EXPECT_FALSE(slurm_state_is_active(state)) << state;
  }
}

TEST(SlurmExecutor, EndedOrVanishedJobsWithoutMarkerFailAfterAGracePoll) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.hold = true;
  SlurmExecutor executor(settings_for(dir), cluster);
  const std::vector<TaskSpec> specs = {make_task_spec("sum", "1", {{"value", 1}}, {}),
                                       make_task_spec("sum", "1", {{"value", 2}}, {})};
  const auto no_inputs = std::make_shared<const std::vector<TaskInput>>();
  executor.submit({{&specs[0], no_inputs, 1}, {&specs[1], no_inputs, 1}},
                  [](const std::vector<JobRecord>&) {});
  EXPECT_TRUE(executor.poll().finished.empty());
  cluster.states["100_0"] = "NODE_FAIL";
  cluster.states.erase("100_1");
  const auto first = executor.poll();
  EXPECT_TRUE(first.finished.empty());
  ASSERT_EQ(first.changed.size(), 2u);
  EXPECT_EQ(first.changed[0].state, "NODE_FAIL");
  EXPECT_EQ(first.changed[1].state, "VANISHED");
  const auto second = executor.poll();
  ASSERT_EQ(second.finished.size(), 2u);
  EXPECT_NE(second.finished[0].error->find("100_0 ended NODE_FAIL without a completion marker"),
            std::string::npos);
  EXPECT_NE(second.finished[1].error->find("100_1 vanished from squeue"), std::string::npos);
}

TEST(SlurmExecutor, CampaignResultsEqualTheLocalExecutors) {
  ScratchDir local;
  ASSERT_EQ(submit(test_campaign("chain", chain_of_sums()), local.db()).exit_code(), 0);
  ScratchDir dir;
  FakeSlurm cluster;
  const auto summary = run_on(cluster, dir, test_campaign("chain", chain_of_sums()));
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(summary.done, 6);
  const std::string results =
      "SELECT task_key || ' ' || result FROM task_results ORDER BY task_key";
  EXPECT_EQ(column(dir.db(), results), column(local.db(), results));
  const std::string artifacts =
      "SELECT task_key || ' ' || name || ' ' || sha256 FROM artifacts ORDER BY task_key";
  EXPECT_EQ(column(dir.db(), artifacts), column(local.db(), artifacts));
  EXPECT_EQ(column(dir.db(), "SELECT DISTINCT state FROM jobs"),
            std::vector<std::string>{"COMPLETED"});
  // Ready tasks go out together: {a, b}, then c, then f, then f's two children.
  EXPECT_EQ(cluster.arrays.size(), 4u);
}

TEST(SlurmExecutor, ResumeReattachesToRecordedJobsInsteadOfSubmittingAgain) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.hold = true;
  const auto first = run_on(cluster, dir, test_campaign("chain", chain_of_sums()), 0,
                            [&] { return !cluster.arrays.empty(); });
  EXPECT_EQ(first.exit_code(), 130);
  EXPECT_EQ(first.detached, 2);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'running'"), 2);
  // While no coordinator runs, a finishes and b's job is forgotten by squeue after writing its
  // marker.
  cluster.run_pending();
  cluster.states.erase("100_1");
  cluster.hold = false;

  const auto second = run_on(cluster, dir, test_campaign("chain", chain_of_sums()));
  EXPECT_EQ(second.exit_code(), 0);
  EXPECT_EQ(second.done, 6);
  EXPECT_EQ(cluster.arrays.size(), 4u);  // {a, b} once, then c, f and f's children
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM jobs"), 6);
  EXPECT_EQ(count(dir.db(), "SELECT max(attempts) FROM tasks"), 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM log_lines WHERE message LIKE 'attempt%failed%'"),
            0);
}

// The window between sbatch accepting an array and the coordinator recording its id: the jobs
// were recorded SUBMITTING under their job name first, so resume finds a by name in squeue and b
// (run and forgotten by squeue meanwhile) by its completion marker, and submits neither again.
TEST(SlurmExecutor, CoordinatorKilledBeforeRecordingTheArrayIdSubmitsNothingTwice) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.kill = FakeSlurm::Kill::after_sbatch;
  EXPECT_THROW(run_on(cluster, dir, test_campaign("chain", chain_of_sums())), CoordinatorKilled);
  ASSERT_EQ(cluster.arrays.size(), 1u);
  const std::string name = "millflow-" + cluster.arrays[0].script.parent_path().filename().string();
  EXPECT_EQ(column(dir.db(), "SELECT job_id || '/' || state || '/' || job_name FROM jobs"),
            (std::vector<std::string>{"/SUBMITTING/" + name, "/SUBMITTING/" + name}));
  cluster.run_pending();
  cluster.states.erase("100_1");

  const auto resumed = run_on(cluster, dir, test_campaign("chain", chain_of_sums()));
  EXPECT_EQ(resumed.exit_code(), 0);
  EXPECT_EQ(resumed.done, 6);
  EXPECT_EQ(cluster.arrays.size(),
            4u);  // {a, b} once, then c, f and f's children, as without the kill
  EXPECT_EQ(count(dir.db(), "SELECT max(attempts) FROM tasks"), 1);
  EXPECT_EQ(column(dir.db(), "SELECT job_id || ' ' || state FROM jobs WHERE job_name = '" + name +
                                 "' ORDER BY job_id"),
            (std::vector<std::string>{" COMPLETED", "100_0 COMPLETED"}));
}

// Killed while sbatch was still talking to the controller: Slurm has no such job and there is no
// marker, so the attempt never ran and goes out again, once.
TEST(SlurmExecutor, CoordinatorKilledBeforeSlurmGotTheArraySubmitsItAgain) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.kill = FakeSlurm::Kill::before_sbatch;
  EXPECT_THROW(
      run_on(cluster, dir, test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}}))),
      CoordinatorKilled);
  EXPECT_TRUE(cluster.arrays.empty());
  const auto resumed =
      run_on(cluster, dir, test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})));
  EXPECT_EQ(resumed.exit_code(), 0);
  EXPECT_EQ(cluster.arrays.size(), 1u);
  EXPECT_EQ(column(dir.db(), "SELECT state FROM jobs ORDER BY attempt"),
            (std::vector<std::string>{"NOT_SUBMITTED", "COMPLETED"}));
  const auto warnings = column(dir.db(), "SELECT message FROM log_lines WHERE level = 'warn'");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0],
            "attempt 1 was being submitted when its coordinator stopped, and slurm knows no job " +
                column(dir.db(), "SELECT job_name FROM jobs WHERE attempt = 1")[0] +
                " and it left no output: submitting it again");
}

TEST(SlurmExecutor, FailedSqueueCallsAreLoggedAndPolledAgain) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.squeue_failures = 2;
  const auto summary = run_on(
      cluster, dir, test_campaign("chain", chain_of_sums()), 0, [] { return false; }, 3);
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(summary.done, 6);
  EXPECT_EQ(cluster.arrays.size(), 4u);
  const auto warnings =
      column(dir.db(), "SELECT message FROM log_lines WHERE level = 'warn' ORDER BY id");
  const std::string reason = FakeSlurm::kSqueueError;
  EXPECT_EQ(
      warnings,
      (std::vector<std::string>{
          "squeue failed (1 of 3 failures in a row before the coordinator stops), polling again: " +
              reason,
          "squeue failed (2 of 3 failures in a row before the coordinator stops), polling again: " +
              reason}));
}

TEST(SlurmExecutor, SqueueFailingTooOftenInARowStopsTheCoordinatorAndResumeReattaches) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.squeue_failures = 3;
  const auto stopped = run_on(
      cluster, dir, test_campaign("chain", chain_of_sums()), 0, [] { return false; }, 3);
  EXPECT_EQ(stopped.exit_code(), 130);
  EXPECT_EQ(stopped.detached, 2);
  const std::string reason =
      "squeue failed 3 times in a row (executor.slurm.max_squeue_failures), last: " +
      std::string(FakeSlurm::kSqueueError) +
      ": the coordinator stops; its jobs keep running and `millflow resume` re-attaches to them";
  EXPECT_EQ(stopped.stop_reason, reason);
  EXPECT_NE(stopped.describe().find("; stopped: " + reason), std::string::npos);
  EXPECT_EQ(column(dir.db(), "SELECT message FROM log_lines WHERE level = 'error'"),
            std::vector<std::string>{reason});
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM campaigns WHERE outcome = 'interrupted'"), 1);

  const auto resumed = run_on(cluster, dir, test_campaign("chain", chain_of_sums()));
  EXPECT_EQ(resumed.exit_code(), 0);
  EXPECT_EQ(resumed.done, 6);
  EXPECT_EQ(cluster.arrays.size(), 4u);
  EXPECT_EQ(count(dir.db(), "SELECT max(attempts) FROM tasks"), 1);
}

TEST(SlurmExecutor, OutputNotMatchingItsMarkerIsAFailedAttempt) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.fate = [](const fs::path& spec_file) {
    const std::string state = FakeSlurm::run_job(spec_file);
    std::ofstream(read_attempt_spec(spec_file).output_dir / "result.json", std::ios::app) << ' ';
    return state;
  };
  const auto summary =
      run_on(cluster, dir, test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})));
  EXPECT_EQ(summary.failed, 1);
  const auto errors = column(dir.db(), "SELECT error FROM tasks");
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("result.json does not match the SHA-256 of its completion marker"),
            std::string::npos);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM results"), 0);
}

TEST(SlurmExecutor, JobKilledByTimeoutIsRetried) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.fate = [](const fs::path& spec_file) {
    return read_attempt_spec(spec_file).attempt == 1 ? std::string("TIMEOUT")
                                                     : FakeSlurm::run_job(spec_file);
  };
  const auto summary =
      run_on(cluster, dir,
             test_campaign(
                 "one", json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 7}}}}})),
             1);
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(column(dir.db(), "SELECT result FROM results"),
            std::vector<std::string>{R"({"sum":7})"});
  EXPECT_EQ(column(dir.db(), "SELECT state FROM jobs ORDER BY attempt"),
            (std::vector<std::string>{"TIMEOUT", "COMPLETED"}));
  EXPECT_EQ(count(dir.db(),
                  "SELECT count(*) FROM status_history WHERE status = 'failed' AND message LIKE "
                  "'%ended TIMEOUT%'"),
            1);
}

TEST(SlurmExecutor, CheckpointedJobIsSubmittedAgainAndNotCountedAsFailure) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.fate = [](const fs::path& spec_file) {
    return FakeSlurm::run_job(spec_file, read_attempt_spec(spec_file).attempt == 1);
  };
  const auto summary =
      run_on(cluster, dir,
             test_campaign(
                 "one", json::array({{{"id", "s"}, {"kind", "sleep"}, {"params", {{"ms", 20}}}}})));
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(column(dir.db(), "SELECT state FROM jobs ORDER BY attempt"),
            (std::vector<std::string>{"STOPPED", "COMPLETED"}));
  EXPECT_EQ(column(dir.db(), "SELECT status FROM status_history ORDER BY id"),
            (std::vector<std::string>{"running", "interrupted", "running", "done"}));
}

TEST(SlurmExecutor, RefusedSubmissionFailsTheAttempts) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.refuse = true;
  const auto summary =
      run_on(cluster, dir, test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})));
  EXPECT_EQ(summary.failed, 1);
  EXPECT_NE(column(dir.db(), "SELECT error FROM tasks")[0].find("Invalid partition name"),
            std::string::npos);
}

}  // namespace
}  // namespace millflow::engine::testing
