#include "dem/stiffness_policy.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "util/sphere.hpp"

namespace millflow::dem {
namespace {

struct PairSlot {
  ContactType type;
  InteractionSpec ShearCellSetup::*spec;
  bool a_is_powder, b_is_powder;
};

constexpr std::array<PairSlot, 3> kPairs{{
    {ContactType::MediaMedia, &ShearCellSetup::media_media, false, false},
    {ContactType::MediaPowder, &ShearCellSetup::media_powder, false, true},
    {ContactType::PowderPowder, &ShearCellSetup::powder_powder, true, true},
}};

PairStiffness derive(const ShearCellSetup& s, const PairSlot& slot) {
  const double d_m = s.media_diameter, d_p = s.powder_diameter_ratio * s.media_diameter;
  const double d_a = slot.a_is_powder ? d_p : d_m, d_b = slot.b_is_powder ? d_p : d_m;
  const double m_a = util::sphere_mass(slot.a_is_powder ? s.powder.density : s.media.density, d_a);
  const double m_b = util::sphere_mass(slot.b_is_powder ? s.powder.density : s.media.density, d_b);
  const double media_mass = util::sphere_mass(s.media.density, d_m);
  PairStiffness out;
  out.pair = contact_type_name(slot.type);
  out.smaller_diameter = std::min(d_a, d_b);
  out.given = (s.*slot.spec).normal_stiffness;
  out.static_bound = kOverlapSafety * s.normal_stress * d_m * d_m /
                     (s.overlap_bound.mean_fraction * out.smaller_diameter);
  // Impact: the balls' pair mass drives every contact on a ball-ball line (a grain between two
  // balls: two contacts in series); powder-powder contacts stop their own pair's mass.
  const bool between_balls = !(slot.a_is_powder && slot.b_is_powder);
  const double driving_mass =
      between_balls ? effective_mass(media_mass, media_mass) : effective_mass(m_a, m_b);
  const double contacts_in_series = slot.a_is_powder != slot.b_is_powder ? 2.0 : 1.0;
  const double speed = kImpactSpeedFactor * s.shear_rate * d_m;
  const double allowed_tail = s.overlap_bound.p95_fraction * out.smaller_diameter;
  out.impact_bound =
      driving_mass * (speed / allowed_tail) * (speed / allowed_tail) / contacts_in_series;
  if (slot.type == ContactType::MediaMedia)
    out.rigidity_bound = s.overlap_bound.media_rigidity * s.normal_stress * d_m;
  out.chosen = std::max({out.given, out.static_bound, out.impact_bound, out.rigidity_bound});
  out.governing = out.chosen == out.given          ? "given"
                  : out.chosen == out.static_bound ? "static"
                  : out.chosen == out.impact_bound ? "impact"
                                                   : "rigidity";
  out.kappa = out.chosen / (s.normal_stress * out.smaller_diameter);
  return out;
}

}  // namespace

std::vector<PairStiffness> apply_overlap_bound(ShearCellSetup& setup) {
  std::vector<PairStiffness> derived;
  for (const PairSlot& slot : kPairs) {
    derived.push_back(derive(setup, slot));
    (setup.*slot.spec).normal_stiffness = derived.back().chosen;
  }
  return derived;
}

std::vector<PairStiffness> describe_stiffness(const ShearCellSetup& setup) {
  std::vector<PairStiffness> described;
  for (const PairSlot& slot : kPairs) {
    described.push_back(derive(setup, slot));
    described.back().chosen = described.back().given;
    described.back().governing = "given";
    described.back().kappa =
        described.back().given / (setup.normal_stress * described.back().smaller_diameter);
  }
  return described;
}

}  // namespace millflow::dem
