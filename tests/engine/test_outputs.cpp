// A campaign's outputs outside the store: CSV cells of nested results, the sweep point in every
// exported row, `millflow files` layouts and a task's log lines.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "engine/inspect.hpp"
#include "engine/outputs.hpp"
#include "engine/store.hpp"
#include "engine/validation.hpp"
#include "support_engine.hpp"
#include "util/durable_file.hpp"

namespace millflow::engine::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(CsvColumns, StringsArePlainNestedScalarsGetTheirOwnColumnsArraysStayOneCell) {
  const json result = {{"region", "toe"},
                       {"power", {{"mean_kw", 1.5}, {"steady", true}}},
                       {"angle", nullptr},
                       {"counts", {1, 2}},
                       {"empty", json::object()}};
  EXPECT_EQ(csv_columns(result), (std::map<std::string, std::string>{{"/angle", ""},
                                                                     {"/counts", "[1,2]"},
                                                                     {"/empty", "{}"},
                                                                     {"/power/mean_kw", "1.5"},
                                                                     {"/power/steady", "true"},
                                                                     {"/region", "toe"}}));
  EXPECT_EQ(csv_columns(json("a, b")), (std::map<std::string, std::string>{{"/", "a, b"}}));
}

// The test kinds with a sweep_points view: "value" is the coordinate, "label" a second one that
// only some tasks have.
Registry registry_with_sweep_points() {
  Registry registry = testing_registry();
  registry.views.push_back({kSweepPointsView,
                            "SELECT key AS task_key, json_extract(params, '$.value') AS value, "
                            "json_extract(params, '$.label') AS label FROM tasks"});
  return registry;
}

class Outputs : public ::testing::Test {
 protected:
  void SetUp() override {
    const json tasks = json::array(
        {{{"id", "a"},
          {"kind", "sum"},
          {"params", {{"value", 1}, {"artifact", true}, {"label", "first, \"quoted\""}}}},
         {{"id", "b"},
          {"kind", "sum"},
          {"params", {{"value", 2}, {"artifact", true}}},
          {"after", {"a"}}},
         {{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 3}}}, {"after", {"b"}}}});
    SubmitOptions options;
    submit_campaign(registry_with_sweep_points(), test_campaign("swept", tasks), dir_.db(),
                    options);
  }
  std::string key_of(int value) {
    auto connection = open_read_only(dir_.db());
    auto row =
        connection.prepare("SELECT key FROM tasks WHERE json_extract(params, '$.value') = ?");
    row.bind_all(value);
    EXPECT_TRUE(row.step());
    return row.text(0);
  }
  ScratchDir dir_;
};

TEST_F(Outputs, EveryCsvRowStartsWithItsSweepPoint) {
  const fs::path out = dir_.path() / "export";
  export_campaign(dir_.db(), "swept", TableFormat::csv, out);
  std::map<std::string, std::string> rows;  // sorted by key, as the file is
  rows[key_of(1)] =
      key_of(1) + ",done,1,\"first, \"\"quoted\"\"\",true,\"first, \"\"quoted\"\"\",1,1";
  rows[key_of(2)] = key_of(2) + ",done,2,,true,,2,3";
  rows[key_of(3)] = key_of(3) + ",done,3,,,,3,6";
  std::string expected =
      "task_key,status,value,label,params/artifact,params/label,params/value,result/sum\n";
  for (const auto& [key, row] : rows) expected += row + "\n";
  EXPECT_EQ(read_text(out / "sum.csv"), expected);
}

TEST_F(Outputs, FilesOfATaskGoUnderTheirOwnNames) {
  const fs::path out = dir_.path() / "one";
  const auto written = export_files(dir_.db(), key_of(2).substr(0, 10), out);
  EXPECT_EQ(written, (std::vector<fs::path>{out / "sum.txt"}));
  EXPECT_EQ(read_text(out / "sum.txt"), "3\n");
}

TEST_F(Outputs, FilesOfACampaignGoUnderKindAndSweepPointWithAnIndex) {
  const fs::path out = dir_.path() / "all";
  const auto written = export_files(dir_.db(), "swept", out);
  const std::string a = "value1_label" + std::string("first---quoted-_") + key_of(1).substr(0, 8);
  const std::string b = "value2_" + key_of(2).substr(0, 8);
  EXPECT_EQ(read_text(out / "sum" / a / "sum.txt"), "1\n");
  EXPECT_EQ(read_text(out / "sum" / b / "sum.txt"), "3\n");
  EXPECT_EQ(written.size(), 3u);  // two artifacts and the index; c has no artifact
  std::map<std::string, std::string> rows;
  rows[key_of(1)] = "sum," + key_of(1) + ",sum/" + a + ",1,\"first, \"\"quoted\"\"\"";
  rows[key_of(2)] = "sum," + key_of(2) + ",sum/" + b + ",2,";
  std::string expected = "kind,task_key,folder,value,label\n";
  for (const auto& [key, row] : rows) expected += row + "\n";
  EXPECT_EQ(read_text(out / "tasks.csv"), expected);
}

// The index was written with a plain stream: a kill or a full disk left part of it, and the
// command said it was written.
TEST_F(Outputs, TheIndexOfTheFilesIsWrittenDurably) {
  const util::SimulatedFullDisk full(10);  // room for the two artifacts, not for the index
  EXPECT_THROW(export_files(dir_.db(), "swept", dir_.path() / "all"), std::system_error);
  EXPECT_FALSE(fs::exists(dir_.path() / "all" / "tasks.csv"));
}

TEST_F(Outputs, FilesOfAnUnknownNameIsBadInput) {
  EXPECT_THROW(export_files(dir_.db(), "nope", dir_.path() / "x"), InvalidInput);
}

TEST(SkippedWork, ATaskWhoseResultSaysSkippedIsShownAsSkipped) {
  ScratchDir dir;
  const json tasks = json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}, {"skipped", "no usable site"}}}}});
  const RunSummary summary = submit(test_campaign("skipping", tasks), dir.db());
  EXPECT_EQ(summary.exit_code(), 0);
  EXPECT_EQ(summary.describe(), "2 tasks: 1 done, 0 cached, 0 failed, 1 skipped");
  std::ostringstream status;
  print_status(dir.db(), "skipping", status);
  EXPECT_NE(status.str().find("sum   done     1"), std::string::npos) << status.str();
  EXPECT_NE(status.str().find("sum   skipped  1"), std::string::npos) << status.str();
  std::ostringstream dag;
  print_dag_dot(dir.db(), "skipping", /*every_task=*/true, dag);
  EXPECT_NE(dag.str().find("fillcolor=lightgrey"), std::string::npos) << dag.str();
  EXPECT_NE(dag.str().find("fillcolor=palegreen"), std::string::npos) << dag.str();
}

// Submitted again, every task cached: the one that skipped its work is counted as skipped,
// though nothing that runs reads its result.
TEST(SkippedWork, ACachedTaskThatSkippedItsWorkIsStillCountedAsSkipped) {
  ScratchDir dir;
  const json tasks = json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}, {"skipped", "no usable site"}}}}});
  submit(test_campaign("skipping", tasks), dir.db());
  const RunSummary again = submit(test_campaign("skipping", tasks), dir.db());
  EXPECT_EQ(again.exit_code(), 0);
  EXPECT_EQ(again.describe(), "2 tasks: 0 done, 1 cached, 0 failed, 1 skipped");
}

// Submitted again with one more task: the new one ran and the cached one skipped its work; the
// summary counted the skip against the task that ran ("0 done") until 6 December.
TEST(SkippedWork, ACachedSkipIsNotTakenFromTheTasksThatRan) {
  ScratchDir dir;
  json tasks = json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}, {"skipped", "no usable site"}}}}});
  submit(test_campaign("skipping", tasks), dir.db());
  tasks.push_back({{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 3}}}});
  const RunSummary again = submit(test_campaign("skipping", tasks), dir.db());
  EXPECT_EQ(again.describe(), "3 tasks: 1 done, 1 cached, 0 failed, 1 skipped");
}

TEST(TaskLog, HoldsEachFailedAttemptWithItsTimeAndLevel) {
  ScratchDir dir;
  const json tasks = json::array({{{"id", "f"}, {"kind", "fail"}, {"params", {{"failures", 2}}}}});
  submit(test_campaign("failing", tasks), dir.db(), 1, 2);
  auto connection = open_read_only(dir.db());
  auto row = connection.prepare("SELECT key FROM tasks");
  ASSERT_TRUE(row.step());
  const auto log = task_log(dir.db(), row.text(0).substr(0, 6));
  ASSERT_EQ(log.size(), 2u);
  for (int attempt = 1; attempt <= 2; ++attempt) {
    const std::string& line = log[attempt - 1];
    EXPECT_EQ(line.substr(0, 2), "20") << line;  // an ISO 8601 time first
    EXPECT_NE(line.find(fmt::format(" error attempt {} failed: planned failure: attempt {} ",
                                    attempt, attempt)),
              std::string::npos)
        << line;
  }
}

}  // namespace
}  // namespace millflow::engine::testing
