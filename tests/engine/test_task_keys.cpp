// Canonical JSON spellings and task-key stability.
#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>

#include "engine/canonical_json.hpp"
#include "engine/task.hpp"
#include "engine/validation.hpp"
#include "util/sha256.hpp"

namespace millflow::engine {
namespace {

using nlohmann::json;

TEST(CanonicalJson, SortsKeysAndDropsWhitespace) {
  EXPECT_EQ(canonical_json(json::parse(R"({ "b": 1, "a": {"d": [1, 2], "c": null} })")),
            R"({"a":{"c":null,"d":[1,2]},"b":1})");
}

TEST(CanonicalJson, IntegersStayDistinctFromFloats) {
  EXPECT_EQ(canonical_json(json::parse("1")), "1");
  EXPECT_EQ(canonical_json(json::parse("1.0")), "1.0");
  EXPECT_EQ(canonical_json(json::parse("-7")), "-7");
  EXPECT_NE(canonical_json(json::parse("[1]")), canonical_json(json::parse("[1.0]")));
}

TEST(CanonicalJson, OneSpellingPerFloat) {
  EXPECT_EQ(canonical_json(json::parse("0.10")), canonical_json(json::parse("1e-1")));
  EXPECT_EQ(canonical_json(json::parse("2.50")), "2.5");
  EXPECT_EQ(canonical_json(json(-0.0)), "0.0");
  EXPECT_EQ(canonical_json(json::parse("1E300")), canonical_json(json::parse("1e+300")));
}

TEST(CanonicalJson, FloatsRoundTripExactly) {
  for (const double value :
       {0.1, 1.0 / 3.0, 6.02214076e23, 5e-324, std::numeric_limits<double>::max(), 123456.789}) {
    EXPECT_EQ(json::parse(canonical_json(json(value))).get<double>(), value)
        << canonical_json(json(value));
  }
}

TEST(CanonicalJson, EscapesOnlyWhatJsonRequires) {
  EXPECT_EQ(canonical_json(json("a\"b\\c\nd\x01 é")), "\"a\\\"b\\\\c\\nd\\u0001 é\"");
}

TEST(CanonicalJson, RefusesNonFiniteNumbers) {
  EXPECT_THROW(canonical_json(json{{"x", std::numeric_limits<double>::quiet_NaN()}}), InvalidInput);
  EXPECT_THROW(canonical_json(json(std::numeric_limits<double>::infinity())), InvalidInput);
}

TEST(TaskKey, IsTheSha256OfTheStoredText) {
  const auto spec = make_task_spec("sum", "1", json{{"value", 3}}, {"aa", "bb"});
  EXPECT_EQ(spec.key_text,
            "millflow-task 1\nkind:sum\nversion:1\nparams:{\"value\":3}\nupstream:aa,bb\n");
  EXPECT_EQ(spec.key, util::sha256_hex(spec.key_text));
}

TEST(TaskKey, Sha256MatchesTheStandardTestVector) {
  // FIPS 180-2 test vector for "abc".
  EXPECT_EQ(util::sha256_hex("abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(TaskKey, GoldenKeyForAFixedTask) {
  // GOLDEN: recorded from this implementation. If it changes, every stored cache is invalidated:
  // change it only together with the "millflow-task 1" tag of the key text. The value equals
  // `printf ... | sha256sum` (coreutils) of the text in the line above.
  const auto spec = make_task_spec(
      "macro", "2", json::parse(R"({"speed": 0.75, "fill": 0.3, "balls": 1000})"), {});
  EXPECT_EQ(spec.key,
            util::sha256_hex("millflow-task "
                             "1\nkind:macro\nversion:2\nparams:{\"balls\":1000,\"fill\":0.3,"
                             "\"speed\":0.75}\nupstream:\n"));
  EXPECT_EQ(spec.key, "2ee358402de72664d4ce899fcf6be552d418c4ad87fec20bff9074c982092103");
}

TEST(TaskKey, ChangesWithEveryIngredientAndNothingElse) {
  const auto base = make_task_spec("sum", "1", json{{"value", 3}, {"w", 1.5}}, {"up"});
  EXPECT_EQ(base.key,
            make_task_spec("sum", "1", json::parse(R"({"w": 1.50, "value": 3})"), {"up"}).key);
  EXPECT_NE(base.key, make_task_spec("sum", "2", json{{"value", 3}, {"w", 1.5}}, {"up"}).key);
  EXPECT_NE(base.key, make_task_spec("sum", "1", json{{"value", 4}, {"w", 1.5}}, {"up"}).key);
  EXPECT_NE(base.key, make_task_spec("sum", "1", json{{"value", 3.0}, {"w", 1.5}}, {"up"}).key);
  EXPECT_NE(base.key, make_task_spec("sum", "1", json{{"value", 3}, {"w", 1.5}}, {"other"}).key);
  EXPECT_NE(base.key, make_task_spec("fail", "1", json{{"value", 3}, {"w", 1.5}}, {"up"}).key);
}

// The store reads a task's parameters back from its key text: the canonical JSON hashed into the
// key, whatever the strings in it hold (a "\nupstream:" inside a parameter stays escaped).
TEST(TaskKey, TheKeyTextGivesBackTheParametersHashedIntoIt) {
  const json params = {{"note", "a\nupstream:b"}, {"fill", 0.3}, {"list", {1, 2}}};
  const TaskSpec spec = make_task_spec("macro", "1", params, {"k1", "k2"});
  EXPECT_EQ(key_text_params(spec.key_text), canonical_json(params));
  EXPECT_THROW(key_text_params("millflow-task 1\nkind:macro\n"), std::logic_error);
}

}  // namespace
}  // namespace millflow::engine
