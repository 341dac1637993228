// `millflow cell SPEC.json --out DIR`: one shear cell outside a campaign, its spec validated with
// the campaign's field table and messages, its result JSON alone on stdout.
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "tests/common/child_process.hpp"
#include "tests/common/scratch_dir.hpp"

namespace millflow::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A small media-only Lees-Edwards cell that runs in about a second.
json tiny_spec() {
  return json::parse(R"({
    "materials": {"steel": {"density": 7800}, "clinker": {"density": 3150}},
    "interactions": [
      {"materials": ["steel", "steel"], "restitution": 0.5, "friction": 0.5, "stiffness": {"collision_time": 0.001}},
      {"materials": ["steel", "clinker"], "restitution": 0.5, "friction": 0.5, "stiffness": {"collision_time": 0.001}},
      {"materials": ["clinker", "clinker"], "restitution": 0.5, "friction": 0.5, "stiffness": {"collision_time": 0.001}}],
    "media": {"material": "steel", "diameter": 0.01},
    "shear_cell": {"boundary": "lees_edwards", "size_diameters": [4, 4, 4],
                   "warmup_strain": 0.5, "max_warmup_strain": 0.5, "measure_strain": 0.5,
                   "convergence": {"max_strain": 0.5}, "steps_per_collision": 20,
                   "powder": {"material": "clinker", "diameter_ratio": 0.5, "load": 0}},
    "shear_rate": 20,
    "normal_stress": 2000
  })");
}

class CellCommand : public ::testing::Test {
 protected:
  fs::path write_spec(const json& spec) {
    const fs::path file = dir_.path() / "spec.json";
    std::ofstream(file) << spec.dump(2);
    return file;
  }
  ScratchDir dir_;
};

TEST_F(CellCommand, BadSpecIsRefusedWithTheCampaignsMessagesAndExitTwo) {
  json spec = tiny_spec();
  spec.erase("shear_rate");
  spec["normal_stress"] = -1;
  spec["shear_cell"]["convergence"]["max_strain"] = 0.1;
  const auto out = dir_.path() / "out";
  const auto finished =
      run_millflow({"cell", write_spec(spec).string(), "--out", out.string()}, dir_.path());
  EXPECT_EQ(finished.exit_code, 2);
  EXPECT_EQ(finished.out, "");
  EXPECT_EQ(
      finished.err,
      "millflow: invalid input:\n"
      "/shear_rate: required field is missing; add the cell's target shear rate, a number in "
      "[0.01, 10000] 1/s\n"
      "/normal_stress: -1 Pa is out of range; the normal stress the cell imposes must be in [1, "
      "100000000] Pa\n"
      "/shear_cell/convergence/max_strain: 0.1 is below /shear_cell/measure_strain = 0.5; "
      "raise it to at least 0.5 or lower /shear_cell/measure_strain\n");
  EXPECT_FALSE(fs::exists(out));
}

// The cell's --out was not checked: a file there was exit 1, a filesystem_error.
TEST_F(CellCommand, AnOutputDirectoryUnderAFileIsRefusedWithExitTwo) {
  const auto file = dir_.path() / "a-file";
  std::ofstream(file) << "x";
  const auto finished = run_millflow(
      {"cell", write_spec(tiny_spec()).string(), "--out", (file / "cell").string()}, dir_.path());
  EXPECT_EQ(finished.exit_code, 2);
  EXPECT_EQ(finished.err, "millflow: invalid input:\n--out: \"" + file.string() +
                              "\" is not a directory; pass a directory (it is created when "
                              "missing)\n");
}

TEST_F(CellCommand, PrintsTheCellsResultAndLeavesItsFilesInTheOutputDirectory) {
  const auto out = dir_.path() / "out";
  const auto finished =
      run_millflow({"cell", write_spec(tiny_spec()).string(), "--out", out.string()}, dir_.path());
  ASSERT_EQ(finished.exit_code, 0) << finished.err;
  const json result = json::parse(finished.out);
  EXPECT_EQ(result.at("site").at("shear_rate_per_s"), 20.0);
  EXPECT_EQ(result.at("site").at("normal_stress_pa"), 2000.0);
  EXPECT_EQ(result.at("powder_count"), 0);
  EXPECT_GT(result.at("friction").get<double>(), 0.0);
  EXPECT_TRUE(result.contains("standard_errors"));
  EXPECT_TRUE(result.at("stiffness").contains("media-media"));
  EXPECT_TRUE(fs::exists(out / "cell.vtp"));
  EXPECT_FALSE(fs::exists(out / "cell.ckpt"));
  EXPECT_NE(finished.err.find("shear cell stiffness at sigma_n 2000 Pa"), std::string::npos);
}

// --threads sets the cell's threads, and its result is the same bytes at 1 and 2 (with powder, so
// that the per-particle passes and the sums run in several blocks). Its stderr names each phase
// as it starts and carries the status line (plain lines: stderr is not a terminal here).
TEST_F(CellCommand, GivesTheSameResultAtOneAndTwoThreadsAndShowsItsPhases) {
  json spec = tiny_spec();
  spec["shear_cell"]["powder"]["load"] = 1.0;
  spec["shear_cell"]["powder"]["diameter_ratio"] = 0.25;
  for (const char* strain : {"warmup_strain", "max_warmup_strain", "measure_strain"})
    spec["shear_cell"][strain] = 0.2;
  spec["shear_cell"]["convergence"]["max_strain"] = 0.2;
  const std::string file = write_spec(spec).string();
  const auto run = [&](const std::string& threads) {
    return run_millflow(
        {"cell", file, "--out", (dir_.path() / threads).string(), "--threads", threads},
        dir_.path());
  };
  const auto one = run("1"), two = run("2");
  ASSERT_EQ(one.exit_code, 0) << one.err;
  ASSERT_EQ(two.exit_code, 0) << two.err;
  EXPECT_GT(json::parse(one.out).at("powder_count").get<int>(), 2048);
  EXPECT_EQ(one.out, two.out);
  for (const char* line : {"\nshear cell: compacting\n", "\nshear cell: warm-up window 1 (at most ",
                           "\nshear cell: measuring\n", " shear_cell 0/1 shear_cell:cell "}) {
    EXPECT_NE(one.err.find(line), std::string::npos) << line << " in\n" << one.err;
  }
}

// SIGTERM (or Ctrl-C) stops the cell at a checkpoint with exit 130, and the same command
// continues it. The signal used to end it at once (143), keeping only its last periodic
// checkpoint.
TEST_F(CellCommand, ASigtermStopsTheCellAtACheckpointThatTheSameCommandContinues) {
  json spec = tiny_spec();
  spec["shear_cell"]["measure_strain"] = 50;  // long enough to be caught running
  spec["shear_cell"]["convergence"]["max_strain"] = 50;
  const auto out = dir_.path() / "out";
  const auto err = dir_.path() / "first.err";
  const auto file = write_spec(spec);
  const pid_t cell = spawn_millflow({"cell", file.string(), "--out", out.string()},
                                    dir_.path() / "first.out", err);
  for (int wait = 0; wait < 300 && read_text(err).find("stiffness") == std::string::npos; ++wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ::kill(cell, SIGTERM);
  EXPECT_EQ(wait_exit_code(cell), 130) << read_text(err);
  EXPECT_NE(read_text(err).find("millflow: interrupted; the cell's checkpoint is in "),
            std::string::npos);
  EXPECT_TRUE(fs::exists(out / "cell.ckpt"));

  const auto again_err = dir_.path() / "again.err";
  const pid_t again = spawn_millflow({"cell", file.string(), "--out", out.string()},
                                     dir_.path() / "again.out", again_err);
  for (int wait = 0; wait < 300 && read_text(again_err).find("continuing from the checkpoint") ==
                                       std::string::npos;
       ++wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ::kill(again, SIGTERM);
  EXPECT_EQ(wait_exit_code(again), 130);
  EXPECT_NE(read_text(again_err).find("shear cell: continuing from the checkpoint at step "),
            std::string::npos)
      << read_text(again_err);
}

}  // namespace
}  // namespace millflow::testing
