// The executor block of a campaign file as the command line reads it for every format (the
// millflow campaign format's own field table checks it before; the test format relies on this).
#include <gtest/gtest.h>

#include "cli/executor_choice.hpp"
#include "engine/validation.hpp"

namespace millflow::cli {
namespace {

using nlohmann::json;

std::vector<std::string> messages_of(const json& document) {
  try {
    choose_executor(document, "");
  } catch (const engine::InvalidInput& error) {
    std::vector<std::string> messages;
    for (const auto& e : error.errors()) messages.push_back(e.message());
    return messages;
  }
  return {};
}

TEST(ExecutorChoice, ReadsTheSlurmBlockAndKeepsDefaultsForWhatItLeavesOut) {
  const auto choice = choose_executor(
      {{"executor",
        {{"kind", "slurm"},
         {"slurm",
          {{"partition", "short"}, {"checkpoint_signal_s", 600}, {"max_squeue_failures", 5}}}}}},
      "");
  EXPECT_EQ(choice.kind, "slurm");
  EXPECT_EQ(choice.slurm.partition, "short");
  EXPECT_EQ(choice.slurm.checkpoint_signal_s, 600);
  EXPECT_EQ(choice.slurm.max_squeue_failures, 5);
  EXPECT_EQ(choice.slurm.max_in_flight, engine::SlurmSettings{}.max_in_flight);
  EXPECT_EQ(
      choose_executor({{"executor", {{"slurm", json::object()}}}}, "").slurm.checkpoint_signal_s,
      300);
  EXPECT_EQ(choose_executor({{"executor", {{"kind", "slurm"}}}}, "local").kind, "local");
}

TEST(ExecutorChoice, ReadsEachKindsOwnResources) {
  const auto choice =
      choose_executor({{"executor",
                        {{"slurm",
                          {{"time_limit", "30"},
                           {"per_kind",
                            {{"macro", {{"time_limit", "4:00:00"}, {"cpus_per_task", 8}}},
                             {"shear_cell", {{"memory", "2G"}}}}}}}}}},
                      "");
  EXPECT_EQ(choice.slurm.time_limit, "30");
  ASSERT_EQ(choice.slurm.per_kind.size(), 2u);
  EXPECT_EQ(choice.slurm.per_kind.at("macro").time_limit, "4:00:00");
  EXPECT_EQ(choice.slurm.per_kind.at("macro").cpus_per_task, 8);
  EXPECT_EQ(choice.slurm.per_kind.at("shear_cell").memory, "2G");
  EXPECT_EQ(choice.slurm.per_kind.at("shear_cell").cpus_per_task, 0);  // the campaign-wide one
  EXPECT_EQ(
      messages_of({{"executor", {{"slurm", {{"per_kind", {{"macro", {{"cpus_per_task", 0}}}}}}}}}}),
      (std::vector<std::string>{"/executor/slurm/per_kind/macro/cpus_per_task: must be a "
                                "positive integer, got 0; fix the campaign file's executor "
                                "block"}));
}

TEST(ExecutorChoice, OutOfRangeOrMistypedSettingsNameTheirPath) {
  EXPECT_EQ(messages_of({{"executor",
                          {{"slurm",
                            {{"checkpoint_signal_s", 0},
                             {"max_squeue_failures", 2.5},
                             {"max_in_flight", -1},
                             {"extra_args", {"--qos=low", 3}}}}}}}),
            (std::vector<std::string>{"/executor/slurm/max_in_flight: must be a positive integer, "
                                      "got -1; fix the campaign file's executor block",
                                      "/executor/slurm/checkpoint_signal_s: must be an integer in "
                                      "[1, 65535], got 0; fix the campaign file's "
                                      "executor block",
                                      "/executor/slurm/max_squeue_failures: must be a positive "
                                      "integer, got 2.5; fix the campaign file's "
                                      "executor block",
                                      "/executor/slurm/extra_args: must be an array of strings, "
                                      "got [\"--qos=low\",3]; fix the campaign file's "
                                      "executor block"}));
  EXPECT_EQ(messages_of({{"executor", {{"slurm", {{"checkpoint_signal_s", 65536}}}}}}),
            (std::vector<std::string>{
                "/executor/slurm/checkpoint_signal_s: must be an integer in [1, 65535], got "
                "65536; fix the campaign file's executor block"}));
}

}  // namespace
}  // namespace millflow::cli
