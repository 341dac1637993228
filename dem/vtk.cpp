#include "dem/vtk.hpp"

#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>

#include "util/durable_file.hpp"

namespace millflow::dem {
namespace {

// The DataArrays of one file, appended as raw bytes after the XML (dem/vtk.hpp).
class AppendedArrays {
 public:
  // The DataArray element of `values` (a name-less one when `name` is empty).
  template <class T>
  std::string array(const char* type, std::string_view name, int components,
                    std::span<const T> values) {
    std::string element = fmt::format(R"(        <DataArray type="{}"{} NumberOfComponents="{}" )"
                                      R"(NumberOfTuples="{}" format="appended" offset="{}"/>)",
                                      type, name.empty() ? "" : fmt::format(R"( Name="{}")", name),
                                      components, values.size() / components, raw_.size());
    const std::uint64_t bytes = values.size_bytes();
    raw_.append(reinterpret_cast<const char*>(&bytes), sizeof bytes);
    raw_.append(reinterpret_cast<const char*>(values.data()), bytes);
    return element + '\n';
  }
  std::string appended_data() const {
    return "  <AppendedData encoding=\"raw\">\n   _" + raw_ + "\n  </AppendedData>\n";
  }

 private:
  std::string raw_;
};

std::vector<float> free_vectors(std::span<const Vec3> values, std::span<const GroupId> groups) {
  std::vector<float> flat;
  for (std::size_t p = 0; p < values.size(); ++p) {
    if (groups[p] != kFreeParticle) continue;
    for (int axis = 0; axis < 3; ++axis) flat.push_back(static_cast<float>(values[p][axis]));
  }
  return flat;
}

// The rows of the free particles (rows indexed by particle).
template <class T, class Row>
std::vector<T> free_rows(std::span<const GroupId> groups, Row row) {
  std::vector<T> values;
  for (std::size_t p = 0; p < groups.size(); ++p) {
    if (groups[p] == kFreeParticle) values.push_back(static_cast<T>(row(p)));
  }
  return values;
}

// Little-endian is what the files declare; the bytes are copied as the machine holds them.
static_assert(std::endian::native == std::endian::little, "VTK files are written little-endian");

constexpr const char* kHeader =
    "<?xml version=\"1.0\"?>\n"
    "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
    "header_type=\"UInt64\">\n"
    "  <PolyData>\n";

std::string footer(const AppendedArrays& arrays) {
  return "  </PolyData>\n" + arrays.appended_data() + "</VTKFile>\n";
}

}  // namespace

void write_particles_vtp(const System& system, const std::filesystem::path& path) {
  const auto groups = system.particle_groups();
  const auto ids = free_rows<std::int64_t>(groups, [](std::size_t p) { return p; });
  const std::size_t free = ids.size();
  AppendedArrays arrays;
  std::string text = kHeader;
  text +=
      fmt::format(R"(    <Piece NumberOfPoints="{}" NumberOfVerts="{}">)", free, free > 0 ? 1 : 0);
  text += "\n      <Points>\n";
  text += arrays.array<float>("Float32", "position", 3, free_vectors(system.positions(), groups));
  text += "      </Points>\n";
  if (free > 0) {  // one vertex cell holding every point, so ParaView shows them without a filter
    std::vector<std::int64_t> connectivity(free);
    for (std::size_t p = 0; p < free; ++p) connectivity[p] = static_cast<std::int64_t>(p);
    const std::vector<std::int64_t> offsets{static_cast<std::int64_t>(free)};
    text += "      <Verts>\n";
    text += arrays.array<std::int64_t>("Int64", "connectivity", 1, connectivity);
    text += arrays.array<std::int64_t>("Int64", "offsets", 1, offsets);
    text += "      </Verts>\n";
  }
  text += "      <PointData Scalars=\"radius\" Vectors=\"velocity\">\n";
  text += arrays.array<std::int64_t>("Int64", "id", 1, ids);
  text += arrays.array<float>("Float32", "radius", 1, free_rows<float>(groups, [&](std::size_t p) {
                                return system.radii()[p];
                              }));
  text += arrays.array<float>("Float32", "velocity", 3, free_vectors(system.velocities(), groups));
  text += arrays.array<float>("Float32", "angular_velocity", 3,
                              free_vectors(system.angular_velocities(), groups));
  text += arrays.array<std::int32_t>("Int32", "material", 1,
                                     free_rows<std::int32_t>(groups, [&](std::size_t p) {
                                       return system.particle_materials()[p];
                                     }));
  text += "      </PointData>\n    </Piece>\n";
  text += footer(arrays);
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
  std::vector<float> points;
  for (const double z : {0.0, shell.length}) {
    for (const Vec3& p : outline) {
      points.insert(points.end(),
                    {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(z)});
    }
  }
  std::vector<std::int64_t> connectivity;
  for (std::size_t ring = 0; ring < 2; ++ring) {
    for (std::size_t k = 0; k <= n; ++k)
      connectivity.push_back(static_cast<std::int64_t>(ring * n + k % n));  // closed
  }
  const std::vector<std::int64_t> offsets{static_cast<std::int64_t>(n + 1),
                                          static_cast<std::int64_t>(2 * (n + 1))};
  const std::vector<double> angle_value{angle};
  AppendedArrays arrays;
  std::string text = kHeader;
  text += "    <FieldData>\n";
  text += arrays.array<double>("Float64", "angle_rad", 1, angle_value);
  text += "    </FieldData>\n";
  text += fmt::format(R"(    <Piece NumberOfPoints="{}" NumberOfLines="2">)", 2 * n);
  text += "\n      <Points>\n";
  text += arrays.array<float>("Float32", "", 3, points);
  text += "      </Points>\n      <Lines>\n";
  text += arrays.array<std::int64_t>("Int64", "connectivity", 1, connectivity);
  text += arrays.array<std::int64_t>("Int64", "offsets", 1, offsets);
  text += "      </Lines>\n    </Piece>\n";
  text += footer(arrays);
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
