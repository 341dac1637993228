#pragma once
// ParaView files without the VTK library: XML PolyData (.vtp) of the particles and of the mill's
// outline, and .pvd collections that put a series of files on a time axis.
//
// Format of the .vtp files (VTK XML, version 1.0, byte_order LittleEndian, header_type UInt64):
// every DataArray is format="appended" and its bytes follow in one <AppendedData
// encoding="raw"> block after a '_': per array a UInt64 byte count, then the values in
// little-endian binary, in the order the arrays appear in the XML (offset = where its count
// starts, from the byte after the '_'). No compression. Any VTK reader (ParaView, VisIt,
// Python's vtkXMLPolyDataReader) reads them; tests/cli/check_vtk_files.py does in the tests.
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "dem/system.hpp"
#include "dem/wall_geometry.hpp"

namespace millflow::dem {

// The free particles as points at their centres (Float32), with point data "id" (Int64: the
// particle's index in the system, the same particle in every file of a run), "radius",
// "velocity", "angular_velocity" (Float32) and "material" (Int32, the material id), each one
// row per particle, and one vertex cell holding every point. Render with a Glyph filter
// (sphere, scale by radius, factor 2). Written durably (util/durable_file.hpp);
// std::system_error on I/O failure (a full disk included).
void write_particles_vtp(const System& system, const std::filesystem::path& path);

// The mill's cross-section outline (liner between the lifters and the lifter profiles) with the
// shell turned by `angle`: `samples` points around the axis, from the axis outwards to the
// first wall, star-shaped, each point found by bisection to 1e-9 of the radius.
std::vector<Vec3> mill_outline(const MillShell& shell, double angle, int samples);

// The outline as two closed polylines, at z = 0 and z = length (atomic write), with the field
// data "angle_rad" (Float64, the shell's angle).
void write_mill_outline_vtp(const MillShell& shell, double angle, const std::filesystem::path& path,
                            int samples = 720);

struct PvdEntry {
  double time = 0.0;
  std::string file;  // relative to the .pvd file
};

// A ParaView collection of `entries` in time order (atomic write).
void write_pvd(const std::filesystem::path& path, std::span<const PvdEntry> entries);

}  // namespace millflow::dem
