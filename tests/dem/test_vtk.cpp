// ParaView files: particle points and data, the mill outline and collections.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <numbers>
#include <sstream>

#include "dem/vtk.hpp"
#include "tests/dem/scenes.hpp"

namespace millflow::dem {
namespace {

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// An XML attribute's value in `element`.
std::string attribute(const std::string& element, const std::string& name) {
  const auto start = element.find(" " + name + "=\"") + name.size() + 3;
  return element.substr(start, element.find('"', start) - start);
}

// The values of the appended DataArray named `name` (dem/vtk.hpp's layout), as doubles.
std::vector<double> data_array(const std::string& text, const std::string& name) {
  const auto at = text.find("Name=\"" + name + "\"");
  if (at == std::string::npos) return {};
  const auto open = text.rfind('<', at);
  const std::string element = text.substr(open, text.find('>', at) - open);
  const std::string raw = text.substr(text.find('_', text.find("<AppendedData")) + 1);
  const auto offset = std::stoull(attribute(element, "offset"));
  std::uint64_t bytes = 0;
  std::memcpy(&bytes, raw.data() + offset, sizeof bytes);
  const char* data = raw.data() + offset + sizeof bytes;
  const std::string type = attribute(element, "type");
  std::vector<double> values;
  auto read = [&]<class T>(T) {
    for (std::size_t k = 0; k < bytes / sizeof(T); ++k) {
      T value;
      std::memcpy(&value, data + k * sizeof(T), sizeof(T));
      values.push_back(static_cast<double>(value));
    }
  };
  if (type == "Float32") read(float{});
  if (type == "Float64") read(double{});
  if (type == "Int32") read(std::int32_t{});
  if (type == "Int64") read(std::int64_t{});
  return values;
}

std::vector<double> as_floats(std::vector<double> values) {
  for (double& v : values) v = static_cast<float>(v);
  return values;
}

// A 1 m mill slice with four radial lifters of 50 mm.
MillShell four_lifter_shell() {
  return {.radius = 0.5,
          .length = 0.1,
          .lifter_count = 4,
          .lifter = {.height = 0.05, .base_width = 0.08, .face_angle_deg = 0.0},
          .end_walls = false};
}

TEST(Vtk, ParticlesCarryTheirStateAsPointData) {
  System system(testing::steel_table(0.5, 0.5), testing::open_box(1.0), Vec3(0, -9.81, 0));
  system.add_particle({.position = Vec3(0.1, 0.2, 0.3), .velocity = Vec3(1, 2, 3), .radius = 0.01});
  system.add_particle(
      {.position = Vec3(-0.1, 0, 0), .angular_velocity = Vec3(0, 0, 5), .radius = 0.02});
  const auto path = std::filesystem::temp_directory_path() / "millflow_test_particles.vtp";
  write_particles_vtp(system, path);
  const std::string text = read_file(path);
  std::filesystem::remove(path);
  EXPECT_NE(text.find("NumberOfPoints=\"2\""), std::string::npos);
  EXPECT_NE(text.find("<AppendedData encoding=\"raw\">"), std::string::npos);
  EXPECT_EQ(data_array(text, "position"), as_floats({0.1, 0.2, 0.3, -0.1, 0, 0}));
  EXPECT_EQ(data_array(text, "id"), (std::vector<double>{0, 1}));
  EXPECT_EQ(data_array(text, "radius"), as_floats({0.01, 0.02}));
  EXPECT_EQ(data_array(text, "velocity"), (std::vector<double>{1, 2, 3, 0, 0, 0}));
  EXPECT_EQ(data_array(text, "angular_velocity"), (std::vector<double>{0, 0, 0, 0, 0, 5}));
  EXPECT_EQ(data_array(text, "material"), (std::vector<double>{0, 0}));
  EXPECT_EQ(data_array(text, "connectivity"), (std::vector<double>{0, 1}));
}

TEST(Vtk, MillOutlineFollowsTheLinerAndTheLifters) {
  const MillShell shell = four_lifter_shell();
  const double angle = 0.3;
  const auto outline = mill_outline(shell, angle, 720);
  ASSERT_EQ(outline.size(), 720u);
  // The sample nearest `phi`: its radius and its angle from phi.
  auto sample_near = [&](double phi) {
    const auto k = std::lround(phi / (2 * std::numbers::pi) * 720);
    return std::pair(outline[static_cast<std::size_t>(k % 720)].norm(),
                     2 * std::numbers::pi * k / 720 - phi);
  };
  // A lifter's flat top R - h, seen from the axis at angle delta off its centreline: (R - h) /
  // cos(delta).
  for (const double centreline : {angle, angle + std::numbers::pi / 2}) {
    const auto [r, delta] = sample_near(centreline);
    EXPECT_NEAR(r, 0.45 / std::cos(delta), 1e-8);
  }
  EXPECT_NEAR(sample_near(angle + std::numbers::pi / 4).first, 0.5,
              1e-8);  // between lifters: the liner
}

TEST(Vtk, MillOutlineFileHoldsTwoClosedRingsAtTheShellsAngle) {
  const MillShell shell = four_lifter_shell();
  const auto path = std::filesystem::temp_directory_path() / "millflow_test_mill.vtp";
  write_mill_outline_vtp(shell, 0.3, path, 8);
  const std::string text = read_file(path);
  std::filesystem::remove(path);
  EXPECT_NE(text.find("NumberOfPoints=\"16\" NumberOfLines=\"2\""), std::string::npos);
  EXPECT_EQ(data_array(text, "angle_rad"), (std::vector<double>{0.3}));
  EXPECT_EQ(data_array(text, "connectivity"),
            (std::vector<double>{0, 1, 2, 3, 4, 5, 6, 7, 0, 8, 9, 10, 11, 12, 13, 14, 15, 8}));
  EXPECT_EQ(data_array(text, "offsets"), (std::vector<double>{9, 18}));
}

TEST(Vtk, CollectionListsEveryFileWithItsTime) {
  const auto path = std::filesystem::temp_directory_path() / "millflow_test.pvd";
  const std::vector<PvdEntry> entries = {{0.0, "a.vtp"}, {0.5, "b.vtp"}};
  write_pvd(path, entries);
  const std::string text = read_file(path);
  std::filesystem::remove(path);
  EXPECT_NE(text.find(R"(timestep="0" group="" part="0" file="a.vtp")"), std::string::npos);
  EXPECT_NE(text.find(R"(timestep="0.5" group="" part="0" file="b.vtp")"), std::string::npos);
}

}  // namespace
}  // namespace millflow::dem
