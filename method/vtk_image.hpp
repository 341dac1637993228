#pragma once
// VTK XML image data (.vti) of cell arrays over a cross-section grid, for ParaView: one layer of
// nx x ny cells spanning [-R, R]^2 at z in [0, 1 cell], every array as ASCII cell data.
#include <filesystem>
#include <span>

#include "method/cross_section_grid.hpp"

namespace millflow::method {

// Throws std::invalid_argument for an array whose size is not cells x components, and
// std::system_error when the file cannot be written.
void write_vtk_image(const std::filesystem::path& file, const CrossSectionGrid& grid,
                     std::span<const CellArray> arrays);

}  // namespace millflow::method
