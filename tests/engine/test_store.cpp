// The store's safety rails: schema versions, read-only queries, the coordinator lock, and reads
// while a coordinator writes.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <sstream>
#include <thread>

#include "engine/coordinator_lock.hpp"
#include "engine/inspect.hpp"
#include "engine/store.hpp"
#include "engine/validation.hpp"
#include "support_engine.hpp"
#include "util/sha256.hpp"

namespace millflow::engine::testing {
namespace {

using nlohmann::json;

TEST(Store, CreatesTheCurrentSchemaVersion) {
  ScratchDir dir;
  const SystemClock clock;
  Store store(dir.db(), {}, clock);
  EXPECT_EQ(store.connection().user_version(), kSchemaVersion);
}

TEST(Store, RefusesANewerSchemaWithoutTouchingIt) {
  ScratchDir dir;
  {
    sql::Connection raw(dir.db(), sql::Access::read_write);
    raw.exec("PRAGMA user_version = 99");
  }
  const SystemClock clock;
  try {
    Store store(dir.db(), {}, clock);
    FAIL() << "a newer schema was opened";
  } catch (const SchemaTooNew& error) {
    EXPECT_NE(std::string(error.what()).find("schema version 99"), std::string::npos)
        << error.what();
  }
  EXPECT_THROW(open_read_only(dir.db()), SchemaTooNew);
  sql::Connection raw(dir.db(), sql::Access::read_only);
  EXPECT_EQ(raw.user_version(), 99);
}

// A first submit killed before it created the schema leaves an empty file: readers (status,
// resume, query) say what happened instead of failing on a missing table.
// A full disk (here a page limit, which SQLite reports the same way) names the database and the
// fix; SQLite's own "database or disk is full" named neither.
TEST(Store, AFullDiskNamesTheDatabaseAndWhatToDo) {
  ScratchDir dir;
  sql::Connection raw(dir.db(), sql::Access::read_write);
  raw.exec("CREATE TABLE t (x TEXT)");
  raw.exec("PRAGMA max_page_count = 4");
  auto insert = raw.prepare("INSERT INTO t VALUES (?)");
  try {
    for (int row = 0; row < 100; ++row) {
      insert.bind(1, std::string(1000, 'x'));
      insert.run();
    }
    FAIL() << "the page limit was never reached";
  } catch (const sql::Error& error) {
    EXPECT_NE(std::string(error.what())
                  .find("database or disk is full (" + dir.db().string() +
                        ": free space on its disk, then run the command again; what was committed "
                        "is kept)"),
              std::string::npos)
        << error.what();
  }
}

TEST(Store, ReadersOfADatabaseWithoutTablesSayToSubmitAgain) {
  ScratchDir dir;
  { sql::Connection raw(dir.db(), sql::Access::read_write); }
  try {
    open_read_only(dir.db());
    FAIL() << "a database without tables was opened";
  } catch (const std::runtime_error& error) {
    EXPECT_EQ(std::string(error.what()), "--db: the database " + dir.db().string() +
                                             " has no millflow tables (nothing was submitted to "
                                             "it, or its first submit stopped before creating "
                                             "them); submit the campaign again");
    EXPECT_NE(dynamic_cast<const InvalidInput*>(&error), nullptr);  // exit 2, not 1
  }
}

// A campaign of one sum task, submitted into dir's database, which `damage` (SQL) then changes
// behind the store's back.
Campaign one_task_done_then(const ScratchDir& dir, const std::string& damage) {
  const Campaign one = test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}}));
  EXPECT_EQ(submit(one, dir.db()).exit_code(), 0);
  sql::Connection raw(dir.db(), sql::Access::read_write);
  raw.exec(damage);
  return one;
}

// A stored result that is not JSON (a byte of the file changed) failed every submit, resume and
// status with SQLite's "malformed JSON" from the query that reads whether results say "skipped":
// it is no result now, and its task runs again.
TEST(Store, AResultThatIsNotJsonIsNoResultAndItsTaskRunsAgain) {
  ScratchDir dir;
  const Campaign one =
      one_task_done_then(dir, "UPDATE results SET result = replace(result, ':', '~')");
  ASSERT_EQ(count(dir.db(), "SELECT count(*) FROM results WHERE json_valid(result)"), 0);
  {  // `show` and `export` read it as a damaged store (exit 2), not as the library's parse error
    auto reader = open_read_only(dir.db());
    auto key = reader.prepare("SELECT task_key FROM results");
    ASSERT_TRUE(key.step());
    try {
      find_result(reader, key.text(0));
      ADD_FAILURE() << "a result that is not JSON was read";
    } catch (const InvalidInput& error) {
      EXPECT_EQ(error.errors()[0].problem, "the stored result of task " + key.text(0) +
                                               " is not JSON: the database is damaged");
    }
  }
  const RunSummary again = submit(one, dir.db());
  EXPECT_EQ(again.exit_code(), 0);
  EXPECT_EQ(again.done, 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM results WHERE json_valid(result)"), 1);
}

// The key of the one task of dir's database.
std::string the_task_key(const ScratchDir& dir) {
  auto reader = open_read_only(dir.db());
  auto key = reader.prepare("SELECT key FROM tasks");
  EXPECT_TRUE(key.step());
  return key.text(0);
}

// A task's parameters changed in the file (a digit) were what the runtime and the views read;
// the key text they were hashed from is what the runtime reads now, and a submit writes the copy
// back.
TEST(Store, ATasksParametersAreItsKeyTextsAndASubmitWritesThemBack) {
  ScratchDir dir;
  const Campaign one =
      one_task_done_then(dir, "UPDATE tasks SET params = json_set(params, '$.changed', 1)");
  {
    auto reader = open_read_only(dir.db());
    EXPECT_FALSE(find_task(reader, the_task_key(dir))->spec.params.contains("changed"));
  }
  EXPECT_EQ(submit(one, dir.db()).cached, 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE params LIKE '%changed%'"), 0);
}

// A key text that no longer hashes to its key is a damaged store, named; a submit writes a
// planned task's anew.
TEST(Store, AKeyTextThatDoesNotHashToItsKeyIsADamagedStoreASubmitMends) {
  ScratchDir dir;
  const Campaign one = one_task_done_then(dir, "UPDATE tasks SET key_text = key_text || ' '");
  const std::string key = the_task_key(dir);
  try {
    auto reader = open_read_only(dir.db());
    find_task(reader, key);
    ADD_FAILURE() << "a key text that does not hash to its key was read";
  } catch (const InvalidInput& error) {
    EXPECT_EQ(error.errors()[0].problem, "the stored key text of task " + key +
                                             " does not hash to its key: the database is damaged");
  }
  EXPECT_EQ(submit(one, dir.db()).cached, 1);
  auto reader = open_read_only(dir.db());
  EXPECT_EQ(util::sha256_hex(find_task(reader, key)->spec.key_text), key);
}

// A campaign's document changed in the file (a digit, still JSON) was what `resume` ran: it is a
// damaged store now, named, until the file is submitted again.
TEST(Store, ACampaignDocumentThatIsNotItsDigestsIsADamagedStore) {
  ScratchDir dir;
  const Campaign one =
      one_task_done_then(dir, "UPDATE campaigns SET document = json_set(document, '$.changed', 1)");
  try {
    auto reader = open_read_only(dir.db());
    find_campaign(reader, "one");
    ADD_FAILURE() << "a changed campaign document was read";
  } catch (const InvalidInput& error) {
    EXPECT_EQ(error.errors()[0].problem,
              "the stored document of campaign one is not the text submitted: the database is "
              "damaged");
  }
  EXPECT_EQ(submit(one, dir.db()).cached, 1);
  auto reader = open_read_only(dir.db());
  EXPECT_FALSE(find_campaign(reader, "one")->document.contains("changed"));
}

// A launcher that fails outright: an error out of the coordinator's run, not out of a task.
class BrokenLauncher final : public Launcher {
 public:
  void launch(std::function<void()>) override { throw std::runtime_error("no worker left"); }
  void wait_idle() override {}
};

// A coordinator stopped by an error records the campaign as failed and leaves no coordinator
// behind; it left its record, and the next submit reported taking over from a coordinator that was
// gone, and `status` called the campaign interrupted by one that had died.
TEST(Store, ACoordinatorStoppedByAnErrorLeavesNoRecordOfItself) {
  ScratchDir dir;
  const auto one = test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}}));
  BrokenLauncher broken;
  SubmitOptions options;
  options.launcher = &broken;
  EXPECT_THROW(submit_campaign(testing_registry(), one, dir.db(), options), std::runtime_error);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM coordinator"), 0);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM campaigns WHERE outcome = 'failed'"), 1);
}

// A result changed in the file to other valid JSON (a digit), which SQLite's integrity check
// passes, was read as the task's: its digest tells it now, and the task runs again.
TEST(Store, AResultThatIsNotItsDigestsIsNoResultAndItsTaskRunsAgain) {
  ScratchDir dir;
  const Campaign one =
      one_task_done_then(dir, "UPDATE results SET result = json_set(result, '$.changed', 1)");
  const RunSummary again = submit(one, dir.db());
  EXPECT_EQ(again.exit_code(), 0);
  EXPECT_EQ(again.done, 1);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM results WHERE result LIKE '%changed%'"), 0);
}

// ... and a submit to it creates the schema: the coordinator lock's look at who held the database
// before must not refuse it (it did, so a crash test round killed that early failed for good).
TEST(Store, SubmitToADatabaseWithoutTablesCreatesThem) {
  ScratchDir dir;
  { sql::Connection raw(dir.db(), sql::Access::read_write); }
  // The dry run takes it for the empty store the submit finds (it refused what submit ran).
  const auto one = test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}}));
  const DryRun dry = dry_run(testing_registry(), one, dir.db());
  ASSERT_EQ(dry.tasks.size(), 1u);
  EXPECT_FALSE(dry.tasks[0].decision.cached());
  EXPECT_EQ(submit(test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})), dir.db())
                .exit_code(),
            0);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'done'"), 1);
}

// A first submit killed while it wrote the schema (before the file switched to WAL) leaves a hot
// rollback journal, which a read-only connection cannot roll back: every command then failed with
// "attempt to write a readonly database", submit included, until the journal was removed by hand.
TEST(Store, AFirstSubmitKilledMidTransactionIsRolledBackByReaders) {
  ScratchDir dir;
  const pid_t child = ::fork();
  if (child == 0) {  // a writer that dies with pages of its transaction spilled to the file
    sql::Connection raw(dir.db(), sql::Access::read_write);
    raw.exec("PRAGMA cache_size = 1");
    raw.exec("BEGIN");
    raw.exec("CREATE TABLE filler (bytes BLOB)");
    raw.exec(
        "INSERT INTO filler WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE "
        "i < 200) SELECT randomblob(1000) FROM n");
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(std::filesystem::exists(dir.db().string() + "-journal"));
  EXPECT_THROW(
      {
        try {
          open_read_only(dir.db());
        } catch (const std::runtime_error& error) {
          EXPECT_NE(std::string(error.what()).find("has no millflow tables"), std::string::npos)
              << error.what();
          throw;
        }
      },
      std::runtime_error);
  EXPECT_EQ(submit(test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})), dir.db())
                .exit_code(),
            0);
}

// Version 3 added jobs.job_name, version 4 changed indexes and rebuilt results (WITHOUT ROWID): a
// version-2 database (built by its own migrations) with a committed result and a job is read as it
// is, opens migrated, its result still answers through the views, its job keeps its id with an
// empty name, and it is intact.
TEST(Store, MigratesAVersion2DatabaseKeepingItsResultsAndJobs) {
  ScratchDir dir;
  {
    sql::Connection raw(dir.db(), sql::Access::read_write);
    for (int version = 0; version < 2; ++version)
      raw.exec(schema_migrations()[static_cast<size_t>(version)]);
    raw.exec("PRAGMA user_version = 2");
    raw.exec(
        "INSERT INTO tasks (key, kind, kind_version, params, key_text, status, created_at) "
        "VALUES ('k', 'sum', '1', '{}', 'text', 'done', 0)");
    raw.exec(
        "INSERT INTO campaigns (id, name, format, document, submitted_at) VALUES (1, 'old', "
        "'millflow-test', '{}', 0)");
    raw.exec("INSERT INTO campaign_tasks (campaign_id, task_key) VALUES (1, 'k')");
    raw.exec("INSERT INTO results (task_key, result, committed_at) VALUES ('k', '{\"sum\":7}', 0)");
    raw.exec(
        "INSERT INTO status_history (task_key, status, attempt, at) VALUES ('k', 'done', 1, 0)");
    raw.exec(
        "INSERT INTO jobs VALUES ('k', 1, 'slurm', '7_0', 'COMPLETED', '/run/b/0', '/run/b/0.out', "
        "'/run/b/0.err', 1, 2)");
  }
  {
    auto reader = open_read_only(dir.db());
    ASSERT_EQ(find_jobs(reader, "k").size(), 1u);
    EXPECT_EQ(find_jobs(reader, "k")[0].job_name, "");
    EXPECT_TRUE(find_stored_task(reader, "k")->has_result);  // no digest before version 5
  }
  const SystemClock clock;
  {
    Store store(dir.db(),
                {{"sum_results",
                  "SELECT task_key, json_extract(result, '$.sum') AS sum FROM task_results"}},
                clock);
    EXPECT_EQ(store.connection().user_version(), kSchemaVersion);
    const auto jobs = find_jobs(store.connection(), "k");
    ASSERT_EQ(jobs.size(), 1u);
    EXPECT_EQ(jobs[0].job_id, "7_0");
    EXPECT_EQ(jobs[0].job_name, "");
    EXPECT_EQ(jobs[0].output_dir, "/run/b/0");
    EXPECT_TRUE(find_stored_task(store.connection(), "k")->has_result);
  }
  EXPECT_EQ(count(dir.db(), "SELECT sum FROM sum_results WHERE task_key = 'k'"), 7);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM pragma_index_info('tasks_by_kind')"), 1);
  EXPECT_EQ(
      count(dir.db(), "SELECT count(*) FROM sqlite_schema WHERE name = 'status_history_by_task'"),
      0);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM status_history"), 1);
  auto connection = open_read_only(dir.db());
  auto check = connection.prepare("PRAGMA integrity_check");
  ASSERT_TRUE(check.step());
  EXPECT_EQ(check.text(0), "ok");
}

// Every page a commit changes is one WAL frame (two writes and a checksum), so the pages of the
// runtime's turn for a trivial task (its commit and the launch of the next) bound the engine's
// cost per task: schema version 3 wrote about 11.5 per turn (counted in the runtime), version 4
// writes 3.85 here.
TEST(Store, ATaskCompletionAndTheNextLaunchWriteAFewPages) {
  ScratchDir dir;
  const SystemClock clock;
  Store store(dir.db(), {}, clock);
  constexpr int kTasks = 2000;
  std::vector<TaskSpec> tasks;
  for (int i = 0; i < kTasks; ++i) tasks.push_back(make_task_spec("sum", "1", {{"value", i}}, {}));
  const std::int64_t campaign =
      store.register_campaign("pages", "millflow-test", json::object(), tasks);
  store.mark_running(tasks[0].key);
  int written = 0;
  int unused = 0;
  sqlite3_db_status(store.connection().handle(), SQLITE_DBSTATUS_CACHE_WRITE, &written, &unused,
                    1);  // reset
  long pages = 0;
  for (size_t i = 0; i + 1 < tasks.size(); ++i) {
    sql::Transaction turn(store.connection());
    store.commit_done(campaign, tasks[i].key, {{"sum", i}}, {}, {}, 0.0);
    store.mark_running(tasks[i + 1].key);
    turn.commit();
    sqlite3_db_status(store.connection().handle(), SQLITE_DBSTATUS_CACHE_WRITE, &written, &unused,
                      1);
    pages += written;
  }
  EXPECT_LE(static_cast<double>(pages) / (kTasks - 1), 5.0)
      << pages << " pages in " << kTasks - 1 << " turns";
}

TEST(Store, TaskStatusIsTheSchemasTextBothWays) {
  const std::vector<std::pair<TaskStatus, std::string>> spelled = {
      {TaskStatus::pending, "pending"},
      {TaskStatus::running, "running"},
      {TaskStatus::done, "done"},
      {TaskStatus::failed, "failed"},
      {TaskStatus::interrupted, "interrupted"},
      {TaskStatus::skipped, "skipped"}};
  for (const auto& [status, text] : spelled) {
    EXPECT_EQ(to_string(status), text);
    EXPECT_EQ(task_status_from(text), status);
  }
  EXPECT_THROW(task_status_from("finished"), std::runtime_error);
}

TEST(Store, DomainViewsAreInstalled) {
  ScratchDir dir;
  const SystemClock clock;
  Store store(
      dir.db(),
      {{"sum_results", "SELECT task_key, json_extract(result, '$.sum') AS sum FROM task_results"}},
      clock);
  std::ostringstream out;
  run_query(dir.db(), "SELECT count(*) AS n FROM sum_results", TableFormat::csv, out);
  EXPECT_EQ(out.str(), "n\n0\n");
}

TEST(Store, QueryRefusesWrites) {
  ScratchDir dir;
  submit(test_campaign("one",
                       json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}}})),
         dir.db());
  std::ostringstream out;
  for (const char* statement :
       {"DELETE FROM tasks", "UPDATE tasks SET status = 'failed'", "DROP TABLE results",
        "INSERT INTO log_lines (at, level, message) VALUES (0, 'x', 'y')"}) {
    EXPECT_THROW(run_query(dir.db(), statement, TableFormat::table, out), InvalidInput)
        << statement;
  }
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'done'"), 1);
  run_query(dir.db(), "SELECT json_extract(result, '$.sum') AS s FROM task_results",
            TableFormat::json, out);
  EXPECT_EQ(json::parse(out.str()), json::parse(R"([{"s": 1}])"));
}

// A recursive query without end used to fill the memory until the process was killed.
TEST(Store, QueryRefusesAResultOfMoreValuesThanItHolds) {
  ScratchDir dir;
  submit(test_campaign("one",
                       json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}}})),
         dir.db());
  auto connection = open_read_only(dir.db());
  const std::string endless =
      "WITH RECURSIVE c(x, y) AS (SELECT 1, 2 UNION ALL SELECT x + 1, y FROM c) SELECT x, y FROM c";
  try {
    run_read_only_query(connection, dir.db(), endless, 1000);
    FAIL() << "no error";
  } catch (const InvalidInput& error) {
    ASSERT_EQ(error.errors().size(), 1u);
    EXPECT_EQ(error.errors()[0].path, "SQL");
    EXPECT_EQ(error.errors()[0].problem, "the result holds more than 1000 values");
    EXPECT_EQ(error.errors()[0].fix, "add a LIMIT, or select fewer rows or columns");
  }
  EXPECT_EQ(run_read_only_query(connection, dir.db(), endless + " LIMIT 500", 1000).rows.size(),
            500u);
}

// ... and so do a few large values: 41 of zeroblob(1e9) had few values and no end of memory.
TEST(Store, QueryRefusesAResultOfMoreBytesThanItHolds) {
  ScratchDir dir;
  submit(test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})), dir.db());
  auto connection = open_read_only(dir.db());
  const auto problem = [&](const std::string& sql) -> std::string {
    try {
      run_read_only_query(connection, dir.db(), sql, kMaxQueryValues, 2500);
    } catch (const InvalidInput& error) {
      return error.errors()[0].problem;
    }
    return "no error";
  };
  EXPECT_EQ(problem("SELECT zeroblob(1000) FROM (VALUES (1), (2), (3))"),
            "the result holds more than 2500 bytes of text");
  EXPECT_EQ(problem("SELECT zeroblob(3000)"), "a value of the result is longer than 2500 bytes");
  EXPECT_EQ(problem("SELECT zeroblob(1000) FROM (VALUES (1), (2))"), "no error");
}

TEST(CoordinatorLock, SecondCoordinatorIsRefusedWithTheHoldersName) {
  ScratchDir dir;
  const SystemClock clock;
  CoordinatorLock first(dir.db());
  Store store(dir.db(), {}, clock);
  store.set_coordinator(::getpid(), "testhost", "campaign-a");
  try {
    CoordinatorLock second(dir.db());
    FAIL() << "two coordinators on one database";
  } catch (const CoordinatorBusy& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("pid " + std::to_string(::getpid())), std::string::npos) << message;
    EXPECT_NE(message.find("testhost"), std::string::npos) << message;
  }
}

TEST(CoordinatorLock, StaleLockOfADeadProcessIsTakenOver) {
  ScratchDir dir;
  const SystemClock clock;
  const pid_t child = ::fork();
  if (child == 0) {  // a coordinator that dies holding the database
    CoordinatorLock lock(dir.db());
    Store store(dir.db(), {}, clock);
    store.set_coordinator(::getpid(), "deadhost", "campaign-b");
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  CoordinatorLock taken(dir.db());
  ASSERT_TRUE(taken.stale_holder().has_value());
  EXPECT_NE(taken.stale_holder()->find("pid " + std::to_string(child)), std::string::npos)
      << *taken.stale_holder();
}

TEST(Store, StatusAndQueryAnswerWhileACampaignRuns) {
  ScratchDir dir;
  json tasks = json::array();
  for (int i = 0; i < 20; ++i)
    tasks.push_back({{"id", std::to_string(i)}, {"kind", "sleep"}, {"params", {{"ms", 20 + i}}}});
  std::thread coordinator([&] { submit(test_campaign("busy", tasks), dir.db(), 2); });
  int answers = 0;
  bool saw_running_coordinator = false;
  while (answers < 200) {
    if (std::filesystem::exists(dir.db())) {
      try {
        std::ostringstream out;
        print_status(dir.db(), "", out);
        saw_running_coordinator |= out.str().find("coordinator: pid") != std::string::npos;
        if (count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'done'") == 20) break;
        ++answers;
      } catch (const std::exception&) {
        // the schema may not exist yet in the first milliseconds
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  coordinator.join();
  EXPECT_TRUE(saw_running_coordinator);
  EXPECT_GT(answers, 5);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'done'"), 20);
}

}  // namespace
}  // namespace millflow::engine::testing
