#pragma once
// The grid of cells over a mill's cross-section (the x-y plane; the mill axis is z through the
// origin) on which the averaged fields live, and named per-cell arrays of those fields.
#include <cstddef>
#include <string>
#include <vector>

namespace millflow::method {

// nx x ny square-ish cells over [-half_width, half_width]^2; cell (i, j) has index j * nx + i, so
// rows of constant y are contiguous (the order VTK image data uses).
struct CrossSectionGrid {
  int nx = 0;
  int ny = 0;
  double half_width = 0.0;  // m: the mill's inner radius

  double dx() const { return 2.0 * half_width / nx; }
  double dy() const { return 2.0 * half_width / ny; }
  double cell_area() const { return dx() * dy(); }
  std::size_t size() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
  std::size_t index(int i, int j) const {
    return static_cast<std::size_t>(j) * nx + static_cast<std::size_t>(i);
  }
  double x(int i) const { return -half_width + (i + 0.5) * dx(); }
  double y(int j) const { return -half_width + (j + 0.5) * dy(); }
  double x_of(std::size_t cell) const {
    return x(static_cast<int>(cell % static_cast<std::size_t>(nx)));
  }
  double y_of(std::size_t cell) const {
    return y(static_cast<int>(cell / static_cast<std::size_t>(nx)));
  }
  // Whether the cell's centre lies inside the mill (the circle of radius half_width).
  bool inside_mill(std::size_t cell) const {
    const double x = x_of(cell), y = y_of(cell);
    return x * x + y * y < half_width * half_width;
  }
};

// One field over the grid: `components` values per cell, cell after cell.
struct CellArray {
  std::string name;
  int components = 1;
  std::vector<double> values;
};

}  // namespace millflow::method
