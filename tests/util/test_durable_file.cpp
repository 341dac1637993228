// Durable writes: whole files or nothing, errors as exceptions (a full disk included), and the one
// SHA-256.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <sstream>
#include <system_error>

#include "tests/common/scratch_dir.hpp"
#include "util/durable_file.hpp"
#include "util/sha256.hpp"

namespace millflow::util {
namespace {

namespace fs = std::filesystem;
using millflow::testing::ScratchDir;

std::string read(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::size_t entries(const fs::path& dir) {
  return static_cast<std::size_t>(
      std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

TEST(DurableFile, WritesAndReplacesAWholeFile) {
  ScratchDir dir;
  const fs::path file = dir.path() / "a.txt";
  write_file_durably(file, "first");
  write_file_durably(file, "second, longer");
  EXPECT_EQ(read(file), "second, longer");
  EXPECT_EQ(entries(dir.path()), 1u);  // no temporary left behind
}

TEST(DurableFile, NewFilesGetThePermissionsOfAPlainOpen) {
  ScratchDir dir;
  const mode_t mask = ::umask(027);
  ::umask(mask);  // read it back: the tests run single-threaded here
  write_file_durably(dir.path() / "shared", "x");
  const auto permissions = fs::status(dir.path() / "shared").permissions();
  EXPECT_EQ(static_cast<mode_t>(permissions) & 0777, 0666 & ~mask);
}

TEST(DurableFile, AFullDiskIsAnExceptionAndLeavesTheOldFileAndNoTemporary) {
  ScratchDir dir;
  const fs::path file = dir.path() / "a.txt";
  write_file_durably(file, "old");
  const SimulatedFullDisk full(4);
  try {
    write_file_durably(file, "new text that does not fit");
    FAIL() << "a write to a full disk succeeded";
  } catch (const std::system_error& error) {
    EXPECT_EQ(error.code().value(), ENOSPC);
    EXPECT_EQ(std::string(error.what()),
              "cannot write '" + file.string() + "': No space left on device");
  }
  EXPECT_EQ(read(file), "old");
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(DurableFile, AnUncommittedFileLeavesNothing) {
  ScratchDir dir;
  {
    DurableFile file(dir.path() / "b.txt");
    file.append("abandoned");
  }
  EXPECT_EQ(entries(dir.path()), 0u);
}

TEST(DurableFile, CopiesAndReportsAMissingSource) {
  ScratchDir dir;
  write_file_durably(dir.path() / "from", std::string(200000, 'x'));
  copy_file_durably(dir.path() / "from", dir.path() / "to");
  EXPECT_EQ(read(dir.path() / "to"), std::string(200000, 'x'));
  EXPECT_THROW(copy_file_durably(dir.path() / "missing", dir.path() / "to2"), std::system_error);
  EXPECT_FALSE(fs::exists(dir.path() / "to2"));
}

TEST(DurableFile, AMissingDirectoryIsReported) {
  ScratchDir dir;
  EXPECT_THROW(write_file_durably(dir.path() / "no" / "such" / "file", "x"), std::system_error);
}

// `millflow report --out DIR` killed part-way left DIR with some of its files and the temporary
// file of the one being copied: a new directory is now filled under another name, then renamed.
TEST(DurableFile, ANewDirectoryIsWholeOrAbsent) {
  ScratchDir dir;
  const fs::path target = dir.path() / "report";
  const fs::path staging = dir.path() / ".report.partial";
  EXPECT_THROW(fill_directory_durably(target,
                                      [](const fs::path& into) {
                                        write_file_durably(into / "a.svg", "a");
                                        throw std::runtime_error("killed");
                                      }),
               std::runtime_error);
  EXPECT_FALSE(fs::exists(target));
  EXPECT_FALSE(fs::exists(staging));

  fs::create_directories(staging);  // as a kill -9 part-way leaves it
  write_file_durably(staging / "stale.svg", "old");
  fill_directory_durably(dir.path() / "report/", [&](const fs::path& into) {
    EXPECT_NE(into, target);
    write_file_durably(into / "index.md", "whole");
  });
  EXPECT_EQ(read(target / "index.md"), "whole");
  EXPECT_EQ(entries(target), 1u);
  EXPECT_EQ(entries(dir.path()), 1u);

  fill_directory_durably(target, [&](const fs::path& into) {  // an existing one: staged inside
    EXPECT_EQ(into, target / kStagingDirectoryName);
    write_file_durably(into / "b.svg", "b");
  });
  EXPECT_EQ(entries(target), 2u);
  EXPECT_EQ(read(target / "b.svg"), "b");
}

// `millflow report --out DIR` into an existing DIR, killed part-way, left DIR with some files of
// the new report among the old report's: the new files are now staged inside DIR and moved in
// only once all are written, replacing those of the same names and keeping the others.
TEST(DurableFile, AnExistingDirectoryKeepsItsFilesUntilTheFillIsWhole) {
  ScratchDir dir;
  const fs::path target = dir.path() / "report";
  write_file_durably(dir.path() / "keep", "");
  fs::create_directories(target / "plots");
  write_file_durably(target / "index.md", "old");
  write_file_durably(target / "plots" / "a.svg", "old");
  write_file_durably(target / "notes.txt", "the user's");
  write_file_durably(target / "table", "a file where the new fill has a directory");
  const auto fill_new = [](const fs::path& into) {
    fs::create_directories(into / "plots");
    fs::create_directories(into / "table");
    write_file_durably(into / "index.md", "new");
    write_file_durably(into / "plots" / "a.svg", "new");
    write_file_durably(into / "plots" / "b.svg", "new");
    write_file_durably(into / "table" / "t.csv", "new");
  };
  EXPECT_THROW(fill_directory_durably(target,
                                      [&](const fs::path& into) {
                                        fill_new(into);
                                        throw std::runtime_error("killed");
                                      }),
               std::runtime_error);
  EXPECT_EQ(read(target / "index.md"), "old");
  EXPECT_EQ(read(target / "plots" / "a.svg"), "old");
  EXPECT_EQ(entries(target / "plots"), 1u);
  EXPECT_EQ(entries(target), 4u) << "nothing of the failed fill remains";

  fs::create_directories(target / kStagingDirectoryName);  // as a kill -9 part-way leaves it
  write_file_durably(target / kStagingDirectoryName / "stale.svg", "stale");
  fill_directory_durably(target, fill_new);
  EXPECT_EQ(read(target / "index.md"), "new");
  EXPECT_EQ(read(target / "plots" / "a.svg"), "new");
  EXPECT_EQ(read(target / "plots" / "b.svg"), "new");
  EXPECT_EQ(read(target / "table" / "t.csv"), "new");
  EXPECT_EQ(read(target / "notes.txt"), "the user's");
  EXPECT_FALSE(fs::exists(target / "stale.svg"));
  EXPECT_EQ(entries(target), 4u) << "index.md, plots, table, notes.txt: no staging left";
  EXPECT_EQ(entries(dir.path()), 2u);
}

TEST(Sha256, KnownDigestsOfTextAndFiles) {
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  ScratchDir dir;
  write_file_durably(dir.path() / "abc", "abc");
  EXPECT_EQ(sha256_file_hex(dir.path() / "abc"), sha256_hex("abc"));
  EXPECT_THROW(sha256_file_hex(dir.path() / "missing"), std::runtime_error);
}

}  // namespace
}  // namespace millflow::util
