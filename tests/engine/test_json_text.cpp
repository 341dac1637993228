// Parsing JSON input text: syntax errors with line and column, keys written twice.
#include <gtest/gtest.h>

#include "engine/json_text.hpp"

namespace {

using millflow::engine::InvalidInput;
using millflow::engine::parse_json_text;

std::string syntax_message(std::string_view text) {
  try {
    parse_json_text(text);
  } catch (const InvalidInput& error) {
    return error.errors().at(0).message();
  }
  return "parsed";
}

TEST(JsonText, SyntaxErrorNamesLineAndColumn) {
  EXPECT_EQ(syntax_message("{\n  \"a\": 1,\n  \"b\": [1, 2}\n}"),
            "(document): JSON syntax error at line 3, column 13: while parsing array - unexpected "
            "'}'; expected ']'; "
            "correct the JSON there (a missing comma or quote, or a comma before } or ], is the "
            "usual cause)");
  EXPECT_TRUE(syntax_message("\n\n{\"a\": tru}")
                  .starts_with("(document): JSON syntax error at line 3, column "));
}

// Some 130,000 levels crashed validate: copying the document recursed once per level.
TEST(JsonText, NestingDeeperThanAHundredLevelsIsRefusedWithThePath) {
  const auto nested = [](std::size_t levels) {
    return "{\"a\": " + std::string(levels - 1, '[') + std::string(levels - 1, ']') + "}";
  };
  EXPECT_EQ(syntax_message(nested(100)), "parsed");
  std::string path = "/a";  // the list on level 2; each on the levels 3 to 101 its parent's 0
  for (int level = 3; level <= 101; ++level) path += "/0";
  EXPECT_EQ(syntax_message(nested(101)),
            path +
                ": nested more than 100 levels deep; check the brackets: a millflow file nests "
                "a few levels");
  EXPECT_EQ(syntax_message(nested(200000)).substr(path.size()),
            ": nested more than 100 levels deep; check the brackets: a millflow file nests a few "
            "levels");
}

// The parser took a NUL byte for the end of the text and ignored the rest.
TEST(JsonText, ANulByteIsASyntaxErrorWhereverItIs) {
  EXPECT_EQ(syntax_message(std::string_view("{\"a\": 1}\n\0{\"b\"", 13)),
            "(document): JSON syntax error at line 2, column 1: a NUL byte; remove it (JSON text "
            "has none; write \\u0000 in a string for one)");
}

// 1e-401 read as 0 without a word, where 1e400 is refused: a lifter count of 1e-401 validated as
// no lifters. A written 0, a small normal number and numbers inside strings pass.
TEST(JsonText, ANumberTooSmallForADoubleIsRefusedWithThePath) {
  EXPECT_EQ(syntax_message(R"({"a": [0.5, {"b": 1e-401}]})"),
            "/a/1/b: number underflow parsing '1e-401'; write 0, or a number a double can hold "
            "(magnitude at least 2.2e-308)");
  EXPECT_EQ(syntax_message(R"({"a": -4e-320})"),
            "/a: number underflow parsing '-4e-320'; write 0, or a number a double can hold "
            "(magnitude at least 2.2e-308)");
  EXPECT_EQ(syntax_message(R"({"a \" 1e-401": [0, 0.0, 0e-500, 2.3e-308, -1, "1e-401"]})"),
            "parsed");
}

TEST(JsonText, KeysWrittenTwiceAreReportedWithTheirPath) {
  const auto parsed = parse_json_text(
      R"({"a": [{"x": 1}, {"y": [0, {"z": 1, "z": 2}], "y2": 0}], "b": 1, "b": 3})");
  ASSERT_EQ(parsed.duplicate_keys.size(), 2U);
  EXPECT_EQ(parsed.duplicate_keys[0].path, "/a/1/y/1/z");
  EXPECT_EQ(parsed.duplicate_keys[1].path, "/b");
  EXPECT_EQ(parsed.duplicate_keys[1].message(),
            "/b: key \"b\" appears twice in the same object; keep one of them (only the last one "
            "would count)");
  EXPECT_EQ(parsed.document["b"], 3);
}

TEST(JsonText, SameKeyInDifferentObjectsIsFine) {
  EXPECT_TRUE(parse_json_text(R"({"a": {"k": 1}, "b": {"k": 2}, "c": [{"k": 1}, {"k": 2}]})")
                  .duplicate_keys.empty());
}

}  // namespace
