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

  // Half of visit_near for a member's own grid, so that each pair of members is visited once
  // instead of twice: x must be the position of the member with index `self`. Visits the cells
  // that come after its own cell in a fixed order of cells (the first axis of order_ on which
  // two cells differ decides; along a periodic axis of n cells those less than n / 2 ahead come
  // after, and the one exactly n / 2 ahead if its index is the larger: see after()), and in its own
  // cell the members with a larger index. Of two members within reach of each other, exactly one is
  // visited by the other's call (twice at most on a tiny Lees-Edwards gradient axis, as with
  // visit_near). Returns the number of cells visited.
  template <class Visit>
  std::size_t visit_after(const Vec3& x, double reach, std::uint32_t self, Visit&& visit) const;

  std::size_t cell_count() const { return cell_start_.empty() ? 0 : cell_start_.size() - 1; }
  const std::vector<Member>& members() const { return members_; }

 private:
  // Runs [begin, end) of cell indices along one axis: up to two for a range (two when it
  // wraps), up to three for the cells of a range that come after a cell (after_in).
  struct AxisRuns {
    std::array<std::pair<int, int>, 3> runs;
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
  // The cell of x as its indices along order_[0], order_[1], order_[2].
  std::array<int, 3> cell_indices(const Vec3& x) const;
  std::size_t cell_of(const Vec3& x) const;
  AxisRuns axis_runs(int axis, double x, double reach) const;
  // axis_runs along the flow axis a1 for a row reached through `images` Lees-Edwards images
  // (`runs`, those of the query's own image, when 0): the query's flow coordinate less the shift.
  AxisRuns runs_in_image(int a1, const Vec3& x, double reach, const AxisRuns& runs,
                         double images) const {
    return images == 0.0 ? runs : axis_runs(a1, x[a1] - images * image_shift_, reach);
  }
  // Whether cell c comes after cell `own` along the axis (see visit_after): ahead of it on an
  // open axis; on a periodic one of n cells, less than n / 2 cells ahead cyclically, or exactly
  // n / 2 ahead with the larger index, so that of two different cells exactly one comes after
  // the other.
  bool after(int axis, int own, int c) const {
    if (!periodic_[axis]) return c > own;
    const int n = cells_[axis];
    const int ahead = c >= own ? c - own : c - own + n;
    return ahead != 0 && (2 * ahead < n || (2 * ahead == n && c > own));
  }
  // The cells of `runs` that come after `own` along the axis.
  AxisRuns after_in(const AxisRuns& runs, int axis, int own) const;
  static bool contains(const AxisRuns& runs, int c) {
    for (int r = 0; r < runs.count; ++r) {
      if (c >= runs.runs[r].first && c < runs.runs[r].second) return true;
    }
    return false;
  }
  // Calls row(c0, images) for every row c0 along order_[0] that overlaps [x - reach, x + reach],
  // `images` the Lees-Edwards image the row is reached through (0 without Lees-Edwards).
  template <class Row>
  void for_each_row(const Vec3& x, double reach, Row&& row) const;
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

template <class Row>
void CellGrid::for_each_row(const Vec3& x, double reach, Row&& row) const {
  const int a0 = order_[0];
  if (image_shift_ == 0.0 || !periodic_[a0]) {
    const AxisRuns runs0 = axis_runs(a0, x[a0], reach);
    for (int r = 0; r < runs0.count; ++r) {
      for (int c0 = runs0.runs[r].first; c0 < runs0.runs[r].second; ++c0) row(c0, 0.0);
    }
    return;
  }
  // Lees-Edwards gradient axis: each unwrapped row lies in its own image, whose flow coordinates
  // are shifted, so rows are walked unwrapped (not deduplicated) with their image count.
  const double first = unwrapped_cell(a0, x[a0] - reach);
  const double last = unwrapped_cell(a0, x[a0] + reach);
  for (double u = first; u <= last; u += 1.0) {
    const auto [c0, images] = wrap_cell(a0, u);
    row(c0, images);
  }
}

template <class Visit>
std::size_t CellGrid::visit_near(const Vec3& x, double reach, Visit&& visit) const {
  const int a1 = order_[1];
  const AxisRuns runs1 = axis_runs(a1, x[a1], reach);
  const AxisRuns runs2 = axis_runs(order_[2], x[order_[2]], reach);
  std::size_t visited = 0;
  // Members of the image `images` boxes up are displaced by images * image_shift_ along the flow
  // axis: look for them at the query's flow coordinate minus that shift.
  for_each_row(x, reach, [&](int c0, double images) {
    visited += visit_row(c0, runs_in_image(a1, x, reach, runs1, images), runs2, visit);
  });
  return visited;
}

template <class Visit>
std::size_t CellGrid::visit_after(const Vec3& x, double reach, std::uint32_t self,
                                  Visit&& visit) const {
  const int a0 = order_[0], a1 = order_[1], a2 = order_[2];
  const std::array<int, 3> own = cell_indices(x);
  const AxisRuns runs1 = axis_runs(a1, x[a1], reach);
  const AxisRuns runs2 = axis_runs(a2, x[a2], reach);
  const AxisRuns runs2_after = after_in(runs2, a2, own[2]);
  const bool own_cell_in_reach = contains(runs2, own[2]);
  std::size_t visited = 0;
  for_each_row(x, reach, [&](int c0, double images) {
    if (c0 != own[0] && !after(a0, own[0], c0)) return;
    const AxisRuns row_runs1 = runs_in_image(a1, x, reach, runs1, images);
    if (c0 != own[0]) {
      visited += visit_row(c0, row_runs1, runs2, visit);
      return;
    }
    // The own row: the lines after the own line, then in the own line the cells after the own
    // cell, then the own cell's members after `self` (a cell holds its members in index order).
    visited += visit_row(c0, after_in(row_runs1, a1, own[1]), runs2, visit);
    if (!contains(row_runs1, own[1])) return;
    visited += visit_row(c0, AxisRuns{{{{own[1], own[1] + 1}}}, 1}, runs2_after, visit);
    if (!own_cell_in_reach) return;
    const std::size_t cell = cell_id(own[0], own[1], own[2]);
    const std::uint32_t end = cell_start_[cell + 1];
    std::uint32_t m = cell_start_[cell];
    while (m < end && members_[m].index <= self) ++m;
    for (; m < end; ++m) visit(members_[m]);
    ++visited;
  });
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
