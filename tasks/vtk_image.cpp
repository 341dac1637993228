#include "tasks/vtk_image.hpp"

#include <fmt/format.h>
#include <fmt/os.h>

#include <stdexcept>

namespace millflow::tasks {

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
  auto out = fmt::output_file(file.string());
  out.print(
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" "
      "byte_order=\"LittleEndian\">\n");
  out.print(
      "  <ImageData WholeExtent=\"0 {0} 0 {1} 0 1\" Origin=\"{2:.17g} {2:.17g} 0\" "
      "Spacing=\"{3:.17g} {4:.17g} {3:.17g}\">\n",
      grid.nx, grid.ny, -grid.half_width, grid.dx(), grid.dy());
  out.print("    <Piece Extent=\"0 {} 0 {} 0 1\">\n      <CellData>\n", grid.nx, grid.ny);
  for (const CellArray& array : arrays) {
    out.print(
        "        <DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{}\" "
        "format=\"ascii\">\n",
        array.name, array.components);
    for (std::size_t k = 0; k < array.values.size(); ++k) {
      out.print("{:.9g}{}", array.values[k],
                (k + 1) % 12 == 0 || k + 1 == array.values.size() ? "\n" : " ");
    }
    out.print("        </DataArray>\n");
  }
  out.print("      </CellData>\n    </Piece>\n  </ImageData>\n</VTKFile>\n");
  out.close();
}

}  // namespace millflow::tasks
