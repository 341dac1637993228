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
    EXPECT_NE(std::string(error.what()).find("schema version 99"), std::string::npos) << error.what();
  }
  EXPECT_THROW(open_read_only(dir.db()), SchemaTooNew);
  sql::Connection raw(dir.db(), sql::Access::read_only);
  EXPECT_EQ(raw.user_version(), 99);
}

// Version 3 added jobs.job_name: a version 2 database (built here by undoing that migration) is
// read as it is and migrated forward by the next writer, its job rows kept with an empty name.
TEST(Store, MigratesAVersion2DatabaseForward) {
  ScratchDir dir;
  const SystemClock clock;
  submit(test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})), dir.db());
  std::string key;
  {
    auto reader = open_read_only(dir.db());
    auto row = reader.prepare("SELECT key FROM tasks");
    ASSERT_TRUE(row.step());
    key = row.text(0);
  }
  {
    sql::Connection raw(dir.db(), sql::Access::read_write);
    raw.exec("ALTER TABLE jobs DROP COLUMN job_name");
    raw.exec("INSERT INTO jobs VALUES ('" + key + "', 1, 'slurm', '7_0', 'COMPLETED', '/run/b/0', '/run/b/0.out', "
             "'/run/b/0.err', 1, 2)");
    raw.exec("PRAGMA user_version = 2");
  }
  auto reader = open_read_only(dir.db());
  ASSERT_EQ(find_jobs(reader, key).size(), 1u);
  EXPECT_EQ(find_jobs(reader, key)[0].job_name, "");
  Store store(dir.db(), {}, clock);
  EXPECT_EQ(store.connection().user_version(), 3);
  const auto jobs = find_jobs(store.connection(), key);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job_id, "7_0");
  EXPECT_EQ(jobs[0].job_name, "");
  EXPECT_EQ(jobs[0].output_dir, "/run/b/0");
}

// A first submit killed before it created the schema leaves an empty file: readers (status,
// resume, query) say what happened instead of failing on a missing table.
TEST(Store, ReadersOfADatabaseWithoutTablesSayToSubmitAgain) {
  ScratchDir dir;
  { sql::Connection raw(dir.db(), sql::Access::read_write); }
  try {
    open_read_only(dir.db());
    FAIL() << "a database without tables was opened";
  } catch (const std::runtime_error& error) {
    EXPECT_EQ(std::string(error.what()),
              "the database " + dir.db().string() +
                  " has no millflow tables (nothing was submitted to it, or its first submit stopped before creating "
                  "them): submit the campaign again");
  }
}

// ... and a submit to it creates the schema: the coordinator lock's look at who held the database
// before must not refuse it (it did, so a crash test round killed that early failed for good).
TEST(Store, SubmitToADatabaseWithoutTablesCreatesThem) {
  ScratchDir dir;
  { sql::Connection raw(dir.db(), sql::Access::read_write); }
  EXPECT_EQ(submit(test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}}})), dir.db()).exit_code(), 0);
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'done'"), 1);
}

TEST(Store, DomainViewsAreInstalled) {
  ScratchDir dir;
  const SystemClock clock;
  Store store(dir.db(), {{"sum_results", "SELECT task_key, json_extract(result, '$.sum') AS sum FROM task_results"}}, clock);
  std::ostringstream out;
  run_query(dir.db(), "SELECT count(*) AS n FROM sum_results", TableFormat::csv, out);
  EXPECT_EQ(out.str(), "n\n0\n");
}

TEST(Store, QueryRefusesWrites) {
  ScratchDir dir;
  submit(test_campaign("one", json::array({{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}}}}})), dir.db());
  std::ostringstream out;
  for (const char* statement : {"DELETE FROM tasks", "UPDATE tasks SET status = 'failed'", "DROP TABLE results",
                                "INSERT INTO log_lines (at, level, message) VALUES (0, 'x', 'y')"}) {
    EXPECT_THROW(run_query(dir.db(), statement, TableFormat::table, out), InvalidInput) << statement;
  }
  EXPECT_EQ(count(dir.db(), "SELECT count(*) FROM tasks WHERE status = 'done'"), 1);
  run_query(dir.db(), "SELECT json_extract(result, '$.sum') AS s FROM task_results", TableFormat::json, out);
  EXPECT_EQ(json::parse(out.str()), json::parse(R"([{"s": 1}])"));
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
  EXPECT_NE(taken.stale_holder()->find("pid " + std::to_string(child)), std::string::npos) << *taken.stale_holder();
}

TEST(Store, StatusAndQueryAnswerWhileACampaignRuns) {
  ScratchDir dir;
  json tasks = json::array();
  for (int i = 0; i < 20; ++i) tasks.push_back({{"id", std::to_string(i)}, {"kind", "sleep"}, {"params", {{"ms", 20 + i}}}});
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
