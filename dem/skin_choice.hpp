#pragma once
// The neighbour skin chosen per scene by trial (issue 17; docs/shear_cells.md, "The neighbour
// skin"): each candidate skin steps a throwaway copy of the system for a stretch of steps, and the
// skin whose stretch cost least by a deterministic cost proxy is kept. The proxy counts work, not
// time: the candidate pairs of each step (summed over the stretch's steps; each priced as
// screened, SkinCostModel) and the list
// rebuilds the skin test asked for, weighed by SkinCostModel's instructions per candidate
// pair-step and per particle-rebuild (dem/system.hpp says how they were measured). The same
// state gives the same choice at any thread count and on every run (every count is a property of
// the state; the system's steps are deterministic), and the original system is left untouched.
#include <cstdint>
#include <span>
#include <vector>

#include "dem/system.hpp"

namespace millflow::dem {

// The skin of an "auto" run until it chooses, and the campaigns' default, as a fraction of the
// smallest diameter (the system's default).
inline constexpr double kDefaultSkinFraction = 0.3;

// The candidates, as fractions of the smallest particle diameter, and each trial's steps.
inline constexpr double kSkinFractionCandidates[] = {0.1, 0.15, 0.2, 0.3};
inline constexpr std::uint64_t kSkinTrialSteps = 100;

// What one candidate skin's trial counted.
struct SkinTrial {
  double skin_fraction = 0.0;  // of the smallest diameter
  std::uint64_t steps = 0;
  double candidate_pair_steps = 0.0;  // candidate pairs summed over the steps
  std::uint64_t rebuilds = 0;         // rebuilds the skin test asked for in the steps
  // The lists' lives used in the steps: the rebuilds plus the change of the current list's
  // travel / skin. Counting rebuilds alone, a list that would last 150 steps looked free over a
  // 100-step trial and one that lasted 101 looked as costly as one of 100.
  double lists_used = 0.0;
  std::size_t particles = 0;
};

// A trial as the cost model's candidate: pairs per particle-step and steps per list life used
// (infinite when the list never moved), so that cheapest_skin weighs it.
SkinCandidate skin_candidate(const SkinTrial& trial, double smallest_diameter);

struct SkinChoice {
  std::vector<SkinTrial> trials;  // in the order of the candidates
  std::size_t chosen = 0;         // index into trials
  double skin_fraction() const { return trials.at(chosen).skin_fraction; }
};

// The smallest particle diameter of `system`, m. Throws std::invalid_argument for no particles.
double smallest_diameter(const System& system);

// Steps `system` (a copy: the caller's is untouched) `steps` steps at a skin of `skin_fraction` x
// its smallest diameter and counts what they screened and rebuilt.
SkinTrial run_skin_trial(System system, double skin_fraction, std::uint64_t steps);

// A trial of each candidate on a copy of `system`, and the cheapest by `model` (of equal costs
// the first). Logs (spdlog info) every trial's counts and cost and the choice. Throws
// std::invalid_argument for no candidates, a candidate <= 0 or zero steps.
SkinChoice choose_skin_by_trials(const System& system, std::span<const double> skin_fractions,
                                 std::uint64_t steps, const SkinCostModel& model = {});

// "auto": the trials of kSkinFractionCandidates over kSkinTrialSteps on copies of `system`, and
// the cheapest set as its skin.
SkinChoice adopt_skin_by_trials(System& system);

}  // namespace millflow::dem
