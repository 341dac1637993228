// The report kind over hand-made upscale results (2 fills x 2 speeds x 2 loads): every file, the
// CSV rows, the page's links, and the same bytes on a second run.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "tasks/report.hpp"
#include "tests/common/scratch_dir.hpp"
#include "tests/tasks/upscale_inputs.hpp"

namespace millflow::tasks {
namespace {

std::vector<engine::TaskInput> upscale_inputs() {
  std::vector<engine::TaskInput> inputs;
  for (double fill : {0.2, 0.35}) {
    for (double speed : {0.65, 0.8}) {
      for (double load : {0.0, 1.0}) {
        inputs.push_back({.key = fmt::format("up-{}-{}-{}", fill, speed, load),
                          .kind = "upscale",
                          .result = testing::upscale(testing::point_inputs(fill, speed, fill + speed), load),
                          .artifacts = {}});
      }
    }
  }
  return inputs;
}

engine::TaskOutcome report(const std::vector<engine::TaskInput>& inputs, const std::filesystem::path& dir) {
  const nlohmann::json params = {{"campaign", "tiny"}};
  engine::TaskContext context{.key = "report-key", .params = params, .inputs = inputs, .work_dir = dir, .threads = 1,
                              .stop = {}, .progress = [](double, std::string_view) {}, .log = [](std::string_view) {}};
  return run_report(context);
}

std::string read(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::size_t lines(const std::string& text) { return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')); }

TEST(Report, WritesEveryFigureAndTableAndLinksThemFromThePage) {
  const millflow::testing::ScratchDir scratch;
  const auto outcome = report(upscale_inputs(), scratch.path() / "a");
  // power draw + 3 figures for each of 4 fill/speed points + 3 CSV + index.md
  ASSERT_EQ(outcome.artifacts.size(), 1u + 3u * 4u + 3u + 1u);
  const std::string page = read(scratch.path() / "a" / "index.md");
  for (const auto& artifact : outcome.artifacts) {
    EXPECT_TRUE(std::filesystem::exists(artifact.file)) << artifact.name;
    if (artifact.name == "index.md") continue;
    EXPECT_NE(page.find("(" + artifact.name + ")"), std::string::npos) << artifact.name;
  }
  EXPECT_EQ(outcome.result.at("points"), 8);
  // Rows: 2 regions per point, 3 sites per point, 2 energy bins per point, plus the header.
  EXPECT_EQ(lines(read(scratch.path() / "a" / "upscaled.csv")), 1u + 8u * 2u);
  EXPECT_EQ(lines(read(scratch.path() / "a" / "sites.csv")), 1u + 8u * 3u);
  EXPECT_EQ(lines(read(scratch.path() / "a" / "spectra.csv")), 1u + 8u * 2u);
  // Sorted by fill, speed, load; the toe dominates every loaded point of these inputs.
  const std::string upscaled = read(scratch.path() / "a" / "upscaled.csv");
  EXPECT_EQ(upscaled.substr(upscaled.find('\n') + 1, 20), "0.2,0.65,0,toe,1,0.0");
  EXPECT_NE(page.find("| 0.35 | 0.8 | 1 | 1150 | 1437.5 | 1.1 | toe |"), std::string::npos) << page;
}

TEST(Report, SameInputsGiveTheSameBytesInAnyOrder) {
  const millflow::testing::ScratchDir scratch;
  auto inputs = upscale_inputs();
  const auto first = report(inputs, scratch.path() / "a");
  std::reverse(inputs.begin(), inputs.end());
  report(inputs, scratch.path() / "b");
  for (const auto& artifact : first.artifacts) {
    EXPECT_EQ(read(scratch.path() / "a" / artifact.name), read(scratch.path() / "b" / artifact.name)) << artifact.name;
  }
}

TEST(Report, RefusesACampaignWithoutUpscaleResults) {
  const millflow::testing::ScratchDir scratch;
  EXPECT_THROW(report({}, scratch.path() / "a"), std::invalid_argument);
}

}  // namespace
}  // namespace millflow::tasks
