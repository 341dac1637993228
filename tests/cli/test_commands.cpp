// The millflow command line through the built binary: validate, submit, status, query, show,
// export, dag, gc, and the exit codes (0 done, 1 failed, 2 bad input, 3 busy, 130 interrupted).
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "engine/store.hpp"
#include "engine/testing_tasks.hpp"
#include "tasks/millflow.hpp"
#include "tests/common/child_process.hpp"
#include "tests/common/running_tasks.hpp"
#include "tests/common/scratch_dir.hpp"

namespace millflow::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// a(1) -> b(2) -> d(4); a -> c(3) -> d: the sum task adds its inputs' sums, so the sums are
// 1, 1+2 = 3, 1+3 = 4 and 4+3+4 = 11.
const std::map<int, int> kDiamondSums = {{1, 1}, {2, 3}, {3, 4}, {4, 11}};

json diamond_tasks() {
  return json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}, {"artifact", true}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}}}, {"after", {"a"}}},
       {{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 3}}}, {"after", {"a"}}},
       {{"id", "d"}, {"kind", "sum"}, {"params", {{"value", 4}}}, {"after", {"b", "c"}}}});
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> words_of(const std::string& line) {
  std::vector<std::string> words;
  std::istringstream in(line);
  for (std::string word; in >> word;) words.push_back(word);
  return words;
}

class Cli : public ::testing::Test {
 protected:
  fs::path write_campaign(const std::string& name, const json& tasks) {
    const fs::path file = dir_.path() / (name + ".json");
    std::ofstream(file) << json{
        {"format", "millflow-test"},
        {"name", name},
        {"tasks", tasks}}.dump();
    return file;
  }
  // millflow ARGS --db <the test's database>
  Finished millflow(std::vector<std::string> arguments) {
    arguments.insert(arguments.end(), {"--db", db().string()});
    return run_millflow(arguments, dir_.path());
  }
  Finished submit_diamond() {
    return millflow({"submit", write_campaign("diamond", diamond_tasks()).string(), "--jobs", "2"});
  }
  fs::path db() const { return dir_.path() / "cli.db"; }
  // A campaign of four 20-second sleeps, its coordinator started in the background with 2 jobs
  // (stdout and stderr to long.out and long.err) and waited for until both run.
  pid_t start_long_campaign() {
    json sleepers = json::array();
    for (int i = 0; i < 4; ++i)
      sleepers.push_back(
          {{"id", std::to_string(i)}, {"kind", "sleep"}, {"params", {{"ms", 20000 + i}}}});
    const pid_t coordinator = spawn_millflow(
        {"submit", write_campaign("long", sleepers).string(), "--db", db().string(), "--jobs", "2"},
        dir_.path() / "long.out", dir_.path() / "long.err");
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (running_tasks(db()) < 2 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return coordinator;
  }
  static constexpr const char* kLongInterrupted =
      "campaign long: 4 tasks: 0 done, 0 cached, 0 failed, 0 skipped, 2 interrupted, 2 not "
      "started\n";
  // value parameter -> task key, read from the store.
  std::map<int, std::string> keys_by_value() {
    auto connection = engine::open_read_only(db());
    auto rows = connection.prepare("SELECT json_extract(params, '$.value'), key FROM tasks");
    std::map<int, std::string> keys;
    while (rows.step()) keys[static_cast<int>(rows.integer(0))] = rows.text(1);
    return keys;
  }

  ScratchDir dir_;
};

TEST_F(Cli, ValidateReportsEveryErrorWithExitTwoAndNothingIsWritten) {
  const auto file =
      write_campaign("bad", json::array({{{"id", "a"}, {"kind", "nope"}},
                                         {{"id", "a"}, {"kind", "sum"}, {"after", {"z"}}}}));
  const auto validated = run_millflow({"validate", file.string()}, dir_.path());
  EXPECT_EQ(validated.exit_code, 2);
  EXPECT_EQ(validated.out, "");
  EXPECT_EQ(validated.err,
            "millflow: invalid input:\n"
            "/tasks/0/kind: unknown kind \"nope\"; use sleep, fail, steps, sum or fanout\n"
            "/tasks/1/after: \"z\" is not the id of an earlier task; list earlier tasks only\n"
            "/tasks/1/id: duplicate id \"a\"\n");
  const auto submitted = millflow({"submit", file.string()});
  EXPECT_EQ(submitted.exit_code, 2);
  EXPECT_EQ(submitted.err, validated.err);
  EXPECT_FALSE(fs::exists(db()));
  EXPECT_FALSE(fs::exists(engine::lock_file(db())));

  const auto good = write_campaign("diamond", diamond_tasks());
  const auto valid = run_millflow({"validate", good.string()}, dir_.path());
  EXPECT_EQ(valid.exit_code, 0);
  EXPECT_EQ(valid.out,
            good.string() + ": valid millflow-test campaign \"diamond\", 4 planned tasks\n");
}

TEST_F(Cli, SubmitThenStatusCountsTasksByKindAndStatus) {
  json tasks = diamond_tasks();
  tasks.push_back({{"id", "broken"}, {"kind", "fail"}, {"params", {{"failures", 9}}}});
  tasks.push_back(
      {{"id", "below"}, {"kind", "sum"}, {"params", {{"value", 5}}}, {"after", {"broken"}}});
  const auto file = write_campaign("mixed", tasks);
  const auto first = millflow({"submit", file.string()});
  EXPECT_EQ(first.exit_code, 1);
  EXPECT_EQ(first.out, "campaign mixed: 6 tasks: 4 done, 0 cached, 1 failed, 1 skipped\n");

  const auto status = millflow({"status", "mixed"});
  ASSERT_EQ(status.exit_code, 0) << status.err;
  std::set<std::vector<std::string>> rows;
  for (const auto& line : lines_of(status.out)) rows.insert(words_of(line));
  const std::set<std::vector<std::string>> expected_rows = {
      {"fail", "failed", "1"}, {"sum", "done", "4"}, {"sum", "skipped", "1"}};
  for (const auto& row : expected_rows)
    EXPECT_EQ(rows.count(row), 1u) << row[0] << " " << row[1] << "\n" << status.out;
  EXPECT_EQ(lines_of(status.out).size(), 2 + expected_rows.size())
      << status.out;  // header, rule, rows

  const auto campaigns = millflow({"status"});
  EXPECT_NE(campaigns.out.find("mixed"), std::string::npos) << campaigns.out;
  EXPECT_NE(campaigns.out.find("failed"), std::string::npos) << campaigns.out;

  const auto again = millflow({"submit", file.string()});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_EQ(again.out, "campaign mixed: 6 tasks: 0 done, 4 cached, 1 failed, 1 skipped\n");
}

TEST_F(Cli, QueryAnswersInCsvAndJsonAndRefusesWrites) {
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const std::string sql =
      "SELECT json_extract(params, '$.value') AS value, json_extract(result, '$.sum') AS sum FROM "
      "task_results "
      "ORDER BY value";
  std::string expected_csv = "value,sum\n";
  json expected_json = json::array();
  for (const auto& [value, sum] : kDiamondSums) {
    expected_csv += std::to_string(value) + "," + std::to_string(sum) + "\n";
    expected_json.push_back({{"value", value}, {"sum", sum}});
  }
  EXPECT_EQ(millflow({"query", "--format", "csv", sql}).out, expected_csv);
  EXPECT_EQ(json::parse(millflow({"query", "--format", "json", sql}).out), expected_json);
  const auto refused = millflow({"query", "DELETE FROM tasks"});
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_EQ(refused.err,
            "millflow: invalid input:\nSQL: refused: the statement would modify the database; "
            "millflow query only reads; the store is written by millflow submit/resume alone\n");
  // An error found running the statement, not preparing it, was exit 1.
  const auto overflow = millflow({"query", "SELECT abs(-9223372036854775808)"});
  EXPECT_EQ(overflow.exit_code, 2);
  EXPECT_EQ(overflow.err,
            "millflow: invalid input:\nSQL: SQL step failed for \"SELECT "
            "abs(-9223372036854775808)\": integer overflow; check the SQL; `millflow query "
            "\"SELECT name FROM sqlite_master\"` lists tables\n");
  // Text that is not UTF-8 made --format json exit 1 (nlohmann's type_error 316).
  const auto bytes = millflow({"query", "--format", "json", "SELECT CAST(x'ff' AS TEXT) AS a"});
  EXPECT_EQ(bytes.exit_code, 0) << bytes.err;
  EXPECT_EQ(json::parse(bytes.out), json::parse(R"([{"a": "\ufffd"}])"));
}

std::time_t parse_iso8601_utc(const std::string& text) {
  std::tm utc{};
  std::istringstream in(text);
  in >> std::get_time(&utc, "%Y-%m-%dT%H:%M:%S");
  return ::timegm(&utc);
}

TEST_F(Cli, ShowFindsATaskByKeyPrefixAndPrintsItsStartInIso8601Utc) {
  const std::time_t before = std::time(nullptr);
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const std::time_t after = std::time(nullptr);
  const auto keys = keys_by_value();
  const auto shown = millflow({"show", keys.at(4).substr(0, 10)});
  ASSERT_EQ(shown.exit_code, 0) << shown.err;
  const auto lines = lines_of(shown.out);
  EXPECT_EQ(lines.at(0), "task " + keys.at(4));
  EXPECT_EQ(lines.at(1), "kind sum (version 1)");
  EXPECT_EQ(lines.at(2), "status done after 1 attempt(s)");
  std::smatch started;
  ASSERT_TRUE(std::regex_search(
      lines.at(3), started, std::regex(R"(^started (\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z) )")))
      << lines.at(3);
  EXPECT_GE(parse_iso8601_utc(started[1]), before);
  EXPECT_LE(parse_iso8601_utc(started[1]), after);
  std::set<std::string> upstream;
  for (const auto& line : lines) {
    if (line.rfind("upstream", 0) == 0) upstream.insert(words_of(line).at(1));
  }
  EXPECT_EQ(upstream, (std::set<std::string>{keys.at(1).substr(0, 16), keys.at(2).substr(0, 16),
                                             keys.at(3).substr(0, 16)}));
  EXPECT_NE(shown.out.find("\"sum\": 11"), std::string::npos) << shown.out;

  const auto unknown = millflow({"show", "zzzz"});
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.err.find("no task key starts with \"zzzz\""), std::string::npos) << unknown.err;
}

TEST_F(Cli, ExportWritesOneCsvPerKindOrOneJsonFile) {
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const auto keys = keys_by_value();
  const fs::path out = dir_.path() / "export";
  const auto csv = millflow({"export", "diamond", "--format", "csv", "--out", out.string()});
  ASSERT_EQ(csv.exit_code, 0) << csv.err;
  EXPECT_EQ(csv.out, (out / "sum.csv").string() + "\n");
  std::map<std::string, std::string> expected_rows;  // by key: rows are sorted by task key
  for (const auto& [value, sum] : kDiamondSums) {
    const std::string artifact = value == 1 ? "true" : "";
    expected_rows[keys.at(value)] = keys.at(value) + ",done," + artifact + "," +
                                    std::to_string(value) + "," + std::to_string(sum);
  }
  std::string expected = "task_key,status,params/artifact,params/value,result/sum\n";
  for (const auto& [key, row] : expected_rows) expected += row + "\n";
  EXPECT_EQ(read_text(out / "sum.csv"), expected);

  const auto exported = millflow({"export", "diamond", "--format", "json", "--out", out.string()});
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  const json tasks = json::parse(read_text(out / "diamond.json"));
  ASSERT_EQ(tasks.size(), kDiamondSums.size());
  for (const auto& task : tasks) {
    const int value = task["params"]["value"];
    EXPECT_EQ(task["task_key"], keys.at(value));
    EXPECT_EQ(task["result"]["sum"], kDiamondSums.at(value));
  }
  // A failed export leaves the directory as it was: both files, nothing staged.
  EXPECT_EQ(millflow({"export", "nope", "--format", "json", "--out", out.string()}).exit_code, 2);
  EXPECT_EQ(std::distance(fs::directory_iterator(out), fs::directory_iterator()), 2);
  // Into a new directory: absent after a failure, whole after a success.
  const fs::path fresh = dir_.path() / "new" / "export";
  EXPECT_EQ(millflow({"export", "nope", "--format", "json", "--out", fresh.string()}).exit_code, 2);
  EXPECT_FALSE(fs::exists(fresh));
  EXPECT_FALSE(fs::exists(fresh.parent_path() / ".export.partial"));
  ASSERT_EQ(millflow({"export", "diamond", "--format", "json", "--out", fresh.string()}).exit_code,
            0);
  EXPECT_EQ(read_text(fresh / "diamond.json"), read_text(out / "diamond.json"));
}

TEST_F(Cli, DagWithTasksHasEveryTaskAndEveryEdge) {
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const auto keys = keys_by_value();
  const auto dag = millflow({"dag", "diamond", "--tasks"});
  ASSERT_EQ(dag.exit_code, 0) << dag.err;
  const auto lines = lines_of(dag.out);
  EXPECT_EQ(lines.front(), "digraph \"diamond\" {");
  EXPECT_EQ(lines.back(), "}");
  std::set<std::pair<std::string, std::string>> edges;
  std::set<std::string> done_nodes;
  const std::regex edge(R"re(^  "([0-9a-f]{64})" -> "([0-9a-f]{64})";$)re");
  const std::regex node(
      R"re(^  "([0-9a-f]{64})" \[label="sum\\n[0-9a-f]{12}", fillcolor=palegreen\];$)re");
  for (const auto& line : lines) {
    std::smatch match;
    if (std::regex_match(line, match, edge)) edges.insert({match[1], match[2]});
    if (std::regex_match(line, match, node)) done_nodes.insert(match[1]);
  }
  EXPECT_EQ(done_nodes, (std::set<std::string>{keys.at(1), keys.at(2), keys.at(3), keys.at(4)}));
  EXPECT_EQ(edges, (std::set<std::pair<std::string, std::string>>{{keys.at(1), keys.at(2)},
                                                                  {keys.at(1), keys.at(3)},
                                                                  {keys.at(2), keys.at(4)},
                                                                  {keys.at(3), keys.at(4)}}));
}

TEST_F(Cli, DagDrawsOneNodePerKindByDefault) {
  json tasks = diamond_tasks();
  tasks.push_back({{"id", "broken"}, {"kind", "fail"}, {"params", {{"failures", 9}}}});
  tasks.push_back(
      {{"id", "below"}, {"kind", "sum"}, {"params", {{"value", 5}}}, {"after", {"broken"}}});
  ASSERT_EQ(millflow({"submit", write_campaign("mixed", tasks).string()}).exit_code, 1);
  const auto dag = millflow({"dag", "mixed"});
  ASSERT_EQ(dag.exit_code, 0) << dag.err;
  EXPECT_EQ(dag.out,
            "digraph \"mixed\" {\n"
            "  node [shape=box, style=filled];\n"
            "  \"sum\" [label=\"sum\\n5 tasks: 4 done, 1 skipped\", fillcolor=lightgrey];\n"
            "  \"fail\" [label=\"fail\\n1 task: 1 failed\", fillcolor=salmon];\n"
            "  \"sum\" -> \"sum\" [label=\"4\"];\n"
            "  \"fail\" -> \"sum\" [label=\"1\"];\n"
            "}\n");
}

// diamond with c's value changed from 3 to 30.
json changed_diamond() {
  json tasks = diamond_tasks();
  tasks[2]["params"]["value"] = 30;
  return tasks;
}

TEST_F(Cli, SubmitDryRunSaysPerKindWhatWouldRunAndWhyAndWritesNothing) {
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const auto file = write_campaign("diamond", changed_diamond());
  const auto dry = millflow({"submit", file.string(), "--dry-run"});
  ASSERT_EQ(dry.exit_code, 0) << dry.err;
  EXPECT_EQ(dry.out,
            "dry run of \"diamond\": 4 tasks, 2 cached, 2 would run\n"
            "sum: 2 of 4 would run\n"
            "  1 parameters changed\n"
            "    /value: 3 -> 30\n"
            "  1 upstream changed\n");
  EXPECT_EQ(keys_by_value().size(), 4u);  // no task of the changed campaign was registered
  const auto forced = millflow({"submit", file.string(), "--dry-run", "--force", "sum"});
  EXPECT_EQ(forced.out,
            "dry run of \"diamond\": 4 tasks, 0 cached, 4 would run\n"
            "sum: 4 of 4 would run\n"
            "  2 forced\n"
            "  1 parameters changed\n"
            "    /value: 3 -> 30\n"
            "  1 upstream changed\n");
}

TEST_F(Cli, EstimateAndTheDryRunPriceEachKindOfACampaignFile) {
  const std::string quick = std::string(MILLFLOW_SOURCE_DIR) + "/campaigns/quick.json";
  const auto estimate = run_millflow({"estimate", quick}, dir_.path());
  ASSERT_EQ(estimate.exit_code, 0) << estimate.err;
  std::map<std::string, std::vector<std::string>> rows;
  for (const auto& line : lines_of(estimate.out)) {
    const auto words = words_of(line);
    if (!words.empty()) rows[words.front()] = words;
  }
  // kind, tasks, particles per task, steps per task, core-hours (least - at the caps).
  EXPECT_EQ(rows.at("macro").at(1), "4");
  EXPECT_EQ(rows.at("macro").at(2), "415");
  EXPECT_EQ(rows.at("macro").at(4), "726");
  EXPECT_EQ(rows.at("shear_cell").at(1), "136");  // 120 and 16 stiff ones (sensitivity)
  EXPECT_EQ(rows.at("average").at(4), "small");
  EXPECT_EQ(rows.at("total").at(1), "161");
  EXPECT_GT(std::stod(rows.at("total").at(4)), std::stod(rows.at("total").at(2)));
  // The dry run of a campaign never run prices all of it, and no file is written.
  const auto dry = millflow({"submit", quick, "--dry-run"});
  ASSERT_EQ(dry.exit_code, 0) << dry.err;
  const auto cost = dry.out.find("cost of what would run:");
  ASSERT_NE(cost, std::string::npos) << dry.out;
  EXPECT_NE(dry.out.find("shear_cell      136", cost), std::string::npos) << dry.out;
  EXPECT_FALSE(fs::exists(db()));
}

TEST_F(Cli, ExplainWorksOnACampaignFileBeforeItWasEverSubmitted) {
  const auto file = write_campaign("diamond", diamond_tasks());
  const auto listed = millflow({"explain", file.string()});
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  const auto lines = lines_of(listed.out);
  ASSERT_EQ(lines.size(), 4u) << listed.out;
  const std::regex new_task(R"(^sum ([0-9a-f]{64}): would run: new$)");
  std::smatch first;
  ASSERT_TRUE(std::regex_match(lines[0], first, new_task)) << lines[0];
  for (const auto& line : lines) EXPECT_TRUE(std::regex_match(line, new_task)) << line;
  EXPECT_FALSE(fs::exists(db()));

  const std::string key = first[1];
  const auto one = millflow({"explain", file.string(), key.substr(0, 8)});
  ASSERT_EQ(one.exit_code, 0) << one.err;
  EXPECT_EQ(one.out,
            "task " + key +
                "\nhashed text (SHA-256 of exactly these bytes):\n"
                "millflow-task 1\nkind:sum\nversion:1\nparams:{\"artifact\":true,\"value\":1}\n"
                "upstream:\nwould run: new\n");
  const auto unknown = millflow({"explain", file.string(), "ffff"});
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_EQ(unknown.err,
            "millflow: invalid input:\n(document): no task of campaign \"diamond\" has a key "
            "starting with \"ffff\"; `millflow explain FILE` lists every task with its key\n");

  ASSERT_EQ(submit_diamond().exit_code, 0);
  const auto cached = millflow({"explain", file.string()});
  for (const auto& line : lines_of(cached.out))
    EXPECT_NE(line.find(": would not run: done, result and artifacts intact (cached)"),
              std::string::npos)
        << line;
}

TEST_F(Cli, ForceAndUntilSelectWhatSubmitAndResumeRun) {
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const auto file = write_campaign("diamond", diamond_tasks());
  const auto keys = keys_by_value();
  EXPECT_EQ(millflow({"submit", file.string(), "--force", keys.at(2).substr(0, 10)}).out,
            "campaign diamond: 4 tasks: 1 done, 3 cached, 0 failed, 0 skipped\n");
  EXPECT_EQ(millflow({"resume", "--force", "sum"}).out,
            "campaign diamond: 4 tasks: 4 done, 0 cached, 0 failed, 0 skipped\n");
  const auto wrong = millflow({"submit", file.string(), "--force", "nope", "--until", "nada"});
  EXPECT_EQ(wrong.exit_code, 2);
  engine::Registry registry;  // the kinds of millflow_testing
  tasks::register_millflow(registry);
  engine::add_testing(registry);
  const std::string kinds = registry.kinds.names();
  EXPECT_EQ(wrong.err,
            "millflow: invalid input:\n--force: \"nope\" is neither a task kind nor a "
            "task key; name a kind (" +
                kinds +
                ") or a key from `millflow explain FILE`\n"
                "--until: \"nada\" is not a task kind; name one of: " +
                kinds + "\n");
  // The empty prefix of every key: it forced the whole campaign.
  const auto empty = millflow({"submit", file.string(), "--force", ""});
  EXPECT_EQ(empty.exit_code, 2);
  EXPECT_EQ(empty.err,
            "millflow: invalid input:\n--force: \"\" is neither a task kind nor a task "
            "key; name a kind (" +
                kinds + ") or a key from `millflow explain FILE`\n");

  const auto chain = write_campaign(
      "chain",
      json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}},
                   {{"id", "s"}, {"kind", "sleep"}, {"params", {{"ms", 0}}}, {"after", {"a"}}},
                   {{"id", "c"}, {"kind", "sum"}, {"params", {{"value", 2}}}, {"after", {"s"}}}}));
  const auto partial = millflow({"submit", chain.string(), "--until", "sleep"});
  EXPECT_EQ(partial.exit_code, 0) << partial.err;
  EXPECT_EQ(partial.out,
            "campaign chain: 3 tasks: 2 done, 0 cached, 0 failed, 0 skipped, 1 held back by "
            "--until\n");
  EXPECT_EQ(millflow({"resume", "chain"}).out,
            "campaign chain: 3 tasks: 1 done, 2 cached, 0 failed, 0 skipped\n");
}

TEST_F(Cli, TheProductionBinaryHasNoTestKinds) {
  const auto file = write_campaign("diamond", diamond_tasks());
  const auto refused =
      run_millflow({"validate", file.string()}, dir_.path(), production_millflow_binary());
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_EQ(refused.err,
            "millflow: invalid input:\n(document): no loader is registered for campaign format "
            "\"millflow-test\" in this build; formats this build reads: millflow_campaign\n");
}

TEST_F(Cli, GcRemovesOnlyFilesNoTaskReferences) {
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const fs::path root = engine::artifacts_dir(db());
  auto connection = engine::open_read_only(db());
  auto row = connection.prepare("SELECT sha256 FROM artifacts");
  ASSERT_TRUE(row.step());
  const fs::path kept = root / row.text(0).substr(0, 2) / row.text(0);
  const std::string stray = std::string(64, 'f');
  const std::string leftover = row.text(0) + ".tmp.1.0";  // a copy interrupted by a crash
  // ... and the temporary file of util::DurableFile inside that copy, whose name starts with '.'
  // (gc once said it removed it, looking for it in a directory ".x", and left it)
  const std::string hidden = "." + leftover + ".tmp.Ab12Cd";
  fs::create_directories(root / "ff");
  std::ofstream(root / "ff" / stray) << "orphan\n";
  std::ofstream(kept.parent_path() / leftover) << "half";
  std::ofstream(kept.parent_path() / hidden) << "ha";

  const auto dry = millflow({"gc", "--dry-run"});
  ASSERT_EQ(dry.exit_code, 0) << dry.err;
  const auto dry_lines = lines_of(dry.out);
  EXPECT_EQ(std::set<std::string>(dry_lines.begin(), dry_lines.end()),
            (std::set<std::string>{"would remove " + stray, "would remove " + leftover,
                                   "would remove " + hidden, "3 unreferenced artifact file(s)"}));
  EXPECT_TRUE(fs::exists(root / "ff" / stray));

  const auto collected = millflow({"gc"});
  const auto lines = lines_of(collected.out);
  EXPECT_EQ(std::set<std::string>(lines.begin(), lines.end()),
            (std::set<std::string>{"removed " + stray, "removed " + leftover, "removed " + hidden,
                                   "3 unreferenced artifact file(s)"}));
  EXPECT_FALSE(fs::exists(root / "ff" / stray));
  EXPECT_FALSE(fs::exists(kept.parent_path() / leftover));
  EXPECT_FALSE(fs::exists(kept.parent_path() / hidden));
  EXPECT_TRUE(fs::exists(kept));
  EXPECT_EQ(millflow({"gc"}).out, "0 unreferenced artifact file(s)\n");
}

TEST_F(Cli, ExitCodesForDoneFailedBadInputBusyAndInterrupted) {
  EXPECT_EQ(submit_diamond().exit_code, 0);
  const auto failing = write_campaign(
      "failing", json::array({{{"id", "f"}, {"kind", "fail"}, {"params", {{"failures", 1}}}}}));
  EXPECT_EQ(millflow({"submit", failing.string()}).exit_code, 1);
  EXPECT_EQ(millflow({"submit", failing.string(), "--jobs", "0"}).exit_code, 2);  // out of range
  EXPECT_EQ(millflow({"submit"}).exit_code, 2);                                   // no file
  EXPECT_EQ(millflow({"status", "no-such-campaign"}).exit_code, 2);

  const pid_t coordinator = start_long_campaign();
  ASSERT_EQ(running_tasks(db()), 2);
  const auto busy = millflow({"submit", (dir_.path() / "long.json").string()});
  EXPECT_EQ(busy.exit_code, 3);
  EXPECT_NE(
      busy.err.find("in use by another millflow coordinator: pid " + std::to_string(coordinator)),
      std::string::npos)
      << busy.err;

  ::kill(coordinator, SIGINT);
  EXPECT_EQ(wait_exit_code(coordinator), 130);
  EXPECT_EQ(read_text(dir_.path() / "long.out"), kLongInterrupted);
  EXPECT_EQ(running_tasks(db()), 0);
}

// A closed terminal (SIGHUP) stops the campaign as Ctrl-C does; it used to kill the coordinator
// mid-task.
TEST_F(Cli, AHangupStopsCleanly) {
  const pid_t coordinator = start_long_campaign();
  ASSERT_EQ(running_tasks(db()), 2);
  ::kill(coordinator, SIGHUP);
  EXPECT_EQ(wait_exit_code(coordinator), 130);
  EXPECT_EQ(read_text(dir_.path() / "long.out"), kLongInterrupted);
  EXPECT_EQ(running_tasks(db()), 0);
}

// The status and log lines are best effort: with stderr unwritable (a full disk, a terminal gone)
// the campaign runs to its end. It used to fail at its first line (exit 1, nothing run).
TEST_F(Cli, AnUnwritableStderrDoesNotStopACampaign) {
  const fs::path out = dir_.path() / "diamond.out";
  const pid_t coordinator =
      spawn_millflow({"submit", write_campaign("diamond", diamond_tasks()).string(), "--db",
                      db().string(), "--jobs", "2"},
                     out, "/dev/full");
  EXPECT_EQ(wait_exit_code(coordinator), 0);
  EXPECT_EQ(read_text(out).rfind("campaign diamond: ", 0), 0u) << read_text(out);
  EXPECT_NE(read_text(out).find(" 0 failed"), std::string::npos) << read_text(out);
}

// `timeout -s INT` signals the command and then its process group, so the coordinator gets one
// request as two signals in a row; it used to take the second as "Ctrl-C again" and exit at
// once, leaving its tasks marked running and their work since the last checkpoint lost. (Two
// kills before the first is handled merge into one signal: the second follows the first's
// message.)
TEST_F(Cli, ARequestDeliveredAsTwoSignalsInARowStillStopsCleanly) {
  const pid_t coordinator = start_long_campaign();
  ASSERT_EQ(running_tasks(db()), 2);
  ::kill(coordinator, SIGINT);
  const auto err = dir_.path() / "long.err";
  for (int wait = 0; wait < 400 && read_text(err).find("millflow: stopping") == std::string::npos;
       ++wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ::kill(coordinator, SIGINT);
  EXPECT_EQ(wait_exit_code(coordinator), 130);
  EXPECT_EQ(read_text(dir_.path() / "long.out"), kLongInterrupted);
  EXPECT_EQ(running_tasks(db()), 0);
}

TEST_F(Cli, ReportOfACampaignWithoutAReportTaskIsBadInput) {
  ASSERT_EQ(submit_diamond().exit_code, 0);
  const auto latest = millflow({"report", "--out", (dir_.path() / "report").string()});
  EXPECT_EQ(latest.exit_code, 2);
  EXPECT_NE(latest.err.find("campaign \"diamond\" has no finished report task"), std::string::npos)
      << latest.err;
  EXPECT_FALSE(fs::exists(dir_.path() / "report"));
  EXPECT_EQ(millflow({"report", "nope"}).exit_code, 2);
}

}  // namespace
}  // namespace millflow::testing
