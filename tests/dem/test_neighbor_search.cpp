// The neighbour search must return exactly the pairs of the O(N^2) reference, whatever the box
// (open, periodic, tiny, Lees-Edwards), the size spread and the thread count.
#include "dem/neighbor_search.hpp"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace millflow::dem {
namespace {

struct System {
  std::vector<Vec3> positions;
  std::vector<double> radii;
};

Domain open_box(double side) {
  Domain d;
  d.lo = Vec3::Constant(-0.5 * side);
  d.hi = Vec3::Constant(0.5 * side);
  return d;
}

Domain periodic_box(const Vec3& length) {
  Domain d;
  d.lo = Vec3(0.1, -0.2, 0.3);
  d.hi = d.lo + length;
  d.periodic = {true, true, true};
  return d;
}

Domain lees_edwards_box(const Vec3& length, int flow, int gradient, double offset) {
  Domain d = periodic_box(length);
  d.lees_edwards = LeesEdwards{true, flow, gradient, offset, 0.0};
  return d;
}

// Uniform in the box widened by 5% on each side.
Vec3 uniform_position(std::mt19937_64& rng, const Domain& domain) {
  std::uniform_real_distribution<double> unit(-0.05, 1.05);
  const Vec3 len = domain.length();
  return Vec3(domain.lo.x() + unit(rng) * len.x(), domain.lo.y() + unit(rng) * len.y(),
              domain.lo.z() + unit(rng) * len.z());
}

// Big particles (radius r_big, fraction big_fraction) and small ones (r_big / ratio), plus a few
// of intermediate sizes. Half of the particles are put next to an earlier one at about the
// cutoff distance, so that many pairs sit near the cutoff, across box faces too. On periodic
// axes positions are wrapped into the box unless `keep_unwrapped`; in open boxes some lie a
// little outside.
System make_system(const Domain& domain, std::size_t count, double r_big, double ratio, double skin,
                   std::uint64_t seed, bool keep_unwrapped = false) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  System s;
  for (std::size_t k = 0; k < count; ++k) {
    const double pick = unit(rng);
    const double r = pick < 0.1    ? r_big
                     : pick < 0.15 ? r_big / (1.0 + (ratio - 1.0) * unit(rng))
                                   : r_big / ratio;
    Vec3 x;
    if (k > 0 && unit(rng) < 0.5) {
      const auto other = static_cast<std::size_t>(unit(rng) * static_cast<double>(k));
      Vec3 direction(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5);
      direction.normalize();
      x = s.positions[other] + direction * (0.8 + 0.4 * unit(rng)) * (r + s.radii[other] + skin);
    } else {
      x = uniform_position(rng, domain);
    }
    if (!keep_unwrapped) {
      Vec3 v = Vec3::Zero();
      domain.wrap(x, v);
    }
    s.positions.push_back(x);
    s.radii.push_back(r);
  }
  return s;
}

std::vector<NeighborPair> search_pairs(const Domain& domain, const System& s, double skin,
                                       bool multilevel) {
  NeighborSearch search({skin, multilevel});
  search.build(domain, s.positions, s.radii);
  return search.pairs();
}

void expect_same_as_brute_force(const Domain& domain, const System& s, double skin) {
  const auto expected = brute_force_pairs(domain, s.positions, s.radii, skin);
  ASSERT_FALSE(expected.empty()) << "the test system should have pairs";
  EXPECT_EQ(search_pairs(domain, s, skin, true), expected) << "multilevel";
  EXPECT_EQ(search_pairs(domain, s, skin, false), expected) << "single grid";
}

TEST(BruteForcePairs, HandMadeCaseAcrossPeriodicAndLeesEdwardsBoundaries) {
  // Unit box periodic on all axes; the image one box up y is shifted by +0.3 along x.
  Domain d = lees_edwards_box(Vec3::Ones(), 0, 1, 0.3);
  d.lo = Vec3::Zero();
  d.hi = Vec3::Ones();
  const std::vector<Vec3> x = {
      {0.02, 0.5, 0.5},  // 0: 0.05 from 1 across the x faces
      {0.97, 0.5, 0.5},  // 1
      {0.2, 0.98, 0.5},  // 2: its image one box down is at (0.9, -0.02): 0.04 from 3
      {0.9, 0.02, 0.5},  // 3
      {0.2, 0.02, 0.5},  // 4: 0.04 from 2 in y, but the Lees-Edwards shift puts it 0.3 away in x
  };
  const std::vector<double> r(x.size(), 0.01);
  const double skin = 0.05;  // cutoff 0.07
  EXPECT_EQ(brute_force_pairs(d, x, r, skin), (std::vector<NeighborPair>{{0, 1}, {2, 3}}));
  EXPECT_NEAR((d.separation(x[2], x[3]) - Vec3(0.0, 0.04, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((d.separation(x[2], x[4]) - Vec3(0.3, 0.04, 0.0)).norm(), 0.0, 1e-12);

  Domain open = d;  // without periodicity only distances inside the box count
  open.lees_edwards.enabled = false;
  open.periodic = {false, false, false};
  EXPECT_TRUE(brute_force_pairs(open, x, r, skin).empty());
  open.periodic = {true, true, true};  // plain periodic: 2 and 4 are neighbours, 2 and 3 are not
  EXPECT_EQ(brute_force_pairs(open, x, r, skin), (std::vector<NeighborPair>{{0, 1}, {2, 4}}));
}

TEST(NeighborSearch, MonodisperseOpenAndPeriodic) {
  const double skin = 0.01;
  expect_same_as_brute_force(open_box(1.0), make_system(open_box(1.0), 800, 0.03, 1.0, skin, 1),
                             skin);
  const Domain p = periodic_box(Vec3(1.0, 0.8, 0.6));
  expect_same_as_brute_force(p, make_system(p, 800, 0.03, 1.0, skin, 2), skin);
}

class Polydisperse : public ::testing::TestWithParam<double> {};

TEST_P(Polydisperse, OpenBox) {
  const double skin = 0.002;
  const Domain d = open_box(0.5);
  expect_same_as_brute_force(d, make_system(d, 1500, 0.05, GetParam(), skin, 3), skin);
}

TEST_P(Polydisperse, PeriodicBox) {
  const double skin = 0.002;
  const Domain d = periodic_box(Vec3(0.5, 0.4, 0.45));
  expect_same_as_brute_force(d, make_system(d, 1500, 0.05, GetParam(), skin, 4), skin);
}

TEST_P(Polydisperse, MixedOpenAndPeriodicAxes) {
  const double skin = 0.002;
  Domain d = periodic_box(Vec3(0.5, 0.4, 0.45));
  d.periodic = {true, false, true};
  expect_same_as_brute_force(d, make_system(d, 1500, 0.05, GetParam(), skin, 5), skin);
}

INSTANTIATE_TEST_SUITE_P(SizeRatios, Polydisperse, ::testing::Values(5.0, 10.0, 20.0));

TEST(NeighborSearch, SmallPeriodicBoxesWithOneOrTwoCellsPerAxis) {
  const double skin = 0.02;  // big cells 0.12 wide
  for (const Vec3& length : {Vec3(0.25, 0.25, 0.25), Vec3(0.1, 0.25, 0.3), Vec3(0.1, 0.1, 0.1)}) {
    const Domain d = periodic_box(length);
    expect_same_as_brute_force(d, make_system(d, 120, 0.05, 5.0, skin, 6), skin);
  }
}

TEST(NeighborSearch, OneCellPeriodicBoxVisitsItsCellOncePerQuery) {
  // Cells 0.12 wide in a 0.1 box: one cell, which every query reaches through several images.
  const double skin = 0.02;
  const Domain d = periodic_box(Vec3(0.1, 0.1, 0.1));
  const std::size_t n = 40;
  std::mt19937_64 rng(16);
  System s;
  for (std::size_t k = 0; k < n; ++k) {
    Vec3 x = uniform_position(rng, d), v = Vec3::Zero();
    d.wrap(x, v);
    s.positions.push_back(x);
    s.radii.push_back(0.05);
  }
  NeighborSearch search({skin, true});
  search.build(d, s.positions, s.radii);
  EXPECT_EQ(search.last_build_stats().levels, 1u);
  EXPECT_EQ(search.last_build_stats().cells_visited, n);
  EXPECT_EQ(search.last_build_stats().candidates_tested, n * (n - 1) / 2);
  EXPECT_EQ(search.pairs().size(), n * (n - 1) / 2);  // every pair is within 0.12 of each other
}

TEST(NeighborSearch, LeesEdwardsOffsetsAndAxes) {
  const double skin = 0.003;
  const Vec3 length(0.5, 0.4, 0.45);
  struct Axes {
    int flow, gradient;
  };
  for (const Axes axes : {Axes{0, 1}, Axes{2, 0}, Axes{1, 2}}) {
    const double l_flow = length[axes.flow];
    for (const double offset : {0.0, 1e-13, 0.013, 0.31 * l_flow, 0.5 * l_flow, l_flow - 1e-9,
                                std::nextafter(l_flow, 0.0)}) {
      SCOPED_TRACE(::testing::Message() << "flow " << axes.flow << " gradient " << axes.gradient
                                        << " offset " << offset);
      const Domain d = lees_edwards_box(length, axes.flow, axes.gradient, offset);
      expect_same_as_brute_force(d, make_system(d, 700, 0.05, 10.0, skin, 7), skin);
    }
  }
}

TEST(NeighborSearch, TinyLeesEdwardsBoxes) {
  const double skin = 0.02;
  for (const Vec3& length : {Vec3(0.25, 0.25, 0.25), Vec3(0.3, 0.1, 0.25), Vec3(0.1, 0.1, 0.1)}) {
    for (const double offset : {0.0, 0.04, 0.5 * length.x(), length.x() - 1e-9}) {
      SCOPED_TRACE(::testing::Message() << "box " << length.transpose() << " offset " << offset);
      const Domain d = lees_edwards_box(length, 0, 1, offset);
      expect_same_as_brute_force(d, make_system(d, 120, 0.05, 5.0, skin, 8), skin);
    }
  }
}

TEST(NeighborSearch, UnwrappedPositionsInPeriodicAndLeesEdwardsBoxes) {
  // Particles up to ~half a box outside (not yet wrapped) are binned as their images.
  const double skin = 0.003;
  const Domain p = periodic_box(Vec3(0.5, 0.4, 0.45));
  expect_same_as_brute_force(p, make_system(p, 700, 0.05, 10.0, skin, 9, true), skin);
  const Domain le = lees_edwards_box(Vec3(0.5, 0.4, 0.45), 0, 1, 0.17);
  expect_same_as_brute_force(le, make_system(le, 700, 0.05, 10.0, skin, 10, true), skin);
}

TEST(NeighborSearch, ParticlesFarOutsideAnOpenBoxAreClamped) {
  const Domain d = open_box(1.0);
  System s = make_system(d, 300, 0.03, 3.0, 0.01, 11);
  s.positions.push_back(Vec3(-3.0, 0.2, 7.0));  // far outside, with a neighbour
  s.positions.push_back(Vec3(-3.0, 0.22, 7.0));
  s.radii.insert(s.radii.end(), {0.01, 0.01});
  expect_same_as_brute_force(d, s, 0.01);
}

TEST(NeighborSearch, MultilevelBinsBySizeAndTestsFarFewerCandidates) {
  const double skin = 0.002;
  const Domain d = periodic_box(Vec3(0.5, 0.4, 0.45));
  System s;  // only the two sizes of a bidisperse bed, ratio 20
  std::mt19937_64 rng(15);
  for (std::size_t k = 0; k < 3000; ++k) {
    s.positions.push_back(uniform_position(rng, d));
    s.radii.push_back(k % 20 == 0 ? 0.05 : 0.0025);
  }
  NeighborSearch multi({skin, true}), single({skin, false});
  multi.build(d, s.positions, s.radii);
  single.build(d, s.positions, s.radii);
  EXPECT_EQ(multi.pairs(), single.pairs());
  EXPECT_EQ(multi.last_build_stats().levels, 2u);
  EXPECT_EQ(single.last_build_stats().levels, 1u);
  EXPECT_LT(5 * multi.last_build_stats().candidates_tested,
            single.last_build_stats().candidates_tested);
}

TEST(NeighborSearch, IdenticalAtOneAndTwoThreads) {
  const double skin = 0.002;
  const Domain d = lees_edwards_box(Vec3(0.5, 0.4, 0.45), 0, 1, 0.21);
  const System s = make_system(d, 6000, 0.05, 10.0, skin, 12);
  const auto run_with_threads = [&](int threads) {
    NeighborSearch search({skin, true});
    tbb::task_arena arena(threads);
    arena.execute([&] { search.build(d, s.positions, s.radii); });
    return search;
  };
  const NeighborSearch one = run_with_threads(1), two = run_with_threads(2);
  EXPECT_EQ(one.pairs(), two.pairs());
  EXPECT_EQ(one.last_build_stats().cells_visited, two.last_build_stats().cells_visited);
  EXPECT_EQ(one.last_build_stats().candidates_tested, two.last_build_stats().candidates_tested);
  EXPECT_EQ(one.pairs(), brute_force_pairs(d, s.positions, s.radii, skin));
}

TEST(NeighborSearch, RebuildingWithOtherSystemsReusesBuffersCorrectly) {
  const double skin = 0.002;
  const Domain d = periodic_box(Vec3(0.5, 0.4, 0.45));
  const System big = make_system(d, 1500, 0.05, 10.0, skin, 13);
  const System small = make_system(d, 300, 0.05, 5.0, skin, 14);
  NeighborSearch search({skin, true});
  for (const System* s : {&big, &small, &big}) {
    search.build(d, s->positions, s->radii);
    EXPECT_EQ(search.pairs(), brute_force_pairs(d, s->positions, s->radii, skin));
  }
  EXPECT_EQ(search.build_count(), 3u);
  search.build(d, std::vector<Vec3>{}, std::vector<double>{});
  EXPECT_TRUE(search.pairs().empty());
}

TEST(NeighborSearchRebuild, AfterAParticleMovesHalfTheSkin) {
  // Values exactly representable in binary, so displacements are exact.
  const double skin = 0.125;
  Domain d = periodic_box(Vec3::Ones());
  d.lo = Vec3::Zero();
  d.hi = Vec3::Ones();
  const std::vector<Vec3> x0 = {{0.25, 0.25, 0.25}, {0.5, 0.5, 0.5}, {0.96875, 0.5, 0.5}};
  const std::vector<double> r(3, 0.0625);
  NeighborSearch search({skin, true});
  EXPECT_TRUE(search.needs_rebuild(d, x0));  // never built
  search.build(d, x0, r);
  EXPECT_FALSE(search.needs_rebuild(d, x0));

  std::vector<Vec3> x = x0;
  x[1].y() += 0.0546875;  // 7/16 of the skin
  EXPECT_FALSE(search.needs_rebuild(d, x));
  x[1].y() = 0.5 + 0.0625;  // half the skin
  EXPECT_TRUE(search.needs_rebuild(d, x));

  x = x0;
  x[2].x() = 0.03125;  // crossed the periodic face: a minimum-image move of 1/16 = skin / 2
  EXPECT_TRUE(search.needs_rebuild(d, x));
  x[2].x() = 0.0;  // 1/32: no rebuild
  EXPECT_FALSE(search.needs_rebuild(d, x));

  EXPECT_TRUE(search.needs_rebuild(d, std::vector<Vec3>(x0.begin(), x0.begin() + 2)));
}

TEST(NeighborSearchRebuild, AfterTheLeesEdwardsOffsetChangesBySkin) {
  const double skin = 0.125;
  Domain d = lees_edwards_box(Vec3::Ones(), 0, 1, 0.9375);
  d.lo = Vec3::Zero();
  d.hi = Vec3::Ones();
  const std::vector<Vec3> x = {{0.25, 0.25, 0.25}, {0.5, 0.5, 0.5}};
  const std::vector<double> r(2, 0.0625);
  NeighborSearch search({skin, true});
  search.build(d, x, r);
  d.lees_edwards.offset =
      0.9375 + 0.109375;  // skin * 7/8, beyond L_flow: as the box sees it, wrapped
  d.lees_edwards.offset -= 1.0;
  EXPECT_FALSE(search.needs_rebuild(d, x));
  d.lees_edwards.offset = 0.0625;  // skin across the wrap at L_flow
  EXPECT_TRUE(search.needs_rebuild(d, x));
  d.lees_edwards.offset = 0.9375 - 0.125;  // skin backwards
  EXPECT_TRUE(search.needs_rebuild(d, x));
}

TEST(NeighborSearchRebuild, ZeroSkinAlwaysRebuilds) {
  const Domain d = open_box(1.0);
  const std::vector<Vec3> x = {{0.0, 0.0, 0.0}};
  const std::vector<double> r = {0.1};
  NeighborSearch search({0.0, true});
  search.build(d, x, r);
  EXPECT_TRUE(search.needs_rebuild(d, x));
}

TEST(NeighborSearch, RejectsBadInput) {
  const Domain d = open_box(1.0);
  const std::vector<Vec3> x = {{0.0, 0.0, 0.0}, {0.1, 0.0, 0.0}};
  NeighborSearch search({0.01, true});
  EXPECT_THROW(NeighborSearch({-0.01, true}), std::invalid_argument);
  EXPECT_THROW(search.build(d, x, std::vector<double>{0.1}), std::invalid_argument);
  EXPECT_THROW(search.build(d, x, std::vector<double>{0.1, -0.1}), std::invalid_argument);
  EXPECT_THROW(search.build(d, x, std::vector<double>{0.1, 0.0}), std::invalid_argument);
  const std::vector<Vec3> nan_x = {{0.0, 0.0, 0.0}, {std::nan(""), 0.0, 0.0}};
  EXPECT_THROW(search.build(d, nan_x, std::vector<double>{0.1, 0.1}), std::invalid_argument);
  EXPECT_THROW(brute_force_pairs(d, x, std::vector<double>{0.1, 0.1}, -1.0), std::invalid_argument);
}

}  // namespace
}  // namespace millflow::dem
