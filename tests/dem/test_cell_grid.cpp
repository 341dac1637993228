// CellGrid::visit_after, the half of visit_near that the neighbour search uses within a level:
// of two members closer than the reach, exactly one visits the other, in periodic boxes two
// cells wide (where the cell ahead and the cell behind are the same), in open and mixed boxes,
// and across Lees-Edwards images, tiny gradient axes included.
#include "dem/cell_grid.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <set>
#include <vector>

namespace millflow::dem {
namespace {

Domain box(const Vec3& length, std::array<bool, 3> periodic) {
  Domain d;
  d.lo = Vec3(0.1, -0.2, 0.3);
  d.hi = d.lo + length;
  d.periodic = periodic;
  return d;
}

Domain lees_edwards_box(const Vec3& length, int flow, int gradient, double offset) {
  Domain d = box(length, {true, true, true});
  d.lees_edwards = LeesEdwards{true, flow, gradient, offset, 0.0};
  return d;
}

// Members in the box widened by 5% on each side (positions are not wrapped, as in a run between
// rebuilds), a third of them next to an earlier one so that many pairs are close.
std::vector<Vec3> positions_in(const Domain& domain, std::size_t count, double spacing,
                               std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> x;
  const Vec3 len = domain.length();
  for (std::size_t k = 0; k < count; ++k) {
    if (k > 0 && unit(rng) < 0.3) {
      const auto other = static_cast<std::size_t>(unit(rng) * static_cast<double>(k));
      x.push_back(x[other] + spacing * Vec3(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5));
    } else {
      x.push_back(domain.lo +
                  Vec3(-0.05 + 1.1 * unit(rng), -0.05 + 1.1 * unit(rng), -0.05 + 1.1 * unit(rng))
                      .cwiseProduct(len));
    }
  }
  return x;
}

// Every member's visit_after must see only members that visit_near sees, and of every two
// members closer than the reach (minimum image), exactly one must see the other.
void expect_each_close_pair_visited_once(const Domain& domain, double cell_size, double reach,
                                         std::uint64_t seed) {
  const std::vector<Vec3> x = positions_in(domain, 300, reach, seed);
  const std::vector<double> radii(x.size(), 0.25 * cell_size);
  std::vector<std::uint32_t> indices(x.size());
  for (std::uint32_t i = 0; i < indices.size(); ++i) indices[i] = i;
  CellGrid grid;
  grid.configure(domain, cell_size, 1u << 20);
  grid.bin(x, radii, indices);

  std::vector<std::set<std::uint32_t>> near(x.size()), after(x.size());
  for (std::uint32_t p = 0; p < x.size(); ++p) {
    grid.visit_near(x[p], reach, [&](const CellGrid::Member& m) { near[p].insert(m.index); });
    grid.visit_after(x[p], reach, p, [&](const CellGrid::Member& m) { after[p].insert(m.index); });
  }
  std::size_t close_pairs = 0;
  for (std::uint32_t p = 0; p < x.size(); ++p) {
    for (const std::uint32_t q : after[p]) {
      EXPECT_TRUE(near[p].count(q)) << "visit_after(" << p << ") saw " << q << ", visit_near not";
      EXPECT_NE(q, p) << "visit_after saw the member itself";
    }
    for (std::uint32_t q = p + 1; q < x.size(); ++q) {
      if (!(domain.separation(x[p], x[q]).norm() < reach * (1.0 - 1e-9))) continue;
      ++close_pairs;
      EXPECT_NE(after[p].count(q), after[q].count(p))
          << "members " << p << " and " << q << ": each must be seen from exactly one side";
    }
  }
  EXPECT_GT(close_pairs, 100u) << "the test should have close pairs";
}

TEST(CellGridVisitAfter, PeriodicBoxesOfTwoThreeFourAndMoreCellsPerAxis) {
  const double cell = 0.1;
  for (const Vec3& length :
       {Vec3(0.2, 0.2, 0.2), Vec3(0.3, 0.25, 0.4), Vec3(0.45, 0.61, 0.2), Vec3(0.1, 0.3, 0.7)}) {
    SCOPED_TRACE(::testing::Message() << "box " << length.transpose());
    const Domain d = box(length, {true, true, true});
    expect_each_close_pair_visited_once(d, cell, 0.95 * cell, 1);
    expect_each_close_pair_visited_once(d, cell, cell, 2);        // reach as wide as a cell
    expect_each_close_pair_visited_once(d, cell, 1.7 * cell, 5);  // wider: up to 5 cells per axis
  }
}

TEST(CellGridVisitAfter, OpenAndMixedBoxes) {
  const double cell = 0.1;
  for (const std::array<bool, 3> periodic :
       {std::array<bool, 3>{false, false, false}, std::array<bool, 3>{true, false, true},
        std::array<bool, 3>{false, true, false}}) {
    expect_each_close_pair_visited_once(box(Vec3(0.5, 0.2, 0.35), periodic), cell, cell, 3);
  }
}

TEST(CellGridVisitAfter, LeesEdwardsImagesAndTinyGradientAxes) {
  const double cell = 0.1;
  struct Axes {
    int flow, gradient;
  };
  for (const Vec3& length : {Vec3(0.5, 0.4, 0.45), Vec3(0.3, 0.2, 0.25), Vec3(0.2, 0.1, 0.2)}) {
    for (const Axes axes : {Axes{0, 1}, Axes{2, 0}, Axes{1, 2}}) {
      const double l_flow = length[axes.flow];
      for (const double offset : {0.0, 0.013, 0.5 * cell, 0.31 * l_flow, l_flow - 1e-9}) {
        SCOPED_TRACE(::testing::Message() << "box " << length.transpose() << " flow " << axes.flow
                                          << " gradient " << axes.gradient << " offset " << offset);
        expect_each_close_pair_visited_once(
            lees_edwards_box(length, axes.flow, axes.gradient, offset), cell, cell, 4);
      }
    }
  }
}

}  // namespace
}  // namespace millflow::dem
