#include "dem/vtk.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>

#include "util/durable_file.hpp"

namespace millflow::dem {
namespace {

void append_vectors(std::string& text, const char* name, std::span<const Vec3> values,
                    std::span<const GroupId> groups) {
  text += fmt::format(
      R"(        <DataArray type="Float32" Name="{}" NumberOfComponents="3" format="ascii">)",
      name);
  text += '\n';
  for (std::size_t p = 0; p < values.size(); ++p) {
    if (groups[p] != kFreeParticle) continue;
    text += fmt::format("{} {} {}\n", static_cast<float>(values[p].x()),
                        static_cast<float>(values[p].y()), static_cast<float>(values[p].z()));
  }
  text += "        </DataArray>\n";
}

template <class T>
void append_scalars(std::string& text, const char* type, const char* name,
                    std::span<const T> values, std::span<const GroupId> groups) {
  text += fmt::format(R"(        <DataArray type="{}" Name="{}" format="ascii">)", type, name);
  text += '\n';
  for (std::size_t p = 0; p < values.size(); ++p) {
    if (groups[p] == kFreeParticle) text += fmt::format("{}\n", values[p]);
  }
  text += "        </DataArray>\n";
}

constexpr const char* kHeader =
    "<?xml version=\"1.0\"?>\n"
    "<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    "  <PolyData>\n";
constexpr const char* kFooter = "  </PolyData>\n</VTKFile>\n";

}  // namespace

void write_particles_vtp(const System& system, const std::filesystem::path& path) {
  const auto groups = system.particle_groups();
  std::size_t free = 0;
  for (GroupId g : groups) free += g == kFreeParticle ? 1 : 0;
  std::vector<float> radius;
  std::vector<std::int32_t> material;
  for (std::size_t p = 0; p < system.size(); ++p) {
    radius.push_back(static_cast<float>(system.radii()[p]));
    material.push_back(static_cast<std::int32_t>(system.particle_materials()[p]));
  }
  std::string text = kHeader;
  text +=
      fmt::format(R"(    <Piece NumberOfPoints="{}" NumberOfVerts="{}">)", free, free > 0 ? 1 : 0);
  text += "\n      <Points>\n";
  append_vectors(text, "position", system.positions(), groups);
  text += "      </Points>\n";
  if (free > 0) {  // one vertex cell holding every point, so ParaView shows them without a filter
    text +=
        "      <Verts>\n        <DataArray type=\"Int32\" Name=\"connectivity\" "
        "format=\"ascii\">\n";
    for (std::size_t p = 0; p < free; ++p) text += fmt::format("{}\n", p);
    text +=
        "        </DataArray>\n        <DataArray type=\"Int32\" Name=\"offsets\" "
        "format=\"ascii\">\n";
    text += fmt::format("{}\n        </DataArray>\n      </Verts>\n", free);
  }
  text += "      <PointData Scalars=\"radius\" Vectors=\"velocity\">\n";
  append_scalars<float>(text, "Float32", "radius", radius, groups);
  append_vectors(text, "velocity", system.velocities(), groups);
  append_vectors(text, "angular_velocity", system.angular_velocities(), groups);
  append_scalars<std::int32_t>(text, "Int32", "material", material, groups);
  text += "      </PointData>\n    </Piece>\n";
  text += kFooter;
  util::write_file_durably(path, text);
}

std::vector<Vec3> mill_outline(const MillShell& shell, double angle, int samples) {
  if (samples < 3)
    throw std::invalid_argument(fmt::format("mill outline: {} samples; use at least 3", samples));
  validate(shell);
  const double z = 0.5 * shell.length;
  std::vector<Vec3> outline;
  for (int k = 0; k < samples; ++k) {
    const double phi = 2.0 * std::numbers::pi * k / samples;
    const Vec3 direction(std::cos(phi), std::sin(phi), 0.0);
    // Inside at lo (the axis is always clear of the walls), not inside at hi (the shell).
    double lo = 0.0, hi = shell.radius;
    for (int iteration = 0; iteration < 40; ++iteration) {
      const double mid = 0.5 * (lo + hi);
      (sphere_clear_of_mill(shell, angle, mid * direction + Vec3(0, 0, z), 0.0) ? lo : hi) = mid;
    }
    outline.push_back(lo * direction);
  }
  return outline;
}

void write_mill_outline_vtp(const MillShell& shell, double angle, const std::filesystem::path& path,
                            int samples) {
  const auto outline = mill_outline(shell, angle, samples);
  const std::size_t n = outline.size();
  std::string text = kHeader;
  text += fmt::format(R"(    <Piece NumberOfPoints="{}" NumberOfLines="2">)", 2 * n);
  text +=
      "\n      <Points>\n        <DataArray type=\"Float32\" NumberOfComponents=\"3\" "
      "format=\"ascii\">\n";
  for (const double z : {0.0, shell.length}) {
    for (const Vec3& p : outline)
      text += fmt::format("{} {} {}\n", static_cast<float>(p.x()), static_cast<float>(p.y()), z);
  }
  text += "        </DataArray>\n      </Points>\n      <Lines>\n";
  text += "        <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  for (std::size_t ring = 0; ring < 2; ++ring) {
    for (std::size_t k = 0; k <= n; ++k)
      text += fmt::format("{}\n", ring * n + k % n);  // closed: back to the start
  }
  text +=
      "        </DataArray>\n        <DataArray type=\"Int32\" Name=\"offsets\" "
      "format=\"ascii\">\n";
  text += fmt::format("{}\n{}\n        </DataArray>\n      </Lines>\n    </Piece>\n", n + 1,
                      2 * (n + 1));
  text += kFooter;
  util::write_file_durably(path, text);
}

void write_pvd(const std::filesystem::path& path, std::span<const PvdEntry> entries) {
  std::string text =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" "
      "byte_order=\"LittleEndian\">\n"
      "  <Collection>\n";
  for (const PvdEntry& entry : entries) {
    text += fmt::format(R"(    <DataSet timestep="{}" group="" part="0" file="{}"/>)", entry.time,
                        entry.file);
    text += '\n';
  }
  text += "  </Collection>\n</VTKFile>\n";
  util::write_file_durably(path, text);
}

}  // namespace millflow::dem
