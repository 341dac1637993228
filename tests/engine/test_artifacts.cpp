// The artifact store behind its FileSystem interface: a disk that fails in the middle of a copy
// leaves no partial file, and the task whose artifact could not be stored is retried.
#include <gtest/gtest.h>

#include <atomic>
#include <fstream>

#include "engine/artifacts.hpp"
#include "engine/files.hpp"
#include "engine/store.hpp"
#include "support_engine.hpp"
#include "util/sha256.hpp"

namespace millflow::engine::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The local disk, except that its first `failures` copies write half the file and then fail.
class DiskFullOnCopies final : public FileSystem {
 public:
  explicit DiskFullOnCopies(int failures) : failures_(failures) {}

  std::optional<std::int64_t> file_size(const fs::path& file) const override {
    return disk().file_size(file);
  }
  std::string sha256(const fs::path& file) const override { return disk().sha256(file); }
  void copy_durably(const fs::path& from, const fs::path& to) const override {
    if (failures_.fetch_sub(1) <= 0) return disk().copy_durably(from, to);
    fs::create_directories(to.parent_path());
    std::ifstream in(from, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(to, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    throw std::runtime_error("disk full (test)");
  }
  void rename(const fs::path& from, const fs::path& to) const override { disk().rename(from, to); }
  void remove(const fs::path& file) const override { disk().remove(file); }
  std::vector<fs::path> files_under(const fs::path& root) const override {
    return disk().files_under(root);
  }

 private:
  static const FileSystem& disk() { return local_file_system(); }
  mutable std::atomic<int> failures_;
};

TEST(Artifacts, CopyFailingMidwayLeavesNoPartialFile) {
  ScratchDir dir;
  const fs::path source = dir.path() / "payload.bin";
  std::ofstream(source, std::ios::binary) << std::string(10000, 'x');
  const DiskFullOnCopies disk(1);
  const ArtifactStore store(dir.path() / "artifacts", disk);

  EXPECT_THROW(store.put("payload.bin", source), std::runtime_error);
  EXPECT_TRUE(disk.files_under(store.root()).empty());

  const StoredArtifact stored = store.put("payload.bin", source);
  EXPECT_EQ(stored.sha256, util::sha256_hex(std::string(10000, 'x')));
  EXPECT_EQ(stored.size, 10000);
  EXPECT_TRUE(store.verify(stored));
  EXPECT_EQ(disk.files_under(store.root()), std::vector<fs::path>{store.path_of(stored.sha256)});
}

TEST(Artifacts, TaskWhoseArtifactCannotBeStoredFailsAndItsRetryCommits) {
  ScratchDir dir;
  const DiskFullOnCopies disk(1);
  SubmitOptions options;
  options.run.retries = 1;
  options.files = &disk;
  const auto campaign = test_campaign(
      "files",
      json::array(
          {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 7}, {"artifact", true}}}}}));
  const auto summary = submit_campaign(testing_registry(), campaign, dir.db(), options);
  EXPECT_EQ(summary.done, 1);
  EXPECT_EQ(summary.failed, 0);
  EXPECT_EQ(count(dir.db(), "SELECT attempts FROM tasks"), 2);
  EXPECT_EQ(count(dir.db(),
                  "SELECT count(*) FROM status_history WHERE status = 'failed' AND message = 'disk "
                  "full (test)'"),
            1);
  EXPECT_EQ(count(dir.db(), "SELECT json_extract(result, '$.sum') FROM results"), 7);
  auto connection = open_read_only(dir.db());
  auto row = connection.prepare("SELECT task_key FROM artifacts");
  ASSERT_TRUE(row.step());
  const auto artifact = find_artifacts(connection, row.text(0)).at(0);
  const ArtifactStore store(artifacts_dir(dir.db()));
  EXPECT_TRUE(store.verify(artifact));
  EXPECT_EQ(local_file_system().files_under(store.root()),
            std::vector<fs::path>{store.path_of(artifact.sha256)});
}

}  // namespace
}  // namespace millflow::engine::testing
