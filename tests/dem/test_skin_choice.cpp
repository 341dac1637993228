// The neighbour skin chosen by trial (dem/skin_choice.hpp): one of the candidates, the same
// choice every time and at 1 and 2 threads, the original system untouched, and an "auto" cell
// choosing at the end of its first warm-up window.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "dem/skin_choice.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

// A compacted Lees-Edwards cell with powder: the scene the shear cells choose their skin on.
ShearCell compacted_cell(std::optional<double> skin_fraction) {
  ShearCellSetup setup = testing::small_shear_cell(0.05, 0.5);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.neighbor_skin_fraction = skin_fraction;
  ShearCell cell(setup);
  cell.compact();
  return cell;
}

bool same_trials(const SkinChoice& a, const SkinChoice& b) {
  if (a.chosen != b.chosen || a.trials.size() != b.trials.size()) return false;
  for (std::size_t k = 0; k < a.trials.size(); ++k) {
    const SkinTrial &x = a.trials[k], &y = b.trials[k];
    if (x.skin_fraction != y.skin_fraction || x.steps != y.steps ||
        x.candidate_pair_steps != y.candidate_pair_steps ||
        x.screened_pair_steps != y.screened_pair_steps || x.rebuilds != y.rebuilds ||
        x.lists_used != y.lists_used || x.particles != y.particles)
      return false;
  }
  return true;
}

TEST(SkinChoice, CheapestSkinWeighsCandidatesScreeningAndRebuilds) {
  const SkinCostModel model;  // the measured constants
  // A dense, slow media cell (le_media_2000's counts): a wider skin holds many more candidates,
  // which sleep (the screened pairs barely grow), and rebuilds are rare at any skin.
  // Candidates at skins of 1, 2 and 3 mm: (candidate pairs, screened pairs) per particle-step and
  // steps per rebuild.
  const auto candidates = [](std::array<std::array<double, 3>, 3> counts) {
    std::vector<SkinCandidate> out;
    for (std::size_t k = 0; k < counts.size(); ++k) {
      out.push_back({.skin = 1e-3 * static_cast<double>(k + 1),
                     .pairs_per_particle = counts[k][0],
                     .screened_per_particle = counts[k][1],
                     .steps_per_rebuild = counts[k][2]});
    }
    return out;
  };
  const std::vector<SkinCandidate> dense_slow =
      candidates({{{3.74, 2.018, 400.0}, {4.56, 2.024, 800.0}, {5.33, 2.027, 1200.0}}});
  EXPECT_EQ(cheapest_skin(dense_slow, model), 0u);
  // A sparse, fast cell: few pairs gained by a narrower skin, rebuilds every few steps.
  const std::vector<SkinCandidate> sparse_fast =
      candidates({{{0.50, 0.40, 5.0}, {0.55, 0.42, 10.0}, {0.60, 0.44, 15.0}}});
  EXPECT_EQ(cheapest_skin(sparse_fast, model), 2u);
  // The cost is the documented sum.
  EXPECT_DOUBLE_EQ(skin_cost(sparse_fast[0], model), 0.5 * model.per_candidate_step +
                                                         0.4 * model.per_screened_step +
                                                         model.per_particle_rebuild / 5.0);
  EXPECT_THROW(cheapest_skin({}, model), std::invalid_argument);
  EXPECT_THROW(cheapest_skin(
                   std::vector<SkinCandidate>{
                       {.skin = 1e-3, .pairs_per_particle = 1.0, .steps_per_rebuild = 0.0}},
                   model),
               std::invalid_argument);
}

TEST(SkinChoice, ATrialAsTheCostModelsCandidate) {
  const SkinTrial quiet{.skin_fraction = 0.1,
                        .steps = 100,
                        .candidate_pair_steps = 4.0e5,
                        .screened_pair_steps = 1.5e5,
                        .rebuilds = 0,
                        .particles = 1000};
  const SkinCandidate c = skin_candidate(quiet, 0.002);
  EXPECT_DOUBLE_EQ(c.skin, 2e-4);
  EXPECT_DOUBLE_EQ(c.pairs_per_particle, 4.0);
  EXPECT_DOUBLE_EQ(c.screened_per_particle, 1.5);
  EXPECT_EQ(c.steps_per_rebuild, std::numeric_limits<double>::infinity());
  const SkinCostModel model;
  const double screening = 4.0 * model.per_candidate_step + 1.5 * model.per_screened_step;
  EXPECT_DOUBLE_EQ(skin_cost(c, model), screening);
  // The lists' lives used, not the whole rebuilds, set the interval.
  SkinTrial busy = quiet;
  busy.rebuilds = 4;
  busy.lists_used = 4.5;
  EXPECT_DOUBLE_EQ(skin_cost(skin_candidate(busy, 0.002), model),
                   screening + model.per_particle_rebuild * 4.5 / 100.0);
}

TEST(SkinChoice, ChoosesACandidateTheSameWayEveryTimeAndAtAnyThreadCount) {
  const ShearCell cell = compacted_cell(0.3);
  const System& system = cell.system();
  const std::uint64_t step = system.step_count();
  const double skin = system.neighbor_skin();
  auto choose = [&](int threads) {
    tbb::task_arena arena(threads);
    SkinChoice choice;
    arena.execute(
        [&] { choice = choose_skin_by_trials(system, kSkinFractionCandidates, kSkinTrialSteps); });
    return choice;
  };
  const SkinChoice one = choose(1);
  ASSERT_EQ(one.trials.size(), std::size(kSkinFractionCandidates));
  for (std::size_t k = 0; k < one.trials.size(); ++k) {
    EXPECT_EQ(one.trials[k].skin_fraction, kSkinFractionCandidates[k]);
    EXPECT_EQ(one.trials[k].steps, kSkinTrialSteps);
    EXPECT_EQ(one.trials[k].particles, system.size());
    // Pairs apart sleep: some candidates go unscreened, and every pair was screened at the
    // copy's first list build at least.
    EXPECT_LT(one.trials[k].screened_pair_steps, one.trials[k].candidate_pair_steps);
    EXPECT_GT(one.trials[k].screened_pair_steps,
              one.trials[k].candidate_pair_steps / static_cast<double>(kSkinTrialSteps) / 2.0);
    // A wider skin holds at least as many pairs and rebuilds no more often.
    if (k > 0) {
      EXPECT_GE(one.trials[k].candidate_pair_steps, one.trials[k - 1].candidate_pair_steps);
      EXPECT_LE(one.trials[k].rebuilds, one.trials[k - 1].rebuilds);
    }
    // Each trial used at least its rebuilds' lives (the copy's list starts new at its skin).
    EXPECT_GE(one.trials[k].lists_used, static_cast<double>(one.trials[k].rebuilds));
  }
  EXPECT_TRUE(same_trials(one, choose(1)));
  EXPECT_TRUE(same_trials(one, choose(2)));
  // The trials step copies.
  EXPECT_EQ(system.step_count(), step);
  EXPECT_EQ(system.neighbor_skin(), skin);
}

TEST(SkinChoice, AnAutoCellChoosesAtTheEndOfItsFirstWarmUpWindowTheSameSkinAtOneAndTwoThreads) {
  // Compacted, it still steps at the default; one window later at its choice (this small cell
  // keeps 0.3; tests/tasks/test_shear_cells.cpp has a cell that chooses another).
  EXPECT_DOUBLE_EQ(compacted_cell(std::nullopt).neighbor_skin_fraction(), kDefaultSkinFraction);
  auto chosen = [](int threads) {
    tbb::task_arena arena(threads);
    double fraction = 0.0;
    arena.execute([&] {
      ShearCell cell = compacted_cell(std::nullopt);
      cell.warm_up(0.05, 1);
      fraction = cell.neighbor_skin_fraction();
    });
    return fraction;
  };
  const double one = chosen(1);
  EXPECT_NE(std::find_if(std::begin(kSkinFractionCandidates), std::end(kSkinFractionCandidates),
                         [&](double f) { return std::abs(f - one) < 1e-12; }),
            std::end(kSkinFractionCandidates))
      << one;
  EXPECT_EQ(chosen(2), one);
  // A fixed skin stays as given.
  EXPECT_DOUBLE_EQ(compacted_cell(0.5).neighbor_skin_fraction(), 0.5);
}

TEST(SkinChoice, RefusesNoCandidatesABadOneOrZeroSteps) {
  const ShearCell cell = compacted_cell(0.3);
  const double none[] = {0.0};
  EXPECT_THROW(choose_skin_by_trials(cell.system(), {}, 10), std::invalid_argument);
  EXPECT_THROW(choose_skin_by_trials(cell.system(), none, 10), std::invalid_argument);
  EXPECT_THROW(choose_skin_by_trials(cell.system(), kSkinFractionCandidates, 0),
               std::invalid_argument);
}

}  // namespace
}  // namespace millflow::dem
