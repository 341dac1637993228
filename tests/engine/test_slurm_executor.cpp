// The Slurm executor against a fake cluster (FakeSlurm): the sbatch text of a job array, how
// Slurm states map to outcomes, re-attaching on resume, rejected outputs, retries after TIMEOUT
// and resubmission after a checkpoint. The fake runs each array element in this process exactly
// as a job would (execute_attempt on its spec file); a real Slurm is tests/slurm/.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

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

// A cluster that runs a pending element when squeue is asked about it: `fate` runs it (or not)
// and returns the state Slurm then reports. `hold` keeps every element pending.
class FakeSlurm final : public SlurmCommands {
 public:
  struct Array {
    std::vector<std::string> options;
    fs::path script;
  };
  using Fate = std::function<std::string(const fs::path& spec_file)>;

  std::string sbatch(const std::vector<std::string>& options, const fs::path& script) override {
    if (refuse) throw std::runtime_error("Batch job submission failed: Invalid partition name specified");
    arrays.push_back({options, script});
    const std::string id = std::to_string(100 + arrays.size() - 1);
    for (int i = 0; i < elements_of(options); ++i) states[id + "_" + std::to_string(i)] = "PENDING";
    return id;
  }

  std::map<std::string, std::string> squeue(const std::vector<std::string>& job_ids) override {
    ++squeue_calls;
    if (!hold) run_pending();
    std::map<std::string, std::string> known;
    for (const auto& [element, state] : states) {
      const std::string array = element.substr(0, element.find('_'));
      if (std::find(job_ids.begin(), job_ids.end(), array) != job_ids.end()) known[element] = state;
    }
    return known;
  }

  void run_pending() {
    for (auto& [element, state] : states) {
      if (state != "PENDING") continue;
      const size_t array = std::stoul(element.substr(0, element.find('_'))) - 100;
      state = fate(arrays.at(array).script.parent_path() / (element.substr(element.find('_') + 1) + ".json"));
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
    const int code = execute_attempt(registry().kinds, spec_file, [=] { return checkpoint_signal; }, log);
    return code == kExecDone ? "COMPLETED" : "FAILED";
  }

  Fate fate = [](const fs::path& spec_file) { return run_job(spec_file); };
  std::vector<Array> arrays;
  std::map<std::string, std::string> states;
  bool hold = false;
  bool refuse = false;
  int squeue_calls = 0;
};

SlurmSettings settings_for(const ScratchDir& dir) {
  SlurmSettings settings;
  settings.run_dir = dir.path() / "run";
  settings.program = "/opt/millflow/bin/millflow";
  settings.poll_interval_s = 0.0;
  return settings;
}

RunSummary run_on(FakeSlurm& cluster, const ScratchDir& dir, const Campaign& campaign, int retries = 0,
                  std::function<bool()> stop = [] { return false; }) {
  SlurmExecutor executor(settings_for(dir), cluster);
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
  return json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}, {"artifact", true}}}},
                      {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}}}},
                      {{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 4}, {"artifact", true}}}, {"after", {"a", "b"}}},
                      {{"id", "f"}, {"kind", "fanout"}, {"params", {{"children", 2}, {"value", 8}}}, {"after", {"c"}}}});
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
  const auto jobs = executor.submit({{&specs[0], no_inputs, 1}, {&specs[1], no_inputs, 1}, {&specs[2], no_inputs, 2}});

  ASSERT_EQ(cluster.arrays.size(), 1u);
  const fs::path batch = cluster.arrays[0].script.parent_path();
  EXPECT_EQ(batch.parent_path(), settings.run_dir / "batches");
  const std::vector<std::string> expected = {
      "--parsable", "--array=0-2%2", "--job-name=millflow", "--output=" + (batch / "%a.out").string(),
      "--error=" + (batch / "%a.err").string(), "--chdir=" + settings.run_dir.string(), "--signal=B:USR1@120",
      "--cpus-per-task=4", "--partition=short", "--account=mills", "--time=90", "--mem=4G", "--qos=low"};
  EXPECT_EQ(cluster.arrays[0].options, expected);
  EXPECT_NE(read_file(cluster.arrays[0].script)
                .find("exec '/opt/millflow/bin/millflow' exec '" + batch.string() + "'/\"${SLURM_ARRAY_TASK_ID}.json\""),
            std::string::npos);

  ASSERT_EQ(jobs.size(), 3u);
  for (size_t i = 0; i < jobs.size(); ++i) {
    EXPECT_EQ(jobs[i].job_id, "100_" + std::to_string(i));
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

TEST(SlurmExecutor, ActiveStatesKeepWaitingEndedOnesSettle) {
  for (const char* state : {"PENDING", "RUNNING", "COMPLETING", "SUSPENDED", "REQUEUED"}) {
    EXPECT_TRUE(slurm_state_is_active(state)) << state;
  }
  for (const char* state : {"COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED"}) {
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
  executor.submit({{&specs[0], no_inputs, 1}, {&specs[1], no_inputs, 1}});
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
  EXPECT_NE(second.finished[0].error->find("100_0 ended NODE_FAIL without a completion marker"), std::string::npos);
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
  const std::string results = "SELECT task_key || ' ' || result FROM task_results ORDER BY task_key";
  EXPECT_EQ(column(dir.db(), results), column(local.db(), results));
  const std::string artifacts = "SELECT task_key || ' ' || name || ' ' || sha256 FROM artifacts ORDER BY task_key";
  EXPECT_EQ(column(dir.db(), artifacts), column(local.db(), artifacts));
  EXPECT_EQ(column(dir.db(), "SELECT DISTINCT state FROM jobs"), std::vector<std::string>{"COMPLETED"});
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
  // While no coordinator runs, a finishes and b's job is forgotten by squeue after writing its marker.
  cluster.run_pending();
  cluster.states.erase("100_1");
  cluster.hold = false;

  const auto second = run_on(cluster, dir, test_campaign("chain", chain_of_sums()));
  EXPECT_EQ(second.exit_code(), 0);
  EXPECT_EQ(second.done, 6);
  EXPECT_EQ(cluster.arrays.size(), 4u);  // {a, b} once, then c, f and f's children
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM jobs"), 6);
  EXPECT_EQ(count(dir.db(), "SELECT max(attempts) FROM tasks"), 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM log_lines WHERE message LIKE 'attempt%failed%'"), 0);
}

TEST(SlurmExecutor, OutputNotMatchingItsMarkerIsAFailedAttempt) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.fate = [](const fs::path& spec_file) {
    const std::string state = FakeSlurm::run_job(spec_file);
    std::ofstream(read_attempt_spec(spec_file).output_dir / "result.json", std::ios::app) << ' ';
    return state;
  };
  const auto summary = run_on(cluster, dir, test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})));
  EXPECT_EQ(summary.failed, 1);
  const auto errors = column(dir.db(), "SELECT error FROM tasks");
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("result.json does not match the SHA-256 of its completion marker"), std::string::npos);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM results"), 0);
}

TEST(SlurmExecutor, JobKilledByTimeoutIsRetried) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.fate = [](const fs::path& spec_file) {
    return read_attempt_spec(spec_file).attempt == 1 ? std::string("TIMEOUT") : FakeSlurm::run_job(spec_file);
  };
  const auto summary = run_on(cluster, dir, test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 7}}}}})), 1);
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(column(dir.db(), "SELECT result FROM results"), std::vector<std::string>{R"({"sum":7})"});
  EXPECT_EQ(column(dir.db(), "SELECT state FROM jobs ORDER BY attempt"), (std::vector<std::string>{"TIMEOUT", "COMPLETED"}));
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM status_history WHERE status = 'failed' AND message LIKE '%ended TIMEOUT%'"), 1);
}

TEST(SlurmExecutor, CheckpointedJobIsSubmittedAgainAndNotCountedAsFailure) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.fate = [](const fs::path& spec_file) {
    return FakeSlurm::run_job(spec_file, read_attempt_spec(spec_file).attempt == 1);
  };
  const auto summary = run_on(cluster, dir, test_campaign("one", json::array({{{"id", "s"}, {"kind", "sleep"}, {"params", {{"ms", 20}}}}})));
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(column(dir.db(), "SELECT state FROM jobs ORDER BY attempt"), (std::vector<std::string>{"STOPPED", "COMPLETED"}));
  EXPECT_EQ(column(dir.db(), "SELECT status FROM status_history ORDER BY id"),
            (std::vector<std::string>{"running", "interrupted", "running", "done"}));
}

TEST(SlurmExecutor, RefusedSubmissionFailsTheAttempts) {
  ScratchDir dir;
  FakeSlurm cluster;
  cluster.refuse = true;
  const auto summary = run_on(cluster, dir, test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})));
  EXPECT_EQ(summary.failed, 1);
  EXPECT_NE(column(dir.db(), "SELECT error FROM tasks")[0].find("Invalid partition name"), std::string::npos);
}

}  // namespace
}  // namespace millflow::engine::testing
