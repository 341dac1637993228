#pragma once
// One cell list over the domain box, aware of periodic and Lees-Edwards images. The neighbour
// search keeps one grid per particle size level.
//
// Cells tile [lo, hi) on every axis. On periodic axes a coordinate outside the box falls into the
// cell of its periodic image; on non-periodic axes it is clamped into the first or last cell.
// With Lees-Edwards, a particle beyond the gradient boundary is binned as its image inside the
// box, with the flow coordinate shifted by the offset, consistently with the queries.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "dem/domain.hpp"
#include "dem/vec.hpp"

namespace millflow::dem {

class CellGrid {
 public:
  struct Member {
    Vec3 position;  // as given to bin(), not wrapped
    double radius;
    std::uint32_t index;
  };

  // Lays out cells at least `min_cell_size` wide, coarsening them if needed so that there are at
  // most `max_cells` cells in all (keeps sparse, fine levels of a big box within memory).
  void configure(const Domain& domain, double min_cell_size, std::size_t max_cells);

  // Bins the particles `indices` (increasing) into cells; within a cell they stay in index order.
  void bin(std::span<const Vec3> positions, std::span<const double> radii,
           std::span<const std::uint32_t> indices);

  // Calls visit(member) for every member of every cell that overlaps the cube of half-width
  // `reach` around x or any of its periodic / Lees-Edwards images. A member may be visited
  // twice only on a Lees-Edwards gradient axis shorter than 2 * reach (tiny boxes); callers
  // deduplicate. Returns the number of cells visited.
  template <class Visit>
  std::size_t visit_near(const Vec3& x, double reach, Visit&& visit) const;

  std::size_t cell_count() const { return cell_start_.empty() ? 0 : cell_start_.size() - 1; }
  const std::vector<Member>& members() const { return members_; }

 private:
  // Up to two runs [begin, end) of cell indices along one axis (two when the range wraps).
  struct AxisRuns {
    std::array<std::pair<int, int>, 2> runs;
    int count;
  };

  double unwrapped_cell(int axis, double x) const {
    return std::floor((x - lo_[axis]) * inv_cell_size_[axis]);
  }
  // Cell index of the unwrapped cell u, and the number of box lengths u lies beyond the box
  // (always 0 on non-periodic axes, where u is clamped).
  std::pair<int, double> wrap_cell(int axis, double u) const;
  std::size_t cell_id(int c0, int c1, int c2) const {
    return (static_cast<std::size_t>(c0) * static_cast<std::size_t>(cells_[order_[1]]) +
            static_cast<std::size_t>(c1)) *
               static_cast<std::size_t>(cells_[order_[2]]) +
           static_cast<std::size_t>(c2);
  }
  std::size_t cell_of(const Vec3& x) const;
  AxisRuns axis_runs(int axis, double x, double reach) const;
  template <class Visit>
  std::size_t visit_row(int c0, const AxisRuns& runs1, const AxisRuns& runs2, Visit& visit) const;

  // Cell ids vary slowest along order_[0] (the Lees-Edwards gradient axis, when enabled) and
  // fastest along order_[2], so a run of cells along order_[2] is contiguous in members_.
  std::array<int, 3> order_{0, 1, 2};
  std::array<int, 3> cells_{1, 1, 1};
  std::array<bool, 3> periodic_{false, false, false};
  // Plain arrays rather than Vec3: these are read per axis in the query's inner loops.
  std::array<double, 3> lo_{0.0, 0.0, 0.0};
  std::array<double, 3> inv_cell_size_{1.0, 1.0, 1.0};
  // Flow-axis displacement of the image one box length up the order_[0] axis (0 without
  // Lees-Edwards); the flow axis is then order_[1].
  double image_shift_ = 0.0;
  std::vector<std::uint32_t>
      cell_start_;  // members_ of cell c: [cell_start_[c], cell_start_[c + 1])
  std::vector<Member> members_;
  std::vector<std::size_t> member_cell_;  // scratch of bin(), kept to avoid reallocation
};

template <class Visit>
std::size_t CellGrid::visit_near(const Vec3& x, double reach, Visit&& visit) const {
  const AxisRuns runs2 = axis_runs(order_[2], x[order_[2]], reach);
  std::size_t visited = 0;
  const int a0 = order_[0];
  const int a1 = order_[1];
  if (image_shift_ == 0.0 || !periodic_[a0]) {
    const AxisRuns runs0 = axis_runs(a0, x[a0], reach);
    const AxisRuns runs1 = axis_runs(a1, x[a1], reach);
    for (int r = 0; r < runs0.count; ++r) {
      for (int c0 = runs0.runs[r].first; c0 < runs0.runs[r].second; ++c0) {
        visited += visit_row(c0, runs1, runs2, visit);
      }
    }
    return visited;
  }
  // Lees-Edwards gradient axis: each unwrapped row lies in its own image, whose flow coordinates
  // are shifted, so rows are walked unwrapped (not deduplicated) with their image count. Members
  // of the image `images` boxes up are displaced by images * image_shift_ along the flow axis:
  // look for them at the query's flow coordinate minus that shift.
  const double first = unwrapped_cell(a0, x[a0] - reach);
  const double last = unwrapped_cell(a0, x[a0] + reach);
  for (double u = first; u <= last; u += 1.0) {
    const auto [c0, images] = wrap_cell(a0, u);
    visited += visit_row(c0, axis_runs(a1, x[a1] - images * image_shift_, reach), runs2, visit);
  }
  return visited;
}

template <class Visit>
std::size_t CellGrid::visit_row(int c0, const AxisRuns& runs1, const AxisRuns& runs2,
                                Visit& visit) const {
  std::size_t visited = 0;
  for (int r1 = 0; r1 < runs1.count; ++r1) {
    for (int c1 = runs1.runs[r1].first; c1 < runs1.runs[r1].second; ++c1) {
      for (int r2 = 0; r2 < runs2.count; ++r2) {
        const auto [begin, end] = runs2.runs[r2];
        visited += static_cast<std::size_t>(end - begin);
        const std::uint32_t m_end = cell_start_[cell_id(c0, c1, end - 1) + 1];
        for (std::uint32_t m = cell_start_[cell_id(c0, c1, begin)]; m < m_end; ++m) {
          visit(members_[m]);
        }
      }
    }
  }
  return visited;
}

}  // namespace millflow::dem
