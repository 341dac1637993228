#include "method/vtk_image.hpp"

#include <fmt/format.h>

#include <iterator>
#include <stdexcept>
#include <string>

#include "util/durable_file.hpp"

namespace millflow::method {

void write_vtk_image(const std::filesystem::path& file, const CrossSectionGrid& grid,
                     std::span<const CellArray> arrays) {
  for (const CellArray& array : arrays) {
    if (array.values.size() != grid.size() * static_cast<std::size_t>(array.components)) {
      throw std::invalid_argument(
          fmt::format("cell array '{}' holds {} values, but {} cells x {} components need {}",
                      array.name, array.values.size(), grid.size(), array.components,
                      grid.size() * static_cast<std::size_t>(array.components)));
    }
  }
  // Built in memory and written in one durable step: a full disk is an exception here, not a
  // failed flush in a destructor.
  std::string text;
  auto out = std::back_inserter(text);
  fmt::format_to(out,
                 "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" "
                 "byte_order=\"LittleEndian\">\n");
  fmt::format_to(out,
                 "  <ImageData WholeExtent=\"0 {0} 0 {1} 0 1\" Origin=\"{2:.17g} {2:.17g} 0\" "
                 "Spacing=\"{3:.17g} {4:.17g} {3:.17g}\">\n",
                 grid.nx, grid.ny, -grid.half_width, grid.dx(), grid.dy());
  fmt::format_to(out, "    <Piece Extent=\"0 {} 0 {} 0 1\">\n      <CellData>\n", grid.nx, grid.ny);
  for (const CellArray& array : arrays) {
    fmt::format_to(out,
                   "        <DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{}\" "
                   "format=\"ascii\">\n",
                   array.name, array.components);
    for (std::size_t k = 0; k < array.values.size(); ++k) {
      fmt::format_to(out, "{:.9g}{}", array.values[k],
                     (k + 1) % 12 == 0 || k + 1 == array.values.size() ? "\n" : " ");
    }
    fmt::format_to(out, "        </DataArray>\n");
  }
  fmt::format_to(out, "      </CellData>\n    </Piece>\n  </ImageData>\n</VTKFile>\n");
  util::write_file_durably(file, text);
}

}  // namespace millflow::method
