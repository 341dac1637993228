#pragma once
// The neighbour skin chosen per scene by trial (issue 17; docs/shear_cells.md, "The neighbour
// skin"): each candidate skin steps a throwaway copy of the system for a stretch of steps, and the
// skin whose stretch cost least by a deterministic cost proxy is kept. The proxy counts work, not
// time: the candidate pairs of each step and those of them screened (a pair apart sleeps,
// unscreened, while its gap cannot have closed), summed over the stretch's steps, and the list
// rebuilds the skin test asked for, weighed by SkinCostModel's instructions per candidate
// pair-step, per screened pair-step and per particle-rebuild. The same state gives the same choice
// at any thread count and on every run (every count is a property of the state; the system's steps
// are deterministic), and the original system is left untouched.
#include <cstdint>
#include <span>
#include <vector>

#include "dem/system.hpp"

namespace millflow::dem {

// A skin s costs, per particle and step, with p(s) candidate pairs per particle, q(s) of them
// screened per step and a list that lasts steps_per_rebuild(s) steps,
//   p(s) x per_candidate_step + q(s) x per_screened_step + per_particle_rebuild /
//   steps_per_rebuild(s).
// A smaller skin holds fewer candidates and rebuilds more often; a pair the wider skin adds is
// apart by more than the narrower one, so it sleeps longer. The constants are instructions
// measured with callgrind as the differences between whole runs (docs/benchmarks.md, "The skin
// chosen per scene" and "The skin's cost with pairs asleep"). The choice never reads a clock, so a
// run chooses the same skin every time (and no result's bits depend on the skin anyway).
struct SkinCostModel {
  // Every candidate, asleep or not, each step: its wake-up value read and tested, and its
  // in-force bytes walked by the force gather (10.5-10.7 in the pair pass and 0.5-1.4 in the
  // gather, on cement_load05 and le_media_2000 between 0.1 d and 0.3 d).
  double per_candidate_step = 11.0;
  // A screened (awake) candidate, besides: its particles' positions, the image test, the distance,
  // both queues' slots and its wake-up value written (71.7 on cement_load05 and 75.6 on
  // le_media_2000, against a build that keeps every pair awake; the smaller taken).
  double per_screened_step = 72.0;
  // A rebuild of the list, per particle (with the skin's screening before pairs slept: 4,530-4,690
  // on cement_load05, besides the screening it saves). Measured directly too (callgrind,
  // inclusive cost of System::rebuild_neighbors per call / particles, whole `millflow cell` runs
  // of quick.json's bulk-0 cell, docs/shear_cells.md): 4,660 at skin 0.1 d and 6,680 at 0.3 d on
  // the 131-media cell (load 0), 5,180 at 0.15 d and 5,800 at 0.2-0.3 d on the 647-particle powder
  // cell (load 1). Kept at 4,500: the weight matters where rebuilds are frequent, the small skins,
  // and there it is within 15%; a rebuild grows with the pairs it finds, but not by one rule
  // across cells (the powder cell finds fewer pairs per particle and costs more), so it is not
  // scaled by them.
  double per_particle_rebuild = 4500.0;
};

struct SkinCandidate {
  double skin = 0.0;                   // m
  double pairs_per_particle = 0.0;     // candidate pairs / particles, at this skin
  double screened_per_particle = 0.0;  // screened candidate pairs per particle and step
  double steps_per_rebuild = 0.0;      // steps between rebuilds, at this skin
};
// The cost above, instructions per particle and step.
double skin_cost(const SkinCandidate& c, const SkinCostModel& model);
// Index of the cheapest candidate; of equal costs the first. Throws std::invalid_argument for no
// candidates or one with a non-positive skin or interval.
std::size_t cheapest_skin(std::span<const SkinCandidate> candidates, const SkinCostModel& model);

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
  double screened_pair_steps = 0.0;   // of them, those screened (awake)
  std::uint64_t rebuilds = 0;         // rebuilds the skin test asked for in the steps
  // The lists' lives used in the steps: the rebuilds plus the change of the current list's
  // travel / skin. Counting rebuilds alone, a list that would last 150 steps looked free over a
  // 100-step trial and one that lasted 101 looked as costly as one of 100.
  double lists_used = 0.0;
  std::size_t particles = 0;
};

// A trial as the cost model's candidate: candidate and screened pairs per particle-step and steps
// per list life used (infinite when the list never moved), so that cheapest_skin weighs it.
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
