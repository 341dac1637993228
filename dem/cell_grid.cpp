#include "dem/cell_grid.hpp"

#include <algorithm>

namespace millflow::dem {

namespace {

// Cells per axis for cells at least `cell_size` wide, as doubles (no overflow for tiny cells).
std::array<double, 3> cells_per_axis(const Vec3& length, double cell_size) {
  std::array<double, 3> cells{};
  for (int a = 0; a < 3; ++a) cells[a] = std::max(1.0, std::floor(length[a] / cell_size));
  return cells;
}

}  // namespace

void CellGrid::configure(const Domain& domain, double min_cell_size, std::size_t max_cells) {
  const Vec3 length = domain.length();
  const auto& le = domain.lees_edwards;
  order_ = le.enabled ? std::array<int, 3>{le.gradient_axis, le.flow_axis,
                                           3 - le.gradient_axis - le.flow_axis}
                      : std::array<int, 3>{0, 1, 2};
  image_shift_ = le.enabled ? le.offset : 0.0;
  periodic_ = domain.periodic;
  for (int a = 0; a < 3; ++a) lo_[a] = domain.lo[a];

  double cell_size = min_cell_size;
  auto cells = cells_per_axis(length, cell_size);
  // Coarsen until the cell count fits; each pass shrinks it by about the excess factor.
  for (double total = cells[0] * cells[1] * cells[2]; total > static_cast<double>(max_cells);
       total = cells[0] * cells[1] * cells[2]) {
    cell_size *= std::cbrt(total / static_cast<double>(max_cells)) * 1.01;
    cells = cells_per_axis(length, cell_size);
  }
  for (int a = 0; a < 3; ++a) {
    cells_[a] = static_cast<int>(cells[a]);
    inv_cell_size_[a] = cells[a] / length[a];
  }
}

std::pair<int, double> CellGrid::wrap_cell(int axis, double u) const {
  const double n = cells_[axis];
  if (u >= 0.0 && u < n) return {static_cast<int>(u), 0.0};  // inside the box: the common case
  if (!periodic_[axis]) return {static_cast<int>(std::clamp(u, 0.0, n - 1.0)), 0.0};
  const double images = std::floor(u / n);
  return {static_cast<int>(u - images * n), images};
}

std::array<int, 3> CellGrid::cell_indices(const Vec3& x) const {
  const auto [c0, images] = wrap_cell(order_[0], unwrapped_cell(order_[0], x[order_[0]]));
  // A particle `images` boxes up the gradient axis is the image of one inside the box whose flow
  // coordinate is smaller by images * shift.
  const double x1 = x[order_[1]] - images * image_shift_;
  const int c1 = wrap_cell(order_[1], unwrapped_cell(order_[1], x1)).first;
  const int c2 = wrap_cell(order_[2], unwrapped_cell(order_[2], x[order_[2]])).first;
  return {c0, c1, c2};
}

std::size_t CellGrid::cell_of(const Vec3& x) const {
  const auto [c0, c1, c2] = cell_indices(x);
  return cell_id(c0, c1, c2);
}

CellGrid::AxisRuns CellGrid::axis_runs(int axis, double x, double reach) const {
  const double first = unwrapped_cell(axis, x - reach);
  const double last = unwrapped_cell(axis, x + reach);
  const int n = cells_[axis];
  if (!periodic_[axis]) {
    return {{{{wrap_cell(axis, first).first, wrap_cell(axis, last).first + 1}, {0, 0}}}, 1};
  }
  // A range as wide as the box covers every cell once: listing wrapped cells again would
  // produce duplicate candidates.
  if (last - first + 1.0 >= n) return {{{{0, n}, {0, 0}}}, 1};
  const int begin = wrap_cell(axis, first).first;
  const int end = begin + static_cast<int>(last - first) + 1;
  if (end <= n) return {{{{begin, end}, {0, 0}}}, 1};
  return {{{{begin, n}, {0, end - n}}}, 2};
}

CellGrid::AxisRuns CellGrid::after_in(const AxisRuns& runs, int axis, int own) const {
  // The runs are at most two intervals and the cells after `own` at most two (a cyclic
  // interval), so their intersection is at most three.
  AxisRuns kept{{}, 0};
  for (int r = 0; r < runs.count; ++r) {
    for (int c = runs.runs[r].first; c < runs.runs[r].second; ++c) {
      if (!after(axis, own, c)) continue;
      if (kept.count > 0 && kept.runs[kept.count - 1].second == c) {
        ++kept.runs[kept.count - 1].second;
      } else {
        kept.runs[kept.count++] = {c, c + 1};
      }
    }
  }
  return kept;
}

void CellGrid::bin(std::span<const Vec3> positions, std::span<const double> radii,
                   std::span<const std::uint32_t> indices) {
  const std::size_t n_cells = static_cast<std::size_t>(cells_[0]) *
                              static_cast<std::size_t>(cells_[1]) *
                              static_cast<std::size_t>(cells_[2]);
  // Counting sort by cell; stable, so members of a cell stay in index order.
  cell_start_.assign(n_cells + 1, 0);
  member_cell_.resize(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) {
    member_cell_[k] = cell_of(positions[indices[k]]);
    ++cell_start_[member_cell_[k] + 1];
  }
  for (std::size_t c = 0; c < n_cells; ++c) cell_start_[c + 1] += cell_start_[c];
  members_.resize(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const std::uint32_t i = indices[k];
    members_[cell_start_[member_cell_[k]]++] = Member{positions[i], radii[i], i};
  }
  // The fill advanced every start to the next cell's start: shift back.
  for (std::size_t c = n_cells; c > 0; --c) cell_start_[c] = cell_start_[c - 1];
  cell_start_[0] = 0;
}

}  // namespace millflow::dem
