// schemas/campaign.schema.json must say what the C++ field table says. The schema is rendered
// from the table; when this test fails it writes the rendering to the build directory so the
// checked-in file can be replaced after a review of the difference.
#include <fstream>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "tasks/campaign.hpp"

namespace {

using nlohmann::json;

json read_json(const std::string& path) {
  std::ifstream stream(path);
  return json::parse(stream);
}

// Every field path the schema describes, in the table's pattern syntax ("*" for map entries and
// list items). The sweep block has its own grammar and only its own path is listed.
void collect_paths(const json& schema, const std::string& path, std::set<std::string>& paths) {
  paths.insert(path);
  if (path == "/sweep") return;
  if (schema.contains("properties")) {
    for (const auto& [key, field] : schema["properties"].items())
      collect_paths(field, path + "/" + key, paths);
  }
  if (schema.contains("additionalProperties") && schema["additionalProperties"].is_object()) {
    collect_paths(schema["additionalProperties"], path + "/*", paths);
  }
  if (schema.contains("items")) collect_paths(schema["items"], path + "/*", paths);
}

TEST(CampaignSchema, DescribesExactlyTheFieldsOfTheTable) {
  const auto schema = read_json(MILLFLOW_SOURCE_DIR "/schemas/campaign.schema.json");
  std::set<std::string> schema_paths;
  collect_paths(schema, "", schema_paths);
  std::set<std::string> table_paths;
  for (const auto& rule : millflow::tasks::campaign_table().rules()) table_paths.insert(rule.path);
  for (const auto& path : table_paths)
    EXPECT_TRUE(schema_paths.count(path)) << path << " is missing in the schema";
  for (const auto& path : schema_paths)
    EXPECT_TRUE(table_paths.count(path)) << path << " is not in the table";
}

TEST(CampaignSchema, CheckedInFileEqualsTheRenderingOfTheTable) {
  const auto rendered = millflow::tasks::campaign_json_schema();
  const auto checked_in = read_json(MILLFLOW_SOURCE_DIR "/schemas/campaign.schema.json");
  if (rendered != checked_in) {
    const std::string fresh = MILLFLOW_BINARY_DIR "/campaign.schema.json";
    std::ofstream(fresh) << rendered.dump(2) << '\n';
    FAIL() << "schemas/campaign.schema.json is out of date; review and copy " << fresh
           << " over it\n"
           << json::diff(checked_in, rendered).dump(2);
  }
}

TEST(CampaignSchema, RangesUnitsAndDefaultsReachTheSchema) {
  // Spot checks against the values the campaign format documents, independent of the table code.
  const auto schema = millflow::tasks::campaign_json_schema();
  const auto& mill = schema["properties"]["mill"]["properties"];
  EXPECT_EQ(mill["diameter"]["minimum"], 0.1);
  EXPECT_EQ(mill["diameter"]["maximum"], 15.0);
  EXPECT_EQ(mill["diameter"]["description"], "inner diameter of the mill shell [m]");
  EXPECT_EQ(mill["lifters"]["properties"]["face_angle_deg"]["exclusiveMaximum"], 60.0);
  const auto& interaction = schema["properties"]["interactions"]["items"]["properties"];
  EXPECT_EQ(interaction["restitution"]["exclusiveMinimum"], 0.0);
  EXPECT_EQ(interaction["tangential_stiffness_ratio"]["default"], 0.2857142857);
  EXPECT_EQ(schema["properties"]["sites"]["properties"]["regions"]["default"].size(), 6U);
  EXPECT_EQ(schema["properties"]["millflow_campaign"]["minimum"], 1);
  EXPECT_EQ(schema["properties"]["millflow_campaign"]["maximum"], 1);
  EXPECT_TRUE(schema["properties"]["sweep"].contains("properties"));
}

}  // namespace
