// The command line under hostile input and faults (issue: "the engine under faults and hostile
// input"): unusable database paths, a second name for the database (symbolic and hard links), a
// coordinator that died, damaged databases, values no run can use, and the exit codes and
// messages of each. Every refusal is exit 2 with the offending path and a fix, and writes nothing.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "engine/store.hpp"
#include "millflow_build_info.hpp"
#include "tests/common/child_process.hpp"
#include "tests/common/running_tasks.hpp"
#include "tests/common/scratch_dir.hpp"

namespace millflow::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

class HostileInput : public ::testing::Test {
 protected:
  fs::path write_campaign(const std::string& name, const json& tasks,
                          const std::string& file_name = "") {
    const fs::path file = dir_.path() / ((file_name.empty() ? name : file_name) + ".json");
    std::ofstream(file) << json{
        {"format", "millflow-test"},
        {"name", name},
        {"tasks", tasks}}.dump();
    return file;
  }
  fs::path quick_campaign() {
    return write_campaign(
        "quick",
        json::array(
            {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}, {"artifact", true}}}}}));
  }
  // Two sleepers that run until interrupted.
  fs::path long_campaign() {
    return write_campaign(
        "long", json::array({{{"id", "0"}, {"kind", "sleep"}, {"params", {{"ms", 30000}}}},
                             {{"id", "1"}, {"kind", "sleep"}, {"params", {{"ms", 30001}}}}}));
  }
  Finished millflow(const std::vector<std::string>& arguments) {
    return run_millflow(arguments, output_);
  }
  // The files under the scratch directory other than the campaign files and captured output.
  std::vector<std::string> written() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_.path())) {
      const auto name = entry.path().filename().string();
      if (!name.ends_with(".json") && name != "output") names.push_back(name);
    }
    std::sort(names.begin(), names.end());
    return names;
  }
  // Starts the long campaign on `db` and waits until both of its tasks run.
  pid_t start_long_coordinator(const fs::path& db) {
    const pid_t coordinator =
        spawn_millflow({"submit", long_campaign().string(), "--db", db.string(), "--jobs", "2"});
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (running_tasks(db) < 2 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    return coordinator;
  }
  void SetUp() override { fs::create_directories(output_); }

  ScratchDir dir_;
  fs::path output_ = dir_.path() / "output";
};

TEST_F(HostileInput, UnusableDatabasePathsAreRefusedBeforeAnythingIsWritten) {
  const auto campaign = quick_campaign();
  const auto empty = millflow({"submit", campaign.string(), "--db", ""});
  EXPECT_EQ(empty.exit_code, 2);
  EXPECT_EQ(
      empty.err,
      "millflow: invalid input:\n--db: the database path is empty; name a database file, e.g. "
      "--db campaigns/mill.db\n");
  const auto directory = millflow({"submit", campaign.string(), "--db", dir_.path().string()});
  EXPECT_EQ(directory.exit_code, 2);
  EXPECT_NE(directory.err.find("--db: \"" + dir_.path().string() +
                               "\" is a directory, not a database file"),
            std::string::npos)
      << directory.err;
  const auto under_a_file =
      millflow({"submit", campaign.string(), "--db", (campaign / "mill.db").string()});
  EXPECT_EQ(under_a_file.exit_code, 2);  // was 1, a filesystem_error
  EXPECT_EQ(under_a_file.err, "millflow: invalid input:\n--db: cannot create the directory " +
                                  fs::weakly_canonical(campaign).string() +
                                  ": Not a directory; name a database in a directory you can "
                                  "write\n");
  const auto missing = (dir_.path() / "missing.db").string();
  for (const char* command : {"status", "gc", "resume", "query"}) {
    std::vector<std::string> arguments{command};
    if (std::string(command) == "query") arguments.push_back("SELECT 1");
    arguments.insert(arguments.end(), {"--db", missing});
    const auto refused = millflow(arguments);
    EXPECT_EQ(refused.exit_code, 2) << command;
    EXPECT_EQ(refused.err, "millflow: invalid input:\n--db: no database at \"" + missing +
                               "\"; submit a campaign first, or pass the --db of an existing "
                               "database\n")
        << command;
  }
  EXPECT_EQ(written(), std::vector<std::string>{});
}

// The lock used to be named from the path given: a symbolic link reached a second lock, and two
// coordinators ran the same tasks at once.
TEST_F(HostileInput, ASymbolicLinkToTheDatabaseReachesTheSameLock) {
  const fs::path db = dir_.path() / "real.db";
  const fs::path link = dir_.path() / "link.db";
  ASSERT_EQ(millflow({"submit", quick_campaign().string(), "--db", db.string()}).exit_code, 0);
  fs::create_symlink(db, link);
  const pid_t coordinator = start_long_coordinator(db);
  ASSERT_EQ(running_tasks(db), 2);
  const auto second = millflow({"submit", long_campaign().string(), "--db", link.string()});
  EXPECT_EQ(second.exit_code, 3) << second.err;
  EXPECT_NE(
      second.err.find("in use by another millflow coordinator: pid " + std::to_string(coordinator)),
      std::string::npos)
      << second.err;
  ::kill(coordinator, SIGINT);
  EXPECT_EQ(wait_exit_code(coordinator), 130);
  // Through the link, everything beside the database is found beside the real file.
  ASSERT_EQ(millflow({"submit", quick_campaign().string(), "--db", link.string()}).exit_code, 0);
  EXPECT_FALSE(fs::exists(dir_.path() / "link.db.lock"));
  EXPECT_FALSE(fs::exists(dir_.path() / "link.db.artifacts"));
  EXPECT_FALSE(fs::exists(dir_.path() / "link.db.logs"));
}

// A hard link cannot be told from the real name: a database with two names is refused.
TEST_F(HostileInput, ADatabaseWithTwoHardLinksIsRefused) {
  const fs::path db = dir_.path() / "real.db";
  const fs::path link = dir_.path() / "hard.db";
  ASSERT_EQ(millflow({"submit", quick_campaign().string(), "--db", db.string()}).exit_code, 0);
  fs::create_hard_link(db, link);
  for (const auto& name : {link, db}) {
    const auto refused = millflow({"resume", "--db", name.string()});
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_EQ(refused.err,
              "millflow: invalid input:\n--db: \"" + name.string() +
                  "\" has 2 hard links: millflow locks a database by its name, so two names would "
                  "let two coordinators write it at once; keep one name (remove the other hard "
                  "links; `find / -samefile` lists them) or work on a copy\n");
  }
  EXPECT_FALSE(fs::exists(dir_.path() / "hard.db.lock"));
  fs::remove(link);
  EXPECT_EQ(millflow({"resume", "--db", db.string()}).exit_code, 0);
}

TEST_F(HostileInput, StatusTellsACoordinatorThatDiedAndTheNextOneSaysItTookOver) {
  const fs::path db = dir_.path() / "died.db";
  const pid_t coordinator = start_long_coordinator(db);
  ASSERT_EQ(running_tasks(db), 2);
  const auto alive = millflow({"status", "--db", db.string()});
  EXPECT_NE(alive.out.find("coordinator: pid " + std::to_string(coordinator) + " on "),
            std::string::npos)
      << alive.out;
  ::kill(coordinator, SIGKILL);
  EXPECT_EQ(wait_exit_code(coordinator), -SIGKILL);
  const auto dead = millflow({"status", "--db", db.string()});
  EXPECT_EQ(dead.exit_code, 0);
  EXPECT_NE(dead.out.find("coordinator: not running (last coordinator pid " +
                          std::to_string(coordinator) + " died)\n"),
            std::string::npos)
      << dead.out;
  EXPECT_NE(dead.out.find("long      interrupted"), std::string::npos) << dead.out;
  EXPECT_EQ(dead.out.find("running", dead.out.find("not running") + 11), std::string::npos)
      << dead.out;
  // ... and so are its tasks: they were shown running until the next resume.
  const auto tasks = millflow({"status", "long", "--db", db.string()});
  EXPECT_EQ(tasks.out.find("running", tasks.out.find("not running") + 11), std::string::npos)
      << tasks.out;
  EXPECT_NE(tasks.out.find("interrupted  2"), std::string::npos) << tasks.out;
  // `show` says so too, and gives no duration for the attempt that never ended.
  const auto keys = millflow({"query", "SELECT key FROM tasks WHERE status = 'running'", "--format",
                              "csv", "--db", db.string()});
  const std::string key = keys.out.substr(4, keys.out.find('\n', 4) - 4);  // after "key\n"
  const auto shown = millflow({"show", key, "--db", db.string()});
  EXPECT_NE(shown.out.find("status interrupted after 1 attempt(s)\n"), std::string::npos)
      << shown.out;
  EXPECT_NE(shown.out.find(" duration - host "), std::string::npos) << shown.out;

  // The warning of the take-over is printed on the terminal.
  const auto resumed = millflow({"submit", quick_campaign().string(), "--db", db.string()});
  EXPECT_NE(resumed.err.find("millflow: warning: took over the database from a coordinator that "
                             "is gone: pid " +
                             std::to_string(coordinator)),
            std::string::npos)
      << resumed.err;
}

TEST_F(HostileInput, DamagedDatabasesAreBadInputNamingTheFile) {
  const fs::path db = dir_.path() / "noise.db";
  std::ofstream(db) << std::string(8192, 'x');
  const auto campaign = quick_campaign();
  for (const std::vector<std::string>& command : {std::vector<std::string>{"status"},
                                                  {"query", "SELECT 1"},
                                                  {"resume"},
                                                  {"submit", campaign.string()},
                                                  {"gc"}}) {
    auto arguments = command;
    arguments.insert(arguments.end(), {"--db", db.string()});
    const auto refused = millflow(arguments);
    EXPECT_EQ(refused.exit_code, 2) << command[0];
    EXPECT_NE(
        refused.err.find("--db: " + db.string() + " is not a readable millflow database (SQLite: "),
        std::string::npos)
        << refused.err;
    EXPECT_EQ(refused.err.find("check the SQL"), std::string::npos) << refused.err;
  }
  // submit and gc found the file unreadable only after creating its lock file.
  EXPECT_EQ(written(), std::vector<std::string>{"noise.db"});
}

// Both were exit 1: SQLite's "attempt to write a readonly database" from the first view the store
// installed, and from the first read of a read-only connection that needed the -shm file.
TEST_F(HostileInput, ADatabaseThatCannotBeWrittenIsRefusedNamingIt) {
  if (::geteuid() == 0) GTEST_SKIP() << "permissions do not hold for root";
  const fs::path db = dir_.path() / "kept.db";
  ASSERT_EQ(millflow({"submit", quick_campaign().string(), "--db", db.string()}).exit_code, 0);
  fs::permissions(db, fs::perms::owner_write, fs::perm_options::remove);
  const auto resumed = millflow({"resume", "--db", db.string()});
  EXPECT_EQ(resumed.exit_code, 2);
  EXPECT_EQ(resumed.err, "millflow: invalid input:\n--db: cannot write " + db.string() +
                             ": Permission denied; make it writable (chmod u+w), or submit to a "
                             "copy of it\n");

  const fs::path shelf = dir_.path() / "shelf";
  fs::create_directories(shelf);
  fs::copy_file(db, shelf / "kept.db");  // without its -shm file
  fs::permissions(shelf, fs::perms::owner_write, fs::perm_options::remove);
  const auto status = millflow({"status", "--db", (shelf / "kept.db").string()});
  fs::permissions(shelf, fs::perms::owner_write, fs::perm_options::add);
  EXPECT_EQ(status.exit_code, 2);
  EXPECT_NE(status.err.find("--db: " + (shelf / "kept.db").string() +
                            " cannot be read where it is: SQLite needs to create "),
            std::string::npos)
      << status.err;
}

TEST_F(HostileInput, ValuesNoRunCanUseAreExitTwoWithThePathAndAFix) {
  const fs::path huge = dir_.path() / "huge.json";
  std::ofstream(huge)
      << R"({"format": "millflow-test", "name": "n", "tasks": [{"id": "a", "kind": "sum", "params": {"value": 1e400}}]})";
  const auto overflow = millflow({"validate", huge.string()});
  EXPECT_EQ(overflow.exit_code, 2);
  EXPECT_EQ(overflow.err,
            "millflow: invalid input:\n/tasks/0/params/value: number overflow parsing '1e400'; "
            "write a number a double can hold (magnitude below 1.8e308)\n");

  const fs::path db = dir_.path() / "names.db";
  const auto long_name = write_campaign(std::string(10000, 'n'), json::array(), "long-name");
  const auto too_long = millflow({"submit", long_name.string(), "--db", db.string()});
  EXPECT_EQ(too_long.exit_code, 2);
  EXPECT_EQ(too_long.err,
            "millflow: invalid input:\n/name: the campaign name has 10000 characters, more than "
            "200; use a shorter name (it names the campaign's log file)\n");
  EXPECT_FALSE(fs::exists(db));

  const auto start = std::chrono::steady_clock::now();
  const auto zero = millflow({"validate", "/dev/zero"});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
  EXPECT_EQ(zero.exit_code, 2);
  EXPECT_EQ(zero.err,
            "millflow: invalid input:\n(document): /dev/zero is not a regular file; pass a "
            "campaign JSON file\n");

  const auto campaign = quick_campaign();
  const auto jobs = millflow({"submit", campaign.string(), "--jobs", "0", "--db", db.string()});
  EXPECT_EQ(jobs.exit_code, 2);
  EXPECT_EQ(jobs.err.substr(0, jobs.err.find('\n')), "--jobs: Value 0 not in range 1 to 1024");
  const auto poll =
      millflow({"submit", campaign.string(), "--poll-interval", "nan", "--db", db.string()});
  EXPECT_EQ(poll.exit_code, 2);
  EXPECT_EQ(poll.err.substr(0, poll.err.find('\n')),
            "--poll-interval: nan s is outside [0.1, 86400] s");
  // An empty kind is no kind (it read as no --until at all).
  const auto until = millflow({"submit", campaign.string(), "--until", "", "--db", db.string()});
  EXPECT_EQ(until.exit_code, 2);
  EXPECT_NE(until.err.find("--until: \"\" is not a task kind"), std::string::npos) << until.err;
  EXPECT_FALSE(fs::exists(db));
  // NaN passed CLI11's ranges: the demo aborted on a NaN fill and ran nothing for NaN revolutions.
  for (const std::string option : {"--fill", "--speed", "--revolutions"}) {
    const auto demo = millflow({"demo", option, "nan"});
    EXPECT_EQ(demo.exit_code, 2) << option;
    EXPECT_EQ(demo.err.substr(0, demo.err.find(" is outside")), option + ": nan") << option;
  }

  ASSERT_EQ(millflow({"submit", campaign.string(), "--db", db.string()}).exit_code, 0);
  const fs::path file = dir_.path() / "a-file";
  std::ofstream(file) << "x";
  const auto out =
      millflow({"export", "quick", "--format", "csv", "--out", file.string(), "--db", db.string()});
  EXPECT_EQ(out.exit_code, 2);
  EXPECT_EQ(out.err, "millflow: invalid input:\n--out: \"" + file.string() +
                         "\" is not a directory; pass a directory (it is created when missing)\n");
  const auto under = millflow({"export", "quick", "--format", "csv", "--out",
                               (file / "csv").string(), "--db", db.string()});
  EXPECT_EQ(under.exit_code, 2);  // was 1, a filesystem_error from creating it
  EXPECT_EQ(under.err, out.err);
}

TEST_F(HostileInput, ATaskSpecThatIsNotAnObjectIsNamedAsNotATaskSpec) {
  for (const char* text : {R"([1, 2])", R"("text")", R"({"millflow_attempt": "1"})"}) {
    const fs::path spec = dir_.path() / "spec.json";
    std::ofstream(spec) << text;
    const auto refused = millflow({"exec", spec.string()});
    EXPECT_EQ(refused.exit_code, 2) << text;
    EXPECT_EQ(refused.err, "millflow exec: /millflow_attempt: " + spec.string() +
                               " is not a version 1 task-spec file; run the millflow that wrote "
                               "it\n")
        << text;
  }
}

// exec read /dev/zero until the kernel killed it for memory.
TEST_F(HostileInput, ATaskSpecThatIsNotARegularFileIsRefusedAtOnce) {
  const auto start = std::chrono::steady_clock::now();
  const auto zero = millflow({"exec", "/dev/zero"});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
  EXPECT_EQ(zero.exit_code, 2);
  EXPECT_EQ(
      zero.err,
      "millflow exec: (document): task-spec file /dev/zero cannot be read: /dev/zero is not a "
      "regular file; pass a spec file written by the millflow coordinator\n");
}

TEST_F(HostileInput, VersionNamesTheReleaseTheCommitAndTheInstructionSet) {
  const auto version = millflow({"--version"});
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(version.out, fmt::format("millflow {} (git {}, instruction set {})\n", MILLFLOW_VERSION,
                                     MILLFLOW_GIT_VERSION, MILLFLOW_INSTRUCTION_SET));
}

}  // namespace
}  // namespace millflow::testing
