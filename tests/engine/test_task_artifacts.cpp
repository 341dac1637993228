// Finding the artifacts of a campaign's finished tasks of one kind, and copying them out of the
// store (what `millflow report` does with the report task's files).
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "engine/inspect.hpp"
#include "engine/store.hpp"
#include "engine/validation.hpp"
#include "support_engine.hpp"

namespace millflow::engine::testing {
namespace {

using nlohmann::json;

// a(1, writes sum.txt = "1") -> b(2); and a fanout task of another kind.
json tasks() {
  return json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}, {"artifact", true}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}}}, {"after", {"a"}}},
       {{"id", "f"}, {"kind", "fanout"}, {"params", {{"children", 0}, {"value", 5}}}}});
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string key_of_value(const std::filesystem::path& db, int value) {
  auto connection = open_read_only(db);
  auto row = connection.prepare(
      "SELECT key FROM tasks WHERE kind = 'sum' AND json_extract(params, '$.value') = ?");
  row.bind_all(value);
  EXPECT_TRUE(row.step());
  return row.text(0);
}

class TaskArtifactsTest : public ::testing::Test {
 protected:
  void SetUp() override { submit(test_campaign("artifacts", tasks()), dir_.db()); }
  ScratchDir dir_;
};

TEST_F(TaskArtifactsTest, ListsTheFinishedTasksOfOneKindWithTheirArtifacts) {
  const auto found = finished_task_artifacts(dir_.db(), "artifacts", "sum");
  ASSERT_EQ(found.size(), 2u);
  for (const TaskArtifacts& task : found) {
    if (task.task_key == key_of_value(dir_.db(), 1)) {
      ASSERT_EQ(task.artifacts.size(), 1u);
      EXPECT_EQ(task.artifacts[0].name, "sum.txt");
    } else {
      EXPECT_EQ(task.task_key, key_of_value(dir_.db(), 2));
      EXPECT_TRUE(task.artifacts.empty());
    }
  }
  EXPECT_EQ(finished_task_artifacts(dir_.db(), "artifacts", "fanout").size(), 1u);
  EXPECT_TRUE(finished_task_artifacts(dir_.db(), "artifacts", "report").empty());
  EXPECT_THROW(finished_task_artifacts(dir_.db(), "nope", "sum"), InvalidInput);
}

TEST_F(TaskArtifactsTest, CopiesVerifiedArtifactsUnderTheirNames) {
  const auto found = finished_task_artifacts(dir_.db(), "artifacts", "sum");
  const auto& with_file = found[0].artifacts.empty() ? found[1] : found[0];
  const auto out = dir_.path() / "out" / "nested";
  const auto copied = copy_artifacts(dir_.db(), with_file.artifacts, out);
  ASSERT_EQ(copied, std::vector<std::filesystem::path>{out / "sum.txt"});
  EXPECT_EQ(read_text(copied[0]), "1\n");
}

TEST_F(TaskArtifactsTest, CorruptArtifactIsRefusedByName) {
  const auto found = finished_task_artifacts(dir_.db(), "artifacts", "sum");
  const auto& with_file = found[0].artifacts.empty() ? found[1] : found[0];
  std::ofstream(ArtifactStore(artifacts_dir(dir_.db())).path_of(with_file.artifacts[0].sha256))
      << "tampered\n";
  try {
    copy_artifacts(dir_.db(), with_file.artifacts, dir_.path() / "out");
    FAIL() << "expected std::runtime_error";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("artifact sum.txt"), std::string::npos)
        << error.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir_.path() / "out" / "sum.txt"));
}

}  // namespace
}  // namespace millflow::engine::testing
