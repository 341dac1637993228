// `millflow exec` in process: one attempt from its task-spec file to its output files, completion
// marker and exit code.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "engine/attempt_files.hpp"
#include "support_engine.hpp"
#include "util/sha256.hpp"

namespace millflow::engine::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Exec {
  int code;
  std::optional<AttemptOutcome> outcome;
  std::string log;
};

class AttemptFiles : public ::testing::Test {
 protected:
  AttemptSpec spec_of(const std::string& kind, json params, int attempt = 1) {
    AttemptSpec spec;
    spec.task = make_task_spec(kind, "1", std::move(params), {});
    spec.attempt = attempt;
    spec.work_dir = dir_.path() / "work";
    spec.output_dir = dir_.path() / "out";
    return spec;
  }
  Exec exec(const AttemptSpec& spec, bool stop = false) {
    const fs::path file = dir_.path() / "spec.json";
    write_attempt_spec(spec, file);
    return exec_file(file, stop, spec.task.key);
  }
  Exec exec_file(const fs::path& file, bool stop = false, const std::string& key = "") {
    std::ostringstream log;
    const int code = execute_attempt(
        registry_.kinds, file, [=] { return stop; }, log);
    return Exec{code, read_attempt_outcome(dir_.path() / "out", key, 1), log.str()};
  }

  ScratchDir dir_;
  Registry registry_ = testing_registry();
};

TEST_F(AttemptFiles, DoneWritesResultArtifactsAndAMarkerWithTheirDigests) {
  AttemptSpec spec = spec_of("sum", {{"value", 2}, {"artifact", true}});
  spec.inputs.push_back(TaskInput{"up", "sum", {{"sum", 3}}, {}});
  const auto run = exec(spec);
  EXPECT_EQ(run.code, kExecDone);
  ASSERT_TRUE(run.outcome && !run.outcome->error);
  EXPECT_EQ(run.outcome->outcome.result, json({{"sum", 5}}));
  const json marker = json::parse(std::ifstream(dir_.path() / "out" / "complete.json"));
  EXPECT_EQ(marker["result_sha256"], util::sha256_file_hex(dir_.path() / "out" / "result.json"));
  ASSERT_EQ(run.outcome->outcome.artifacts.size(), 1u);
  EXPECT_EQ(run.outcome->outcome.artifacts[0].name, "sum.txt");
  std::ifstream artifact(run.outcome->outcome.artifacts[0].file);
  int value = 0;
  artifact >> value;
  EXPECT_EQ(value, 5);
}

TEST_F(AttemptFiles, FailingTaskExitsOneAndItsMarkerHoldsTheError) {
  const auto run = exec(spec_of("fail", {{"failures", 1}}));
  EXPECT_EQ(run.code, kExecFailed);
  ASSERT_TRUE(run.outcome && run.outcome->error);
  EXPECT_NE(run.outcome->error->find("planned failure: attempt 1"), std::string::npos);
}

TEST_F(AttemptFiles, StopRequestExitsWithTheStoppedCode) {
  const auto run = exec(spec_of("sleep", {{"ms", 10000}}), true);
  EXPECT_EQ(run.code, kExecStopped);
  ASSERT_TRUE(run.outcome);
  EXPECT_TRUE(run.outcome->outcome.interrupted);
}

TEST_F(AttemptFiles, BadSpecFilesExitTwoWithoutAMarker) {
  std::ofstream(dir_.path() / "garbage.json") << "{\"millflow_attempt\": 1, \"key\": 3}";
  auto run = exec_file(dir_.path() / "garbage.json");
  EXPECT_EQ(run.code, kExecBadSpec);
  EXPECT_NE(run.log.find("is incomplete"), std::string::npos);
  AttemptSpec other_version = spec_of("sum", {{"value", 1}});
  other_version.task.version = "9";
  run = exec(other_version);
  EXPECT_EQ(run.code, kExecBadSpec);
  EXPECT_NE(run.log.find("version 1 in this millflow, the spec wants 9"), std::string::npos);
  EXPECT_FALSE(run.outcome);
}

}  // namespace
}  // namespace millflow::engine::testing
