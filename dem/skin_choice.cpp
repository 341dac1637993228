#include "dem/skin_choice.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace millflow::dem {

double skin_cost(const SkinCandidate& c, const SkinCostModel& model) {
  return c.pairs_per_particle * model.per_candidate_step +
         c.screened_per_particle * model.per_screened_step +
         model.per_particle_rebuild / c.steps_per_rebuild;
}

std::size_t cheapest_skin(std::span<const SkinCandidate> candidates, const SkinCostModel& model) {
  if (candidates.empty()) throw std::invalid_argument("cheapest_skin: no candidate skins");
  std::size_t best = 0;
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    const SkinCandidate& c = candidates[k];
    if (!(c.skin > 0.0) || !(c.steps_per_rebuild > 0.0)) {
      throw std::invalid_argument(fmt::format("cheapest_skin: skin {} m with {} steps per rebuild",
                                              c.skin, c.steps_per_rebuild));
    }
    if (skin_cost(c, model) < skin_cost(candidates[best], model)) best = k;
  }
  return best;
}

SkinCandidate skin_candidate(const SkinTrial& trial, double smallest_diameter) {
  const double particle_steps = static_cast<double>(trial.steps) *
                                static_cast<double>(std::max<std::size_t>(trial.particles, 1));
  return {.skin = trial.skin_fraction * smallest_diameter,
          .pairs_per_particle = trial.candidate_pair_steps / particle_steps,
          .screened_per_particle = trial.screened_pair_steps / particle_steps,
          .steps_per_rebuild = trial.lists_used > 0.0
                                   ? static_cast<double>(trial.steps) / trial.lists_used
                                   : std::numeric_limits<double>::infinity()};
}

double smallest_diameter(const System& system) {
  const auto radii = system.radii();
  if (radii.empty()) throw std::invalid_argument("smallest_diameter: the system has no particles");
  return 2.0 * *std::min_element(radii.begin(), radii.end());
}

SkinTrial run_skin_trial(System system, double skin_fraction, std::uint64_t steps) {
  system.set_record_collisions(false);  // a throwaway copy: nobody reads its events
  system.set_neighbor_skin(skin_fraction * smallest_diameter(system));
  SkinTrial trial{.skin_fraction = skin_fraction, .steps = steps, .particles = system.size()};
  const std::uint64_t rebuilds0 = system.neighbor_rebuild_count();
  const double life_used0 = system.neighbor_travel() / system.neighbor_skin();
  const std::uint64_t screened0 = system.pairs_screened();
  for (std::uint64_t s = 0; s < steps; ++s) {
    system.step();
    trial.candidate_pair_steps += static_cast<double>(system.candidate_pairs().size());
  }
  trial.screened_pair_steps = static_cast<double>(system.pairs_screened() - screened0);
  trial.rebuilds = system.neighbor_rebuild_count() - rebuilds0;
  trial.lists_used = static_cast<double>(trial.rebuilds) +
                     system.neighbor_travel() / system.neighbor_skin() - life_used0;
  return trial;
}

SkinChoice choose_skin_by_trials(const System& system, std::span<const double> skin_fractions,
                                 std::uint64_t steps, const SkinCostModel& model) {
  if (skin_fractions.empty() || steps == 0)
    throw std::invalid_argument("choose_skin_by_trials: no candidate skins or zero steps");
  for (double f : skin_fractions) {
    if (!(f > 0.0) || !std::isfinite(f))
      throw std::invalid_argument(fmt::format("choose_skin_by_trials: skin fraction = {}", f));
  }
  const double d = smallest_diameter(system);
  SkinChoice choice;
  std::vector<SkinCandidate> candidates;
  for (double f : skin_fractions) {
    choice.trials.push_back(run_skin_trial(system, f, steps));
    candidates.push_back(skin_candidate(choice.trials.back(), d));
  }
  choice.chosen = cheapest_skin(candidates, model);
  std::string table;
  for (std::size_t k = 0; k < choice.trials.size(); ++k) {
    table += fmt::format(
        " [{:.3g} d: {:.3f} pairs/particle, {:.3f} screened per particle-step, {} rebuilds, {:.2f} "
        "list lives, cost {:.0f}]",
        choice.trials[k].skin_fraction, candidates[k].pairs_per_particle,
        candidates[k].screened_per_particle, choice.trials[k].rebuilds, choice.trials[k].lists_used,
        skin_cost(candidates[k], model));
  }
  spdlog::info(
      "neighbour skin chosen by trial: {:.3g} x the smallest diameter {:.4g} m ({} steps per "
      "candidate from step {}; cost per particle-step = pairs x {} + screened x {} + list lives "
      "per step x {}):{}",
      choice.skin_fraction(), d, steps, system.step_count(), model.per_candidate_step,
      model.per_screened_step, model.per_particle_rebuild, table);
  return choice;
}

SkinChoice adopt_skin_by_trials(System& system) {
  SkinChoice choice = choose_skin_by_trials(system, kSkinFractionCandidates, kSkinTrialSteps);
  system.set_neighbor_skin(choice.skin_fraction() * smallest_diameter(system));
  return choice;
}

}  // namespace millflow::dem
