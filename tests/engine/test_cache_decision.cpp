// The one cache decision (engine/cache.hpp) as the runtime, the dry run and `explain` see it:
// they agree task by task; the dry run's words per kind; --force by kind and by key; --until.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "engine/cache.hpp"
#include "engine/inspect.hpp"
#include "engine/store.hpp"
#include "support_engine.hpp"

namespace millflow::engine::testing {
namespace {

using nlohmann::json;

// noted_diamond, and f (fails its first attempt) beside it.
json tasks(int c_value) {
  json tasks = noted_diamond(c_value);
  tasks.push_back({{"id", "f"}, {"kind", "fail"}, {"params", {{"failures", 1}}}});
  return tasks;
}

std::map<std::string, std::int64_t> launches_by_key(const std::filesystem::path& db) {
  auto connection = open_read_only(db);
  auto rows = connection.prepare(
      "SELECT task_key, count(*) FROM status_history WHERE status = 'running' GROUP BY task_key");
  std::map<std::string, std::int64_t> launches;
  while (rows.step()) launches[rows.text(0)] = rows.integer(1);
  return launches;
}

// What `explain KEY` prints after the hashed text.
std::string explained_reason(const std::filesystem::path& db, const TaskSpec& spec) {
  std::ostringstream out;
  print_explain(db, spec.key, out);
  const std::string header =
      "task " + spec.key + "\nhashed text (SHA-256 of exactly these bytes):\n" + spec.key_text;
  EXPECT_EQ(out.str().substr(0, header.size()), header);
  return out.str().substr(header.size());
}

std::string joined_lines(const CacheDecision& decision) {
  std::string text;
  for (const auto& line : decision.lines()) text += line + "\n";
  return text;
}

class CacheDecisions : public ::testing::Test {
 protected:
  // First run: everything done but f (failed). Then a's artifact is corrupted and c changed.
  void SetUp() override {
    submit(test_campaign("cache", tasks(3)), dir_.db());
    auto connection = open_read_only(dir_.db());
    auto row = connection.prepare("SELECT task_key FROM artifacts");
    ASSERT_TRUE(row.step());
    const auto artifact = find_artifacts(connection, row.text(0)).at(0);
    std::ofstream(artifacts_dir(dir_.db()) / artifact.sha256.substr(0, 2) / artifact.sha256)
        << "9\n";
  }

  ScratchDir dir_;
  Registry registry_ = testing_registry();
  Campaign changed_ = test_campaign("cache", tasks(30));
};

TEST_F(CacheDecisions, TheRuntimeTheDryRunAndExplainAgreeTaskByTask) {
  RunOptions force_b;
  force_b.force.key_prefixes = {plan_campaign(registry_, changed_).at(1).key.substr(0, 10)};
  const DryRun dry = dry_run(registry_, changed_, dir_.db(), force_b);
  std::map<std::string, RunReason> reasons;
  for (const auto& task : dry.tasks)
    reasons[task.spec.kind + std::to_string(task.spec.params.value("value", -1))] =
        task.decision.reason;
  EXPECT_EQ(reasons, (std::map<std::string, RunReason>{{"sum1", RunReason::artifact_bad},
                                                       {"sum2", RunReason::forced},
                                                       {"sum30", RunReason::parameters_changed},
                                                       {"sum4", RunReason::upstream_changed},
                                                       {"fail-1", RunReason::not_finished}}));

  // explain says what the dry run says: by key for stored tasks (without --force), and for every
  // task of the campaign file.
  const DryRun unforced = dry_run(registry_, changed_, dir_.db());
  std::string listed;
  for (const auto& task : unforced.tasks) {
    EXPECT_EQ(unforced.explain(task.spec.key.substr(0, 12)),
              explain_text(task.spec, task.decision));
    listed += task.spec.kind + " " + task.spec.key + ": " + joined_lines(task.decision);
    auto connection = open_read_only(dir_.db());
    if (find_task(connection, task.spec.key)) {
      EXPECT_EQ(explained_reason(dir_.db(), task.spec), joined_lines(task.decision));
    }
  }
  EXPECT_EQ(unforced.list(), listed);

  // The runtime runs exactly the tasks the dry run said would run.
  const auto before = launches_by_key(dir_.db());
  SubmitOptions options;
  options.run = force_b;
  const RunSummary summary = submit_campaign(registry_, changed_, dir_.db(), options);
  const auto after = launches_by_key(dir_.db());
  std::set<std::string> ran;
  for (const auto& [key, launches] : after) {
    if (launches > (before.count(key) ? before.at(key) : 0)) ran.insert(key);
  }
  std::set<std::string> would_run;
  for (const auto& task : dry.tasks) {
    if (!task.decision.cached()) would_run.insert(task.spec.key);
  }
  EXPECT_EQ(ran, would_run);
  EXPECT_EQ(summary.done, 5);
  EXPECT_EQ(summary.cached, 0);
  // Afterwards everything is cached, as all three say.
  for (const auto& task : dry_run(registry_, changed_, dir_.db()).tasks)
    EXPECT_EQ(explained_reason(dir_.db(), task.spec), joined_lines(task.decision));
  EXPECT_EQ(submit(changed_, dir_.db()).cached, 5);
}

TEST_F(CacheDecisions, DryRunSaysPerKindWhatWouldRunAndWhy) {
  const auto planned = plan_campaign(registry_, changed_);
  const std::string a = planned.at(0).key;
  const std::string f = planned.at(4).key;
  auto connection = open_read_only(dir_.db());
  const auto artifact = find_artifacts(connection, a).at(0);
  EXPECT_EQ(dry_run(registry_, changed_, dir_.db()).describe(),
            "dry run of \"cache\": 5 tasks, 1 cached, 4 would run\n"
            "sum: 3 of 4 would run\n"
            "  1 artifact missing or corrupt\n"
            "    " +
                a.substr(0, 12) + ": sum.txt (" + artifact.sha256 +
                ")\n"
                "  1 parameters changed\n"
                "    /value: 3 -> 30\n"
                "  1 upstream changed\n"
                "fail: 1 of 1 would run\n"
                "  1 not finished\n"
                "    " +
                f.substr(0, 12) +
                ": the previous attempt failed: planned failure: attempt 1 of a task that fails "
                "its first 1\n");
  EXPECT_EQ(dry_run(registry_, changed_, dir_.path() / "none.db").describe(),
            "dry run of \"cache\": 5 tasks, 0 cached, 5 would run\n"
            "sum: 4 of 4 would run\n"
            "  4 new\n"
            "fail: 1 of 1 would run\n"
            "  1 new\n");
  EXPECT_FALSE(std::filesystem::exists(dir_.path() / "none.db"));
}

TEST_F(CacheDecisions, ForceByKindRunsEveryTaskOfThatKindAgainAndNothingBelowIt) {
  const auto original = test_campaign("cache", tasks(3));
  submit(original, dir_.db());  // repairs a, finishes f
  SubmitOptions options;
  options.run.force.kinds = {"sum"};
  const auto forced = submit_campaign(registry_, original, dir_.db(), options);
  EXPECT_EQ(forced.done, 4);
  EXPECT_EQ(forced.cached, 1);
  EXPECT_EQ(submit(original, dir_.db()).cached, 5);
}

TEST(CacheUntil, RunsOnlyTheKindAndWhatItNeedsThenResumeRunsTheRest) {
  ScratchDir dir;
  // a -> s (steps) -> c, and x beside them; fanout may declare steps tasks, so it runs too.
  const auto campaign = test_campaign(
      "until",
      json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}},
                   {{"id", "s"}, {"kind", "steps"}, {"params", {{"steps", 2}}}, {"after", {"a"}}},
                   {{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 2}}}, {"after", {"s"}}},
                   {{"id", "x"}, {"kind", "sleep"}, {"params", {{"ms", 0}}}},
                   {{"id", "e"}, {"kind", "fanout"}, {"params", {{"children", 1}}}}}));
  const Registry registry = testing_registry();
  RunOptions until;
  until.until = "steps";
  const DryRun dry = dry_run(registry, campaign, dir.db(), until);
  std::set<std::string> held;
  for (const auto& task : dry.tasks) {
    if (task.held) held.insert(task.spec.kind + std::to_string(task.spec.params.value("value", 0)));
  }
  EXPECT_EQ(held, (std::set<std::string>{"sum2", "sleep0"}));
  EXPECT_EQ(dry.describe(),
            "dry run of \"until\": 5 tasks, 0 cached, 3 would run, 2 held back by --until; 1 of "
            "them may declare more tasks when it finishes\n"
            "sum: 1 of 2 would run, 1 held back by --until\n"
            "  1 new\n"
            "steps: 1 of 1 would run\n"
            "  1 new\n"
            "sleep: 0 of 1 would run, 1 held back by --until\n"
            "fanout: 1 of 1 would run\n"
            "  1 new\n");

  SubmitOptions options;
  options.run = until;
  const auto partial = submit_campaign(registry, campaign, dir.db(), options);
  EXPECT_EQ(partial.done, 3);
  EXPECT_EQ(partial.held_back, 3);  // c and x, and the fanout's child (a sum task)
  EXPECT_EQ(partial.exit_code(), 0);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM campaigns WHERE outcome = 'partial'"), 1);
  const auto rest = submit(campaign, dir.db());
  EXPECT_EQ(rest.cached, 3);
  EXPECT_EQ(rest.done, 3);
}

// A dry run carries the stored result of a cached task where a task that would run, of a kind
// with a cost model, takes it as an input (a cell's sites): the cost of what would run is priced
// from it. No other result is read.
TEST(CacheDryRun, CarriesTheStoredResultsThatAPricedTaskWouldRead) {
  ScratchDir dir;
  const auto campaign = [](int value) {
    return test_campaign(
        "priced",
        json::array(
            {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}},
             {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", value}}}, {"after", {"a"}}},
             {{"id", "x"}, {"kind", "sum"}, {"params", {{"value", 5}}}}}));
  };
  submit(campaign(2), dir.db());
  Registry registry = testing_registry();
  // Per task, by its value: its key and the result the dry run carries.
  const auto results = [&](const Registry& with) {
    std::map<int, std::pair<std::string, std::optional<json>>> by_value;
    for (const auto& task : dry_run(with, campaign(3), dir.db()).tasks)
      by_value[task.spec.params.at("value").get<int>()] = {task.spec.key, task.result};
    return by_value;
  };
  // Without a cost model nothing is read.
  for (const auto& [value, task] : results(registry)) EXPECT_FALSE(task.second) << value;
  registry.kinds.set_cost_model(
      "sum", [](const TaskSpec&, const TaskLookup&) { return std::optional<double>(1.0); });
  const auto priced = results(registry);
  ASSERT_EQ(priced.size(), 3u);
  ASSERT_TRUE(priced.at(1).second);  // a: cached, and b, which would run, reads it
  EXPECT_EQ(*priced.at(1).second, result_of(dir.db(), priced.at(1).first));
  EXPECT_FALSE(priced.at(3).second);  // b would run: no result yet
  EXPECT_FALSE(priced.at(5).second);  // x: cached, but nothing that would run reads it
}
}  // namespace
}  // namespace millflow::engine::testing
