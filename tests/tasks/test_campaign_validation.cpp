// Campaign files: the corpus of bad files with their exact messages (the message contract users
// see; tests/tasks/bad_campaigns/expected.json), good files loading and expanding to the right
// points, defaults, and loading writing nothing.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "tasks/campaign.hpp"

namespace {

namespace fs = std::filesystem;
using millflow::engine::InvalidInput;
using millflow::tasks::load_campaign;
using nlohmann::json;

const fs::path source_dir = MILLFLOW_SOURCE_DIR;
const fs::path corpus_dir = source_dir / "tests/tasks/bad_campaigns";

json expected_messages() {
  std::ifstream stream(corpus_dir / "expected.json");
  return json::parse(stream);
}

std::vector<std::string> messages_of(const fs::path& file) {
  try {
    load_campaign(file);
  } catch (const InvalidInput& error) {
    std::vector<std::string> messages;
    for (const auto& e : error.errors()) messages.push_back(e.message());
    return messages;
  }
  return {};
}

std::vector<fs::path> corpus_files() {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(corpus_dir)) {
    if (entry.path().extension() == ".json" && entry.path().filename() != "expected.json") {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(CampaignCorpus, EveryBadFileGivesExactlyItsExpectedMessages) {
  const auto expected = expected_messages();
  const auto files = corpus_files();
  ASSERT_GE(files.size(), 30U);
  for (const auto& file : files) {
    const auto name = file.filename().string();
    ASSERT_TRUE(expected.contains(name)) << name << " has no entry in expected.json";
    EXPECT_EQ(messages_of(file), expected[name]["messages"].get<std::vector<std::string>>())
        << name;
  }
  EXPECT_EQ(expected.size(), files.size()) << "expected.json names a file the corpus does not hold";
}

TEST(CampaignCorpus, CoversEveryKindOfMistake) {
  // The corpus must keep at least one file of each kind, and files with several errors.
  std::map<std::string, int> levels;
  std::size_t most_messages = 0;
  const auto expected = expected_messages();
  for (const auto& [name, entry] : expected.items()) {
    ++levels[entry["level"].get<std::string>()];
    most_messages = std::max(most_messages, entry["messages"].size());
  }
  EXPECT_GE(levels["syntax"], 1);
  EXPECT_GE(levels["schema"], 10);
  EXPECT_GE(levels["semantic"], 10);
  EXPECT_GE(most_messages, 3U);
}

std::set<std::pair<std::string, fs::file_time_type>> snapshot(const fs::path& directory) {
  std::set<std::pair<std::string, fs::file_time_type>> files;
  for (const auto& entry : fs::recursive_directory_iterator(directory)) {
    files.insert({entry.path().string(), fs::last_write_time(entry.path())});
  }
  return files;
}

TEST(CampaignLoading, WritesNothing) {
  const auto scratch = fs::temp_directory_path() / ("millflow_load_" + std::to_string(::getpid()));
  fs::create_directories(scratch);
  const auto previous = fs::current_path();
  fs::current_path(scratch);
  const auto corpus_before = snapshot(corpus_dir);
  for (const auto& file : corpus_files()) messages_of(file);
  load_campaign(source_dir / "campaigns/quick.json");
  fs::current_path(previous);
  EXPECT_TRUE(fs::is_empty(scratch));
  EXPECT_EQ(snapshot(corpus_dir), corpus_before);
  fs::remove_all(scratch);
}

TEST(CampaignLoading, MissingFileIsReportedAsInput) {
  const auto messages = messages_of(corpus_dir / "no_such_file.json");
  ASSERT_EQ(messages.size(), 1U);
  EXPECT_EQ(messages[0],
            "(document): cannot read campaign file " + (corpus_dir / "no_such_file.json").string() +
                ": No such file or directory; check the file name and its permissions");
}

TEST(CampaignLoading, FillsEveryDefault) {
  const auto campaign = load_campaign(source_dir / "tests/tasks/good_campaigns/minimal.json");
  EXPECT_EQ(campaign["description"], "");
  EXPECT_EQ(campaign["dem"],
            json({{"steps_per_collision", 20}, {"neighbor_skin_fraction", 0.3}, {"seed", 1}}));
  EXPECT_EQ(campaign["mill"]["axial_ends"], "periodic");
  EXPECT_EQ(campaign["macro"]["settle_time"], 0.5);
  EXPECT_EQ(campaign["macro"]["warmup_revolutions"], 2.0);
  EXPECT_EQ(campaign["macro"]["measure_revolutions"], 3.0);
  EXPECT_EQ(campaign["macro"]["sample_interval"], 0.01);
  EXPECT_EQ(campaign["macro"]["vtk_interval"], 0.1);
  EXPECT_EQ(campaign["macro"]["checkpoint_interval_s"], 60.0);
  EXPECT_EQ(campaign["average"], json({{"grid_cells", {40, 40}}, {"kernel_width_diameters", 1.5}}));
  EXPECT_EQ(campaign["sites"]["per_region"], 2);
  EXPECT_EQ(campaign["sites"]["regions"],
            json({"bulk", "shoulder", "cascading", "toe", "cataracting", "near_liner"}));
  const auto& cell = campaign["shear_cell"];
  EXPECT_EQ(cell["boundary"], "lees_edwards");
  EXPECT_EQ(cell["size_diameters"], json({6.0, 8.0, 6.0}));
  EXPECT_EQ(cell["gravity"], false);
  EXPECT_EQ(cell["warmup_strain"], 2.0);
  EXPECT_EQ(cell["measure_strain"], 4.0);
  EXPECT_EQ(cell["stress_control"]["gain"], 0.5);
  EXPECT_EQ(campaign["executor"], json({{"kind", "local"}}));
  for (const auto& interaction : campaign["interactions"]) {
    EXPECT_EQ(interaction["tangential_stiffness_ratio"], 0.2857142857);
    EXPECT_EQ(interaction["tangential_damping_ratio"], 0.5);
  }
  EXPECT_FALSE(campaign.contains("sweep"));
}

TEST(CampaignLoading, TakesAutoForTheSkinAndKeepsIt) {
  auto document = millflow::tasks::validate_campaign(
      json::parse(std::ifstream(source_dir / "tests/tasks/good_campaigns/minimal.json")));
  document["dem"]["neighbor_skin_fraction"] = "auto";
  EXPECT_EQ(millflow::tasks::validate_campaign(document)["dem"]["neighbor_skin_fraction"], "auto");
}

TEST(CampaignLoading, StoresNumbersAsFloatsAndCountsAsIntegers) {
  // One spelling per value, so the same settings always hash to the same task key.
  const auto campaign = load_campaign(source_dir / "tests/tasks/good_campaigns/minimal.json");
  EXPECT_TRUE(campaign["materials"]["steel"]["density"].is_number_float());      // written as 7800
  EXPECT_TRUE(campaign["mill"]["lifters"]["face_angle_deg"].is_number_float());  // written as 15
  EXPECT_TRUE(campaign["mill"]["lifters"]["count"].is_number_integer());
  EXPECT_TRUE(campaign["dem"]["seed"].is_number_integer());
}

TEST(CampaignExpansion, CampaignWithoutSweepIsOnePoint) {
  const auto campaign = load_campaign(source_dir / "tests/tasks/good_campaigns/minimal.json");
  const auto points = millflow::tasks::expand(campaign);
  ASSERT_EQ(points.size(), 1U);
  EXPECT_TRUE(points[0].coordinates.empty());
  EXPECT_EQ(points[0].document, campaign);
}

// The swept values of a point, keyed by path.
std::map<std::string, double> coordinates_of(const millflow::tasks::CampaignPoint& point) {
  std::map<std::string, double> values;
  for (const auto& c : point.coordinates) values[c.path] = c.value.get<double>();
  return values;
}

TEST(CampaignExpansion, QuickCampaignIsTwoFillsTimesTwoSpeedsTimesThreeLoads) {
  const auto campaign = load_campaign(source_dir / "campaigns/quick.json");
  const auto points = millflow::tasks::expand(campaign);
  ASSERT_EQ(points.size(), 12U);
  std::size_t i = 0;
  for (const double fill : {0.2, 0.35}) {
    for (const double speed : {0.65, 0.8}) {
      for (const double load : {0.0, 0.5, 1.0}) {
        const auto& point = points[i++];
        EXPECT_EQ(coordinates_of(point),
                  (std::map<std::string, double>{{"/macro/fill", fill},
                                                 {"/macro/speed_fraction", speed},
                                                 {"/shear_cell/powder/load", load}}));
        EXPECT_EQ(point.document["macro"]["fill"], fill);
        EXPECT_EQ(point.document["macro"]["speed_fraction"], speed);
        EXPECT_EQ(point.document["shear_cell"]["powder"]["load"], load);
        EXPECT_FALSE(point.document.contains("sweep"));
        EXPECT_EQ(point.document["mill"], campaign["mill"]);
      }
    }
  }
}

TEST(CampaignExpansion, CementMillRangesGiveExactLookingValues) {
  const auto campaign = load_campaign(source_dir / "campaigns/cement_ball_mill.json");
  const auto points = millflow::tasks::expand(campaign);
  ASSERT_EQ(points.size(), 3U * 4U * 4U);
  std::set<double> speeds;
  std::set<double> loads;
  for (const auto& point : points) {
    speeds.insert(coordinates_of(point).at("/macro/speed_fraction"));
    loads.insert(coordinates_of(point).at("/shear_cell/powder/load"));
  }
  // 0.65 + 3 * 0.1 is 0.9500000000000001 in floating point; the sweep must give 0.95.
  EXPECT_EQ(speeds, (std::set<double>{0.65, 0.75, 0.85, 0.95}));
  EXPECT_EQ(loads, (std::set<double>{0.0, 0.5, 1.0, 1.5}));
}

TEST(CampaignExpansion, EveryPointIsItselfAValidNormalizedCampaign) {
  for (const auto* name : {"campaigns/quick.json", "campaigns/cement_ball_mill.json"}) {
    for (const auto& point : millflow::tasks::expand(load_campaign(source_dir / name))) {
      EXPECT_EQ(millflow::tasks::validate_campaign(point.document), point.document) << name;
    }
  }
}

}  // namespace
