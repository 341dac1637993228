// A full disk in every writer: each reports ENOSPC as an exception that fails the caller's work,
// leaves the previous file (or none) and no temporary file. A VTK image used to terminate the
// process from a destructor's flush instead (exit 134).
#include <gtest/gtest.h>

#include <cerrno>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <system_error>

#include "dem/binary_io.hpp"
#include "dem/vtk.hpp"
#include "engine/artifacts.hpp"
#include "method/vtk_image.hpp"
#include "tests/dem/scenes.hpp"
#include "tests/tasks/macro_fixtures.hpp"
#include "util/durable_file.hpp"

namespace millflow::tasks {
namespace {

namespace fs = std::filesystem;
using testing::ScratchDir;

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Runs `write` on a disk with `room` bytes left and expects ENOSPC with no file left behind in
// `dir` but those that were there before.
void expect_full_disk_error(const fs::path& dir, const std::function<void()>& write,
                            std::int64_t room = 10) {
  std::set<fs::path> before;
  for (const auto& entry : fs::recursive_directory_iterator(dir))
    if (entry.is_regular_file()) before.insert(entry.path());
  {
    const util::SimulatedFullDisk full(room);
    try {
      write();
      ADD_FAILURE() << "a write to a full disk succeeded";
    } catch (const std::system_error& error) {
      EXPECT_EQ(error.code().value(), ENOSPC) << error.what();
      EXPECT_NE(std::string(error.what()).find("No space left on device"), std::string::npos);
    }
  }
  std::set<fs::path> after;
  for (const auto& entry : fs::recursive_directory_iterator(dir))
    if (entry.is_regular_file()) after.insert(entry.path());
  EXPECT_EQ(after, before);
}

TEST(FullDisk, DemWritersReportItAndKeepThePreviousFile) {
  ScratchDir scratch("full_disk_dem");
  const fs::path dir = scratch.path();
  dem::System system(dem::testing::steel_table(0.5, 0.5), dem::testing::open_box(1.0),
                     dem::Vec3(0, -9.81, 0));
  system.add_particle({.position = dem::Vec3(0.1, 0.2, 0.3), .radius = 0.01});
  dem::write_particles_vtp(system, dir / "p.vtp");
  const std::string previous = read_file(dir / "p.vtp");
  expect_full_disk_error(dir, [&] { dem::write_particles_vtp(system, dir / "p.vtp"); });
  EXPECT_EQ(read_file(dir / "p.vtp"), previous);
  const std::vector<dem::PvdEntry> entries{{0.0, "p.vtp"}};
  expect_full_disk_error(dir, [&] { dem::write_pvd(dir / "p.pvd", entries); });
  expect_full_disk_error(dir, [&] {
    dem::write_checksummed_file(dir / "state.bin", "MFTEST01", 1, std::string(1000, 'x'));
  });
}

TEST(FullDisk, VtkImageReportsItInsteadOfTerminating) {
  ScratchDir scratch("full_disk_vti");
  const method::CrossSectionGrid grid{.nx = 20, .ny = 20, .half_width = 0.5};
  const std::vector<method::CellArray> arrays{
      {"density", 1, std::vector<double>(grid.size(), 1.5)}};
  expect_full_disk_error(scratch.path(), [&] {
    method::write_vtk_image(scratch.path() / "fields.vti", grid, arrays);
  });
}

TEST(FullDisk, AnArtifactThatCannotBeStoredIsAnErrorAndLeavesNoPart) {
  ScratchDir scratch("full_disk_artifacts");
  const fs::path file = scratch.path() / "big.bin";
  util::write_file_durably(file, std::string(100000, 'a'));
  fs::create_directories(scratch.path() / "store");
  const engine::ArtifactStore store(scratch.path() / "store");
  expect_full_disk_error(
      scratch.path(), [&] { store.put("big.bin", file); }, 50000);
  EXPECT_EQ(store.stored_files(), std::vector<fs::path>{});
}

TEST(FullDisk, AMacroRunFailsWithTheErrorInsteadOfAborting) {
  ScratchDir scratch("full_disk_macro");
  const testing::DirectRun run{testing::tiny_macro_params(), scratch.path() / "work"};
  const util::SimulatedFullDisk full(0);
  try {
    run.run();
    FAIL() << "a macro run on a full disk succeeded";
  } catch (const std::system_error& error) {
    EXPECT_EQ(error.code().value(), ENOSPC) << error.what();
  }
}

}  // namespace
}  // namespace millflow::tasks
