// Sweep expansion: value forms, rounding, product and zip axes, and every sweep error.
#include <gtest/gtest.h>

#include "engine/sweep.hpp"

namespace {

using millflow::engine::at_least;
using millflow::engine::at_most;
using millflow::engine::Field;
using millflow::engine::FieldTable;
using millflow::engine::FieldType;
using millflow::engine::InvalidInput;
using millflow::engine::SweepCoordinate;
using nlohmann::json;

const FieldTable& oven_table() {
  static const FieldTable table({
      Field("/temperature", FieldType::number, "oven temperature")
          .unit("K")
          .range(at_least(250), at_most(600)),
      Field("/minutes", FieldType::integer, "baking time").range(at_least(1), {}),
      Field("/fan", FieldType::enumeration, "fan mode").choices({"off", "low", "high"}),
      Field("/trays", FieldType::array, "trays"),
      Field("/trays/*", FieldType::object, "one tray"),
      Field("/trays/*/height", FieldType::number, "tray height").unit("m"),
      Field("/sweep", FieldType::object, "the sweep").opaque(),
  });
  return table;
}

json oven(json sweep) {
  json document = {{"temperature", 450.0},
                   {"minutes", 30},
                   {"fan", "low"},
                   {"trays", {{{"height", 0.1}}, {{"height", 0.3}}}}};
  document["sweep"] = std::move(sweep);
  return document;
}

std::vector<std::string> sweep_errors(const json& sweep) {
  std::vector<std::string> texts;
  for (const auto& e : check_sweep(oven(sweep), oven_table())) texts.push_back(e.message());
  return texts;
}

TEST(SweepValues, LinspaceIncludesBothEnds) {
  EXPECT_EQ(millflow::engine::linspace(0.0, 1.0, 5),
            (std::vector<double>{0.0, 0.25, 0.5, 0.75, 1.0}));
  EXPECT_EQ(millflow::engine::linspace(0.1, 0.3, 3), (std::vector<double>{0.1, 0.2, 0.3}));
  EXPECT_EQ(millflow::engine::linspace(2.0, 7.0, 1), (std::vector<double>{2.0}));
}

TEST(SweepValues, RangeIncludesStopWhenAStepLandsOnIt) {
  // 0.6 + 3 * 0.1 = 0.9000000000000001 and (0.9 - 0.6) / 0.1 = 2.9999999999999996 in doubles.
  EXPECT_EQ(millflow::engine::arange_inclusive(0.6, 0.9, 0.1),
            (std::vector<double>{0.6, 0.7, 0.8, 0.9}));
  EXPECT_EQ(millflow::engine::arange_inclusive(0.0, 1.0, 0.3),
            (std::vector<double>{0.0, 0.3, 0.6, 0.9}));
  EXPECT_EQ(millflow::engine::arange_inclusive(1.0, 0.0, -0.25),
            (std::vector<double>{1.0, 0.75, 0.5, 0.25, 0.0}));
  EXPECT_EQ(millflow::engine::arange_inclusive(5.0, 5.0, 1.0), (std::vector<double>{5.0}));
}

TEST(SweepValues, RoundingToTwelveDigitsRemovesFloatingPointNoise) {
  EXPECT_EQ(millflow::engine::round_significant(0.1 + 0.2), 0.3);
  EXPECT_EQ(millflow::engine::round_significant(1e-7 * 3), 3e-7);
  EXPECT_EQ(millflow::engine::round_significant(123456789.0123456), 123456789.012);
  EXPECT_EQ(millflow::engine::round_significant(0.0), 0.0);
  // Subnormal: std::stod threw std::out_of_range on it, and validate exited 1 with "stod".
  EXPECT_EQ(millflow::engine::round_significant(1e-320), 1e-320);
}

TEST(SweepExpansion, WithoutSweepTheDocumentIsTheOnlyPoint) {
  json document = oven(json::object());
  document.erase("sweep");
  const auto points = expand_sweep(document, oven_table());
  ASSERT_EQ(points.size(), 1U);
  EXPECT_EQ(points[0].document, document);
  EXPECT_TRUE(points[0].coordinates.empty());
}

TEST(SweepExpansion, ProductAxesInPathOrderWithTheLastVaryingFastest) {
  const auto points =
      expand_sweep(oven({{"product",
                          {{"/temperature", {{"start", 400}, {"stop", 500}, {"num", 3}}},
                           {"/fan", {"off", "high"}}}}}),
                   oven_table());
  ASSERT_EQ(points.size(), 6U);
  std::size_t i = 0;
  for (const char* fan : {"off", "high"}) {  // "/fan" sorts before "/temperature"
    for (const double temperature : {400.0, 450.0, 500.0}) {
      EXPECT_EQ(points[i].coordinates,
                (std::vector<SweepCoordinate>{{"/fan", fan}, {"/temperature", temperature}}));
      EXPECT_EQ(points[i].document["fan"], fan);
      EXPECT_EQ(points[i].document["temperature"], temperature);
      EXPECT_EQ(points[i].document["minutes"], 30);
      EXPECT_FALSE(points[i].document.contains("sweep"));
      ++i;
    }
  }
}

TEST(SweepExpansion, ZipGroupIsOneAxisCombinedWithTheProduct) {
  const auto points =
      expand_sweep(oven({{"product", {{"/fan", {"off", "high"}}}},
                         {"zip",
                          {{{"/temperature", {300, 350, 400}},
                            {"/minutes", {{"start", 40}, {"stop", 20}, {"step", -10}}}}}}}),
                   oven_table());
  ASSERT_EQ(points.size(), 6U);
  const std::vector<std::pair<double, int>> zipped = {{300.0, 40}, {350.0, 30}, {400.0, 20}};
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& [temperature, minutes] = zipped[i % 3];
    EXPECT_EQ(points[i].document["temperature"], temperature);
    EXPECT_EQ(points[i].document["minutes"], minutes);
    EXPECT_TRUE(points[i]
                    .document["minutes"]
                    .is_number_integer());  // generated from a range, kept an integer
    EXPECT_EQ(points[i].document["fan"], i < 3 ? "off" : "high");
    EXPECT_EQ(points[i].coordinates.size(), 3U);
  }
}

TEST(SweepExpansion, SweepsItemsOfListsAndNormalizesValues) {
  const auto points =
      expand_sweep(oven({{"product", {{"/trays/1/height", {1, 2}}}}}), oven_table());
  ASSERT_EQ(points.size(), 2U);
  EXPECT_EQ(points[1].document["trays"][1]["height"], 2.0);
  EXPECT_TRUE(
      points[1].document["trays"][1]["height"].is_number_float());  // written as 2, a number field
  EXPECT_EQ(points[1].document["trays"][0]["height"], 0.1);
}

TEST(SweepErrors, UnknownPathSuggestsAField) {
  EXPECT_EQ(sweep_errors({{"product", {{"/temprature", {300}}}}}),
            std::vector<std::string>{
                "/sweep/product/~1temprature: \"/temprature\" is not a field of this file; did you "
                "mean \"/temperature\"?"});
  EXPECT_EQ(sweep_errors({{"product", {{"/trays/5/height", {1}}}}}),
            std::vector<std::string>{
                "/sweep/product/~1trays~15~1height: \"/trays/5/height\" is not set in this file; "
                "set it outside the sweep first, or sweep a field that is set"});
}

TEST(SweepErrors, SweptValuesMustPassTheFieldsRule) {
  EXPECT_EQ(
      sweep_errors(
          {{"product", {{"/temperature", {{"start", 500}, {"stop", 700}, {"step", 100}}}}}}),
      std::vector<std::string>{
          "/sweep/product/~1temperature/2: 700 K is out of range; oven temperature must be in "
          "[250, 600] K"});
  EXPECT_EQ(sweep_errors({{"product", {{"/minutes", {{"start", 1}, {"stop", 2}, {"num", 3}}}}}}),
            std::vector<std::string>{
                "/sweep/product/~1minutes/1: expected an integer, got the number 1.5; give baking "
                "time as an integer"});
  EXPECT_EQ(
      sweep_errors({{"zip", {{{"/fan", {"of", "low"}}, {"/minutes", {1, 2}}}}}}),
      std::vector<std::string>{
          "/sweep/zip/0/~1fan/0: \"of\" is not allowed; did you mean \"off\"? (allowed: \"off\", "
          "\"low\", \"high\")"});
}

TEST(SweepErrors, ZipListsMustHaveEqualLengths) {
  EXPECT_EQ(
      sweep_errors({{"zip", {{{"/fan", {"off", "low"}}, {"/minutes", {1, 2, 3}}}}}}),
      std::vector<std::string>{
          "/sweep/zip/0: lists of different lengths: \"/fan\" has 2 values, \"/minutes\" has 3; "
          "give every path of a zip group the same number of values"});
}

TEST(SweepErrors, BadRanges) {
  EXPECT_EQ(
      sweep_errors({{"product", {{"/temperature", {{"start", 300}, {"stop", 400}, {"step", 0}}}}}}),
      std::vector<std::string>{
          "/sweep/product/~1temperature/step: step 0 never reaches stop 400 from start 300; "
          "use a non-zero step"});
  EXPECT_EQ(
      sweep_errors({{"product", {{"/temperature", {{"start", 300}, {"stop", 400}, {"num", 0}}}}}}),
      std::vector<std::string>{
          "/sweep/product/~1temperature/num: 0 is not a valid number of values; give an "
          "integer in [1, 10000]"});
  EXPECT_EQ(sweep_errors(
                {{"product", {{"/temperature", {{"start", 300}, {"stop", 400}, {"step", 1e-3}}}}}}),
            std::vector<std::string>{
                "/sweep/product/~1temperature/step: step 0.001 makes more than 10000 values; use a "
                "larger step"});
  EXPECT_EQ(sweep_errors({{"product",
                           {{"/temperature", {{"start", -1e308}, {"stop", 1e308}, {"num", 3}}}}}}),
            std::vector<std::string>{"/sweep/product/~1temperature: the span from start -1e+308 to "
                                     "stop 1e+308 is beyond a double; narrow the range"});
  EXPECT_EQ(
      sweep_errors({{"product", {{"/temperature", {{"stop", "400"}, {"num", 2}}}}}}),
      (std::vector<std::string>{
          "/sweep/product/~1temperature/start: required field is missing; add \"start\", a number",
          "/sweep/product/~1temperature/stop: expected a number, got the string \"400\"; give "
          "\"stop\" as a number"}));
}

TEST(SweepErrors, TooManyPointsAreRefusedBeforeTheyAreBuilt) {
  const json temperatures = {{"start", 300}, {"stop", 400}, {"num", 200}};
  const json minutes = {{"start", 1}, {"stop", 200}, {"step", 1}};
  EXPECT_EQ(sweep_errors({{"product", {{"/temperature", temperatures}, {"/minutes", minutes}}}}),
            std::vector<std::string>{
                "/sweep: makes 40000 points, more than 10000; split the study into several files"});
}

TEST(SweepErrors, AFieldIsSweptInOnePlaceOnly) {
  EXPECT_EQ(sweep_errors({{"product", {{"/trays", {json::array()}}, {"/trays/0/height", {1}}}}}),
            std::vector<std::string>{
                "/sweep/product/~1trays~10~1height: \"/trays/0/height\" overlaps \"/trays\", swept "
                "elsewhere; sweep each field in one place only"});
}

// Its values passed unchecked and the points' sweep blocks did nothing.
TEST(SweepErrors, TheSweepBlockCannotSweepItself) {
  EXPECT_EQ(sweep_errors({{"product", {{"/sweep", {{{"product", {{"/minutes", {1, 2}}}}}}}}}}),
            std::vector<std::string>{
                "/sweep/product/~1sweep: \"/sweep\" cannot be swept; sweep the fields of the file, "
                "not the sweep block"});
}

// A campaign's name or executor swept changed nothing from point to point.
TEST(SweepErrors, AWholeCampaignFieldOrOneUnderItCannotBeSwept) {
  const FieldTable table({
      Field("/name", FieldType::string, "the name").whole_campaign(),
      Field("/executor", FieldType::object, "where it runs").whole_campaign(),
      Field("/executor/kind", FieldType::string, "which"),
      Field("/minutes", FieldType::integer, "baking time"),
      Field("/sweep", FieldType::object, "the sweep").opaque(),
  });
  const json document = {
      {"name", "bake"},
      {"executor", {{"kind", "local"}}},
      {"minutes", 3},
      {"sweep",
       {{"product",
         {{"/name", {"a", "b"}}, {"/executor/kind", {"local", "slurm"}}, {"/minutes", {1, 2}}}}}}};
  std::vector<std::string> errors;
  for (const auto& e : check_sweep(document, table)) errors.push_back(e.path + ": " + e.problem);
  const std::string effect =
      " holds one value for the whole campaign; a sweep would change it to "
      "no effect";
  EXPECT_EQ(errors, (std::vector<std::string>{
                        "/sweep/product/~1executor~1kind: \"/executor/kind\"" + effect,
                        "/sweep/product/~1name: \"/name\"" + effect}));
}

TEST(SweepErrors, StructureOfTheBlock) {
  EXPECT_EQ(sweep_errors({{"zipp", json::array()}}),
            std::vector<std::string>{"/sweep/zipp: unknown field \"zipp\"; did you mean \"zip\"?"});
  EXPECT_EQ(sweep_errors({{"zip", {json::object()}}}),
            std::vector<std::string>{
                "/sweep/zip/0: empty zip group; map each path of the group to its values, e.g. "
                "{\"/a\": [1, 2], \"/b\": [3, 4]}"});
  EXPECT_EQ(
      sweep_errors(json::array()),
      std::vector<std::string>{
          "/sweep: expected an object, got a list; write {\"product\": {...}, \"zip\": [...]}"});
}

TEST(SweepErrors, ExpandThrowsWithEveryError) {
  try {
    expand_sweep(oven({{"product", {{"/fan", {"fast"}}, {"/minutes", {0}}}}}), oven_table());
    FAIL() << "expected InvalidInput";
  } catch (const InvalidInput& error) {
    EXPECT_EQ(error.errors().size(), 2U);
  }
}

TEST(SweepSchema, DescribesTheThreeValueForms) {
  const auto schema = millflow::engine::sweep_json_schema();
  const auto& forms = schema["properties"]["product"]["additionalProperties"]["oneOf"];
  ASSERT_EQ(forms.size(), 3U);
  EXPECT_EQ(forms[0]["type"], "array");
  EXPECT_EQ(forms[1]["required"], json({"start", "stop", "num"}));
  EXPECT_EQ(forms[2]["required"], json({"start", "stop", "step"}));
}

}  // namespace
