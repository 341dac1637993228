// The generic table-driven validator, on a small table of its own.
#include <gtest/gtest.h>

#include "engine/json_validator.hpp"

namespace {

using millflow::engine::above;
using millflow::engine::at_least;
using millflow::engine::at_most;
using millflow::engine::below;
using millflow::engine::Field;
using millflow::engine::FieldTable;
using millflow::engine::FieldType;
using millflow::engine::ValidationResult;
using nlohmann::json;

const FieldTable& pump_table() {
  static const FieldTable table({
      Field("/kind", FieldType::enumeration, "pump kind").required().choices({"piston", "rotary"}),
      Field("/label", FieldType::string, "pump label")
          .pattern("[a-z]+")
          .hint("use lower-case letters"),
      Field("/rate", FieldType::number, "flow rate")
          .unit("m^3/s")
          .required()
          .range(above(0), at_most(2)),
      Field("/stages", FieldType::integer, "number of stages")
          .defaults(1)
          .range(at_least(1), below(10)),
      Field("/enabled", FieldType::boolean, "whether the pump runs").defaults(true),
      Field("/motor", FieldType::object, "the motor")
          .defaults(json::object())
          .exactly_one_of({"power", "torque"}),
      Field("/motor/power", FieldType::number, "motor power").unit("W"),
      Field("/motor/torque", FieldType::number, "motor torque").unit("N m"),
      Field("/motor/poles", FieldType::integer, "pole count").defaults(4),
      Field("/fluids", FieldType::object, "fluids by name").pattern("[a-z]+").items(1, {}),
      Field("/fluids/*", FieldType::object, "one fluid"),
      Field("/fluids/*/viscosity", FieldType::number, "dynamic viscosity")
          .unit("Pa s")
          .required()
          .range(above(0), {}),
      Field("/ports", FieldType::array, "port diameters").items(1, 3).unique(),
      Field("/ports/*", FieldType::number, "a port diameter").unit("m").range(above(0), {}),
  });
  return table;
}

const json valid_pump = {{"kind", "piston"},
                         {"rate", 1},
                         {"motor", {{"power", 50}}},
                         {"fluids", {{"water", {{"viscosity", 0.001}}}}}};

std::vector<std::string> messages(const ValidationResult& result) {
  std::vector<std::string> texts;
  for (const auto& e : result.errors) texts.push_back(e.message());
  return texts;
}

std::vector<std::string> errors_of(const json& patch) {
  json pump = valid_pump;
  pump.merge_patch(patch);
  return messages(validate(pump, pump_table()));
}

TEST(JsonValidator, ValidDocumentGetsDefaultsAndOneSpellingPerNumber) {
  const auto result = validate(valid_pump, pump_table());
  ASSERT_TRUE(result.ok()) << messages(result)[0];
  const json expected = {{"kind", "piston"},
                         {"rate", 1.0},
                         {"stages", 1},
                         {"enabled", true},
                         {"motor", {{"power", 50.0}, {"poles", 4}}},
                         {"fluids", {{"water", {{"viscosity", 0.001}}}}}};
  EXPECT_EQ(result.document, expected);
  EXPECT_TRUE(result.document["rate"].is_number_float());
  EXPECT_TRUE(result.document["stages"].is_number_integer());
}

TEST(JsonValidator, IntegerWrittenWithAPointIsAnInteger) {
  json pump = valid_pump;
  pump["stages"] = 3.0;
  const auto result = validate(pump, pump_table());
  ASSERT_TRUE(result.ok());
  EXPECT_TRUE(result.document["stages"].is_number_integer());
  EXPECT_EQ(result.document["stages"], 3);
}

TEST(JsonValidator, UnknownKeySuggestsTheClosestField) {
  EXPECT_EQ(
      errors_of({{"stagse", 2}}),
      std::vector<std::string>{"/stagse: unknown field \"stagse\"; did you mean \"stages\"?"});
  EXPECT_EQ(errors_of({{"colour", "red"}}),
            std::vector<std::string>{
                "/colour: unknown field \"colour\"; allowed fields here: \"kind\", \"label\", "
                "\"rate\", \"stages\", \"enabled\", \"motor\", \"fluids\", \"ports\""});
}

// Printed raw, a NUL (from "\u0000" in the file) cut the whole report short and an escape
// sequence reached the terminal.
TEST(JsonValidator, ControlCharactersArePrintedAsJsonEscapes) {
  const std::string key("stag\0\x1b[1m", 9);
  EXPECT_EQ(
      errors_of({{key, 2}}),
      std::vector<std::string>{
          "/stag\\u0000\\u001b[1m: unknown field \"stag\\u0000\\u001b[1m\"; allowed fields "
          "here: \"kind\", \"label\", \"rate\", \"stages\", \"enabled\", \"motor\", \"fluids\", "
          "\"ports\""});
  EXPECT_EQ(std::string(millflow::engine::InvalidInput({{"/" + key, "x", "y"}}).what()),
            "/stag\\u0000\\u001b[1m: x; y");
}

TEST(JsonValidator, WrongTypeNamesTheExpectedType) {
  EXPECT_EQ(errors_of({{"rate", "fast"}}),
            std::vector<std::string>{"/rate: expected a number, got the string \"fast\"; give flow "
                                     "rate as a number in m^3/s"});
  EXPECT_EQ(
      errors_of({{"stages", 2.5}}),
      std::vector<std::string>{
          "/stages: expected an integer, got the number 2.5; give number of stages as an integer"});
  EXPECT_EQ(errors_of({{"enabled", 1}}),
            std::vector<std::string>{"/enabled: expected true or false, got the number 1; give "
                                     "whether the pump runs as true or false"});
  EXPECT_EQ(errors_of({{"fluids", json::array({1})}}),
            std::vector<std::string>{
                "/fluids: expected an object, got a list; give fluids by name as an object"});
}

TEST(JsonValidator, RangeBoundsAreInclusiveOrExclusiveAsDeclared) {
  EXPECT_TRUE(errors_of({{"rate", 2}}).empty());  // at_most(2) admits 2
  EXPECT_TRUE(errors_of({{"stages", 1}}).empty());
  EXPECT_EQ(errors_of({{"rate", 0}}),
            std::vector<std::string>{
                "/rate: 0 m^3/s is out of range; flow rate must be in (0, 2] m^3/s"});
  EXPECT_EQ(
      errors_of({{"stages", 10}}),
      std::vector<std::string>{"/stages: 10 is out of range; number of stages must be in [1, 10)"});
  EXPECT_EQ(
      errors_of({{"fluids", {{"water", {{"viscosity", -1}}}}}}),
      std::vector<std::string>{
          "/fluids/water/viscosity: -1 Pa s is out of range; dynamic viscosity must be > 0 Pa s"});
}

TEST(JsonValidator, MissingRequiredFieldSaysWhatToAdd) {
  json pump = valid_pump;
  pump.erase("rate");
  EXPECT_EQ(messages(validate(pump, pump_table())),
            std::vector<std::string>{
                "/rate: required field is missing; add flow rate, a number in (0, 2] m^3/s"});
}

TEST(JsonValidator, EnumerationSuggestsOrListsTheChoices) {
  EXPECT_EQ(errors_of({{"kind", "pistn"}}),
            std::vector<std::string>{"/kind: \"pistn\" is not allowed; did you mean \"piston\"? "
                                     "(allowed: \"piston\", \"rotary\")"});
  EXPECT_EQ(
      errors_of({{"kind", "jet"}}),
      std::vector<std::string>{"/kind: \"jet\" is not allowed; use one of \"piston\", \"rotary\""});
}

TEST(JsonValidator, PatternsApplyToStringsAndToMapKeys) {
  EXPECT_EQ(errors_of({{"label", "Pump 1"}}),
            std::vector<std::string>{
                "/label: \"Pump 1\" does not match the pattern [a-z]+; give pump label as a "
                "string matching it; use lower-case letters"});
  EXPECT_EQ(errors_of({{"fluids", {{"Oil", {{"viscosity", 0.1}}}}}}),
            std::vector<std::string>{
                "/fluids/Oil: name \"Oil\" does not match the pattern [a-z]+; rename it"});
}

// Matching such texts would overflow std::regex's stack (a segmentation fault at some 50,000
// characters).
TEST(JsonValidator, StringsAndKeysLongerThanAPatternChecksAreRefusedBeforeMatching) {
  const std::string long_text(100000, 'a');
  EXPECT_EQ(errors_of({{"label", long_text}}),
            std::vector<std::string>{
                "/label: the string has 100000 characters, more than 200; give pump label as at "
                "most 200 characters matching [a-z]+; use lower-case letters"});
  EXPECT_EQ(errors_of({{"fluids", {{long_text, {{"viscosity", 0.1}}}}}}),
            std::vector<std::string>{"/fluids/" + long_text +
                                     ": the name has 100000 characters, more than 200; rename "
                                     "it to at most 200 characters"});
  EXPECT_TRUE(errors_of({{"label", std::string(200, 'a')}}).empty());
}

TEST(JsonValidator, ListsCheckTheirItemsCountAndUniqueness) {
  EXPECT_TRUE(errors_of({{"ports", {0.1, 0.2}}}).empty());
  EXPECT_EQ(
      errors_of({{"ports", {0.1, -0.2, 0.1}}}),
      (std::vector<std::string>{"/ports/1: -0.2 m is out of range; a port diameter must be > 0 m",
                                "/ports/2: 0.1 appears more than once; list each value once"}));
  EXPECT_EQ(errors_of({{"ports", {0.1, 0.2, 0.3, 0.4}}}),
            std::vector<std::string>{"/ports: has 4 items; give between 1 and 3 items"});
  json pump = valid_pump;
  pump["fluids"] = json::object();
  EXPECT_EQ(messages(validate(pump, pump_table())),
            std::vector<std::string>{"/fluids: has 0 entries; give at least 1 entry"});
}

TEST(JsonValidator, ExactlyOneOfTwoAlternatives) {
  EXPECT_EQ(errors_of({{"motor", {{"torque", 3}}}}),
            std::vector<std::string>{"/motor: sets \"power\", \"torque\" together; "
                                     "keep exactly one of \"power\", \"torque\""});
  json pump = valid_pump;
  pump.erase("motor");  // the default {} holds neither
  EXPECT_EQ(messages(validate(pump, pump_table())),
            std::vector<std::string>{
                "/motor: sets none of \"power\", \"torque\"; add exactly one of them"});
}

TEST(JsonValidator, ReportsEveryErrorAtOnceInDocumentOrder) {
  EXPECT_EQ(
      errors_of({{"kind", 3}, {"rate", 5}, {"extra", true}}),
      (std::vector<std::string>{
          "/extra: unknown field \"extra\"; allowed fields here: \"kind\", \"label\", \"rate\", "
          "\"stages\", \"enabled\", \"motor\", \"fluids\", \"ports\"",
          "/kind: expected one of \"piston\", \"rotary\", got the number 3; give pump kind as "
          "one of \"piston\", \"rotary\"",
          "/rate: 5 m^3/s is out of range; flow rate must be in (0, 2] m^3/s"}));
}

TEST(JsonValidator, ValidateFieldReportsUnderTheGivenPath) {
  const auto result = validate_field(json(-3), "/ports/*", pump_table(), "/elsewhere/7");
  EXPECT_EQ(messages(result),
            std::vector<std::string>{
                "/elsewhere/7: -3 m is out of range; a port diameter must be > 0 m"});
  EXPECT_EQ(result.document, -3.0);
}

TEST(JsonValidator, TableMatchesConcretePathsAgainstWildcards) {
  EXPECT_EQ(pump_table().match("/fluids/oil/viscosity")->path, "/fluids/*/viscosity");
  EXPECT_EQ(pump_table().match("/ports/2")->path, "/ports/*");
  EXPECT_EQ(pump_table().match("/rate")->path, "/rate");
  EXPECT_EQ(pump_table().match("/flow"), nullptr);
  EXPECT_EQ(pump_table().match("rate"), nullptr);
}

TEST(JsonValidator, TableRejectsRulesWithoutAContainerParent) {
  EXPECT_THROW(FieldTable({Field("/a/b", FieldType::number, "orphan")}), std::logic_error);
  EXPECT_THROW(
      FieldTable({Field("/a", FieldType::number, "a"), Field("/a/b", FieldType::number, "b")}),
      std::logic_error);
}

TEST(JsonValidator, ClosestMatchToleratesTyposOnly) {
  const std::vector<std::string> names = {"density", "diameter", "length"};
  EXPECT_EQ(millflow::engine::closest_match("densty", names), "density");
  EXPECT_EQ(millflow::engine::closest_match("diamteer", names),
            "diameter");  // adjacent swap counts once
  EXPECT_EQ(millflow::engine::closest_match("lenght", names), "length");
  EXPECT_EQ(millflow::engine::closest_match("colour", names), std::nullopt);
}

TEST(JsonValidator, PathSegmentsAreEscapedAsInRfc6901) {
  EXPECT_EQ(millflow::engine::escape_path_segment("/a~b/c"), "~1a~0b~1c");
}

TEST(JsonValidator, SchemaSaysWhatTheTableSays) {
  const FieldTable table({
      Field("/n", FieldType::integer, "count").required().range(at_least(1), below(10)),
      Field("/m", FieldType::object, "map").pattern("[a-z]+"),
      Field("/m/*", FieldType::number, "value").unit("m").defaults(0.5),
      Field("/e", FieldType::enumeration, "choice").choices({"x", "y"}),
      Field("/l", FieldType::array, "list").items(2, 2).unique(),
      Field("/l/*", FieldType::string, "item").pattern("[a-z]"),
      Field("/o", FieldType::object, "either").exactly_one_of({"p", "q"}),
      Field("/o/p", FieldType::boolean, "p"),
      Field("/o/q", FieldType::boolean, "q"),
  });
  const json expected = json::parse(R"({
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object", "description": "document", "additionalProperties": false, "required": ["n"],
    "properties": {
      "n": {"type": "integer", "description": "count", "minimum": 1, "exclusiveMaximum": 10},
      "m": {"type": "object", "description": "map", "propertyNames": {"pattern": "^(?:[a-z]+)$", "maxLength": 200},
            "additionalProperties": {"type": "number", "description": "value [m]", "default": 0.5}},
      "e": {"type": "string", "description": "choice", "enum": ["x", "y"]},
      "l": {"type": "array", "description": "list", "minItems": 2, "maxItems": 2, "uniqueItems": true,
            "items": {"type": "string", "description": "item", "pattern": "^(?:[a-z])$", "maxLength": 200}},
      "o": {"type": "object", "description": "either", "additionalProperties": false,
            "properties": {"p": {"type": "boolean", "description": "p"}, "q": {"type": "boolean", "description": "q"}},
            "oneOf": [{"required": ["p"]}, {"required": ["q"]}]}
    }
  })");
  EXPECT_EQ(to_json_schema(table), expected) << json::diff(expected, to_json_schema(table)).dump(1);
}

}  // namespace
