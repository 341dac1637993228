#include "dem/system.hpp"

#include "util/sphere.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "dem/array_growth.hpp"
#include "dem/awake_pairs.hpp"
#include "dem/contact_lanes.hpp"
#include "dem/contact_law.hpp"
#include "dem/drift.hpp"
#include "dem/packed_vec3.hpp"

namespace millflow::dem {
namespace {

// Chunk sizes of the parallel loops: per-element work is tens of nanoseconds, so smaller chunks
// cost more in scheduling than they gain in balance. Results do not depend on them.
constexpr std::size_t kReduceGrain = 1024;
constexpr std::size_t kParticleGrain = 256;
constexpr std::size_t kPairGrain = 1024;

// How far ahead the pair pass asks for the particles it will read (docs/benchmarks.md, "The pair
// pass asks for its particles ahead"): a dense cell of 100,000 particles outgrows the caches, and
// the second particle of a pair sits anywhere along the Morton curve. Measured on cement_load15:
// 8 to 32 pairs and 2 to 8 contacts ahead gave the same gain within the host's noise.
constexpr std::size_t kScreeningLookahead = 16;
constexpr std::size_t kContactLookahead = 4;

// The default neighbour skin, x the smallest radius (0.3 x the smallest diameter).
constexpr double kDefaultSkinPerSmallestRadius = 0.6;

double square(double v) {
  return v * v;
}

bool finite(const Vec3& v) {
  return v.allFinite();
}

// Calls f(index) for each nonzero byte in increasing index order; skips zero bytes eight at a
// time (finished contacts are few among many pairs).
template <class F>
void for_each_nonzero(std::span<const std::uint8_t> flags, F&& f) {
  std::size_t k = 0;
  for (; k + 8 <= flags.size(); k += 8) {
    std::uint64_t word;
    std::memcpy(&word, flags.data() + k, sizeof word);
    if (word == 0) continue;
    for (std::size_t b = k; b < k + 8; ++b) {
      if (flags[b]) f(b);
    }
  }
  for (; k < flags.size(); ++k) {
    if (flags[k]) f(k);
  }
}

// Mass of the lightest free particle of each material (infinity where there is none).
std::vector<double> lightest_mass_per_material(std::size_t material_count,
                                               std::span<const double> mass,
                                               std::span<const MaterialId> material,
                                               std::span<const GroupId> group) {
  std::vector<double> lightest(material_count, std::numeric_limits<double>::infinity());
  for (std::size_t p = 0; p < mass.size(); ++p) {
    if (group[p] == kFreeParticle) lightest[material[p]] = std::min(lightest[material[p]], mass[p]);
  }
  return lightest;
}

double restitution_of(double damping_ratio) {
  return std::exp(-damping_ratio * std::numbers::pi /
                  std::sqrt(1.0 - damping_ratio * damping_ratio));
}

}  // namespace

System::System(MaterialTable materials, Domain domain, Vec3 gravity)
    : materials_(std::move(materials)),
      domain_(domain),
      gravity_(gravity),
      neighbors_(NeighborSearchOptions{}),
      contacts_in_lanes_(contact_lanes_available()) {
  domain_.validate();
  if (!finite(gravity_)) throw std::invalid_argument("gravity is not finite");
  finished_dissipation_.resize(category_count());
}

void System::set_contacts_in_lanes(bool on) {
  contacts_in_lanes_ = on && contact_lanes_available();
}

ParticleId System::add_particle(const ParticleSpec& spec) {
  const std::size_t id = size();
  if (!(spec.radius > 0.0) || !std::isfinite(spec.radius)) {
    throw std::invalid_argument(
        fmt::format("particle {}: radius = {} m must be > 0", id, spec.radius));
  }
  if (!finite(spec.position) || !finite(spec.velocity) || !finite(spec.angular_velocity)) {
    throw std::invalid_argument(fmt::format("particle {}: position or velocity is not finite", id));
  }
  if (spec.material >= materials_.size()) {
    throw std::invalid_argument(
        fmt::format("particle {}: material id {} is not defined ({} materials)", id, spec.material,
                    materials_.size()));
  }
  if (spec.group > groups_.size()) {
    throw std::invalid_argument(fmt::format("particle {}: group {} is not defined ({} groups)", id,
                                            spec.group, groups_.size()));
  }
  const double volume = util::sphere_volume_of_radius(spec.radius);
  const double mass = materials_.material(spec.material).density * volume;
  const bool free = spec.group == kFreeParticle;
  Vec3 position = spec.position, velocity = free ? spec.velocity : groups_[spec.group - 1].velocity;
  domain_.wrap(position, velocity);

  position_.push_back(position);
  velocity_.push_back(velocity);
  angular_velocity_.push_back(free ? spec.angular_velocity : Vec3::Zero());
  force_.push_back(Vec3::Zero());
  torque_.push_back(Vec3::Zero());
  predicted_velocity_.push_back(velocity);
  predicted_angular_velocity_.push_back(angular_velocity_.back());
  radius_.push_back(spec.radius);
  mass_.push_back(mass);
  inv_mass_.push_back(free ? 1.0 / mass : 0.0);
  inv_inertia_.push_back(free ? 1.0 / (0.4 * mass * spec.radius * spec.radius) : 0.0);
  material_.push_back(spec.material);
  group_.push_back(spec.group);
  if (!walls_.empty()) {
    for (WallSlots& buffer : wall_slots_) buffer.resize(size());
    finished_wall_mask_.push_back(0);
  }
  prepared_ = false;
  return static_cast<ParticleId>(id);
}

GroupId System::add_group(const KinematicGroup& group) {
  if (!finite(group.velocity))
    throw std::invalid_argument(fmt::format("group '{}': velocity is not finite", group.name));
  groups_.push_back(group);
  group_loads_.emplace_back();
  return static_cast<GroupId>(groups_.size());
}

std::size_t System::add_wall(const Wall& wall) {
  validate_wall(wall);
  if (wall.material >= materials_.size()) {
    throw std::invalid_argument(
        fmt::format("wall '{}': material id {} is not defined", wall.name, wall.material));
  }
  walls_.push_back(wall);
  wall_loads_.emplace_back();
  for (WallSlots& buffer : wall_slots_) buffer.resize(size());
  finished_wall_mask_.resize(size(), 0);
  finished_dissipation_.resize(category_count());
  prepared_ = false;
  return walls_.size() - 1;
}

std::size_t System::category_count() const {
  const std::size_t m = materials_.size();
  return m * m + walls_.size() * m;
}

std::uint32_t System::pair_category(MaterialId a, MaterialId b) const {
  return static_cast<std::uint32_t>(std::min(a, b) * materials_.size() + std::max(a, b));
}

std::uint32_t System::wall_category(std::size_t wall, MaterialId m) const {
  const std::size_t n = materials_.size();
  return static_cast<std::uint32_t>(n * n + wall * n + m);
}

std::string System::category_name(std::uint32_t category) const {
  const std::size_t n = materials_.size();
  if (category < n * n) {
    return materials_.pair_name(static_cast<MaterialId>(category / n),
                                static_cast<MaterialId>(category % n));
  }
  const std::size_t rest = category - n * n;
  return fmt::format("{}-wall:{}", materials_.material(static_cast<MaterialId>(rest % n)).name,
                     walls_.at(rest / n).name);
}

double System::min_collision_duration() const {
  double shortest = std::numeric_limits<double>::infinity();
  const auto lightest = lightest_mass_per_material(materials_.size(), mass_, material_, group_);
  auto consider = [&](MaterialId a, MaterialId b, double m_eff, const std::string& what) {
    if (!materials_.has_interaction(a, b)) {
      throw std::invalid_argument(
          fmt::format("no interaction is defined for {}; add one for that material pair", what));
    }
    const PairParams& p = materials_.pair(a, b);
    shortest = std::min(shortest, collision_duration(p.normal_stiffness, m_eff, p.damping_ratio));
  };
  for (MaterialId a = 0; a < materials_.size(); ++a) {
    if (!std::isfinite(lightest[a])) continue;
    for (MaterialId b = a; b < materials_.size(); ++b) {
      if (std::isfinite(lightest[b]))
        consider(a, b, effective_mass(lightest[a], lightest[b]), materials_.pair_name(a, b));
    }
    for (const Wall& wall : walls_) {
      consider(a, wall.material, lightest[a],
               fmt::format("{} and wall '{}'", materials_.material(a).name, wall.name));
    }
  }
  // Kinematic particles act as infinitely heavy walls.
  for (std::size_t p = 0; p < size(); ++p) {
    if (is_free(p)) continue;
    for (MaterialId a = 0; a < materials_.size(); ++a) {
      if (std::isfinite(lightest[a]))
        consider(a, material_[p], lightest[a], materials_.pair_name(a, material_[p]));
    }
  }
  if (!std::isfinite(shortest))
    throw std::invalid_argument("no free particles: cannot derive a time step");
  return shortest;
}

double System::stable_time_step() const {
  // The stability limit scales with the contact duration with the same damping, so the pair with
  // the shortest contact also has the smallest limit for equal damping; take the minimum over all.
  double limit = std::numeric_limits<double>::infinity();
  const auto lightest = lightest_mass_per_material(materials_.size(), mass_, material_, group_);
  for (MaterialId a = 0; a < materials_.size(); ++a) {
    if (!std::isfinite(lightest[a])) continue;
    for (MaterialId b = 0; b < materials_.size(); ++b) {
      if (!materials_.has_interaction(a, b)) continue;
      const PairParams& p = materials_.pair(a, b);
      const double m_eff =
          std::isfinite(lightest[b]) ? effective_mass(lightest[a], lightest[b]) : lightest[a];
      limit = std::min(limit, pair_stable_time_step_limit(p, m_eff));
    }
  }
  return limit;
}

void System::set_time_step_from_collisions(int steps_per_collision) {
  if (steps_per_collision < 1) {
    throw std::invalid_argument(fmt::format(
        "steps per collision = {} must be >= 1 (20 or more is usual)", steps_per_collision));
  }
  const double t_c = min_collision_duration();
  const auto lightest = lightest_mass_per_material(materials_.size(), mass_, material_, group_);
  for (MaterialId a = 0; a < materials_.size(); ++a) {
    for (MaterialId b = a; b < materials_.size(); ++b) {
      if (!materials_.has_interaction(a, b) || !std::isfinite(lightest[a])) continue;
      const PairParams& p = materials_.pair(a, b);
      const double m_eff =
          std::isfinite(lightest[b]) ? effective_mass(lightest[a], lightest[b]) : lightest[a];
      spdlog::info(
          "dem: {}: k_n = {:.4g} N/m, k_t = {:.4g} N/m, e = {:.4g} (zeta = {:.4g}), mu = {:.4g}; "
          "lightest pair m_eff = {:.4g} kg: C_n = {:.4g} N s/m, t_c = {:.4g} s",
          materials_.pair_name(a, b), p.normal_stiffness, p.tangential_stiffness,
          restitution_of(p.damping_ratio), p.damping_ratio, p.friction, m_eff,
          normal_damping_coefficient(p.normal_stiffness, m_eff, p.damping_ratio),
          collision_duration(p.normal_stiffness, m_eff, p.damping_ratio));
    }
  }
  set_time_step(t_c / steps_per_collision);
  spdlog::info(
      "dem: dt = t_c / {} = {:.4g} s (shortest contact t_c = {:.4g} s, stability limit {:.4g} s)",
      steps_per_collision, dt_, t_c, stable_time_step());
}

void System::set_time_step(double dt) {
  const double limit = stable_time_step();
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    throw std::invalid_argument(fmt::format("time step dt = {} s must be > 0", dt));
  }
  if (dt > limit) {
    // In steps per collision, which a user gives: a contact damped near the critical (restitution
    // near 0) has a long duration but a short limit, so 20 steps may not do.
    const double t_c = min_collision_duration();
    throw std::invalid_argument(fmt::format(
        "time step dt = {:.4g} s is above the stability limit {:.4g} s of the stiffest, lightest "
        "contact; use dt <= {:.4g} s: {:.0f} or more steps per collision of the shortest contact "
        "(t_c = {:.4g} s)",
        dt, limit, limit, std::ceil(t_c / limit), t_c));
  }
  dt_ = dt;
}

void System::set_neighbor_skin(double skin) {
  if (!(skin > 0.0) || !std::isfinite(skin)) {
    throw std::invalid_argument(fmt::format("neighbour skin = {} m must be > 0", skin));
  }
  skin_ = skin;
  if (!prepared_) return;
  // A running system keeps its state: only the neighbour list is built again, with the new skin,
  // the pairs in force keeping their histories and forces (which the skin does not change).
  const std::vector<TouchingSlot> touching = touching_pairs();
  neighbors_ = NeighborSearch(NeighborSearchOptions{.skin = skin_});
  rebuild_with_touching(touching);
}

std::vector<System::TouchingSlot> System::touching_pairs() const {
  std::vector<TouchingSlot> touching;
  const auto& pairs = neighbors_.pairs();
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    if (pair_touching_[k]) touching.push_back(TouchingSlot{pairs[k], pair_slot_[k]});
  }
  return touching;
}

void System::rebuild_with_touching(std::span<const TouchingSlot> touching) {
  std::vector<NeighborPair> pairs(touching.size());
  std::vector<std::uint32_t> slots(touching.size());
  for (std::size_t c = 0; c < touching.size(); ++c) {
    pairs[c] = touching[c].pair;
    slots[c] = touching[c].slot;
  }
  rebuild_neighbors(pairs, slots);
  restore_pair_forces(pairs);
}

void System::deform_affinely(int axis, double factor) {
  if (axis < 0 || axis > 2 || !domain_.periodic[static_cast<std::size_t>(axis)]) {
    throw std::invalid_argument(
        fmt::format("deform_affinely: axis {} must be a periodic axis (0, 1 or 2)", axis));
  }
  if (!(factor > 0.0) || !std::isfinite(factor)) {
    throw std::invalid_argument(fmt::format("deform_affinely: factor = {} must be > 0", factor));
  }
  if (!groups_.empty()) {
    throw std::invalid_argument(
        "deform_affinely: kinematic groups would be torn apart; use walls or no groups");
  }
  const double lo = domain_.lo[axis];
  for (Vec3& x : position_) x[axis] = lo + factor * (x[axis] - lo);
  domain_.hi[axis] = lo + factor * (domain_.hi[axis] - lo);
  if (domain_.lees_edwards.enabled && domain_.lees_edwards.gradient_axis == axis)
    domain_.lees_edwards.velocity *= factor;
  contact_virial_.col(axis) *= factor;
  approach_bound_ += std::abs(factor - 1.0) * pair_separation_bound_;
}

void System::check_overlaps(double tolerance) const {
  const auto pairs = brute_force_pairs(domain_, position_, radius_, 0.0);
  for (const auto& [i, j] : pairs) {
    if (!is_free(i) && !is_free(j)) continue;
    const double distance = domain_.separation(position_[i], position_[j]).norm();
    const double overlap = radius_[i] + radius_[j] - distance;
    const double smaller = std::min(radius_[i], radius_[j]);
    if (overlap > tolerance * smaller) {
      throw std::invalid_argument(
          fmt::format("particles {} and {} overlap by {:.4g} m ({:.3g}% of the smaller radius; "
                      "tolerance {:.3g}%); "
                      "move them apart or place them on a coarser lattice",
                      i, j, overlap, 100.0 * overlap / smaller, 100.0 * tolerance));
    }
  }
}

void System::prepare_first_step() {
  if (dt_ == 0.0) set_time_step_from_collisions(20);
  if (skin_ == 0.0 && size() > 0) {
    skin_ = kDefaultSkinPerSmallestRadius * *std::min_element(radius_.begin(), radius_.end());
  }
  neighbors_ = NeighborSearch(NeighborSearchOptions{.skin = skin_});
  pair_slot_.clear();
  contact_history_.clear();
  contact_force_.clear();
  free_contact_slots_.clear();
  update_neighbors(neighbors_.needs_rebuild(domain_, position_));
  // Forces at the current time (no spring increment, no dissipation: no time passes).
  compute_pair_forces(0.0);
  compute_particle_forces(0.0, /*closing_kick=*/false);
  reduce_loads(0.0);
  collect_finished_contacts();
  prepared_ = true;
}

void System::step(std::size_t count) {
  if (!prepared_) prepare_first_step();
  for (std::size_t n = 0; n < count; ++n) {
    if (reorder_every_ > 0 && step_count_ % reorder_every_ == 0) reorder_particles();
    domain_.advance_shear(dt_);  // the image offset at t + dt, where drift() wraps positions
    const bool rebuild = kick_and_drift();
    time_ += dt_;
    for (Wall& wall : walls_) advance_wall(wall, dt_);
    update_neighbors(rebuild);
    if (rebuild) ++rebuild_count_;
    const std::size_t in_force = contact_history_.size() - free_contact_slots_.size();
    if (2 * contacts_placed_since_compaction_ > in_force &&
        256 * contacts_placed_since_compaction_ > neighbors_.pairs().size())
      compact_contacts();
    compute_pair_forces(dt_);
    // The closing half kick uses only this step's forces and masses: the force gather applies it
    // as it sums each particle's force, sparing a pass over the particles.
    compute_particle_forces(dt_, /*closing_kick=*/true);
    reduce_loads(dt_);
    collect_finished_contacts();
    for (std::size_t w = 0; w < walls_.size(); ++w) control_wall(walls_[w], wall_loads_[w]);
    ++step_count_;
  }
}

std::array<double, 3> System::no_image_limits() const {
  std::array<double, 3> limit{};
  const Vec3 box = domain_.length();
  for (int axis = 0; axis < 3; ++axis)
    limit[axis] =
        domain_.periodic[axis] ? 0.5 * box[axis] : std::numeric_limits<double>::infinity();
  return limit;
}

// The hot loops below read and write through local pointers, declared inside each task: Eigen's
// vector stores may alias anything, which would otherwise make the compiler reload every array's
// address and the box after each store.

DriftArrays System::drift_arrays() {
  DriftArrays arrays;
  arrays.position = position_.data();
  arrays.velocity = velocity_.data();
  arrays.angular_velocity = angular_velocity_.data();
  arrays.predicted_velocity = predicted_velocity_.data();
  arrays.predicted_angular_velocity = predicted_angular_velocity_.data();
  arrays.force = force_.data();
  arrays.torque = torque_.data();
  arrays.inv_mass = inv_mass_.data();
  arrays.inv_inertia = inv_inertia_.data();
  if (!groups_.empty()) {
    arrays.group = group_.data();
    arrays.groups = groups_.data();
  }
  const std::span<const Vec3> reference = neighbors_.reference_positions();
  if (reference.size() == size()) arrays.reference_position = reference.data();
  if (gravity_.isZero(0.0) && particle_force_state_.size() == size())
    arrays.force_state = particle_force_state_.data();
  return arrays;
}

bool System::kick_and_drift() {
  const double half_dt = 0.5 * dt_, dt = dt_;
  const std::array<double, 3> no_image_limit = no_image_limits();
  const double image_test_sq =
      square(std::min({no_image_limit[0], no_image_limit[1], no_image_limit[2]}));
  // The shear flow the particles' own speeds are taken against (pairs apart sleep by them): the
  // image velocity over the gradient axis's length, zero about the box's middle.
  const LeesEdwards& shear = domain_.lees_edwards;
  const int gradient_axis = shear.enabled ? shear.gradient_axis : 1;
  const double shear_rate = shear.enabled ? shear.velocity / domain_.length()[gradient_axis] : 0.0;
  const double flow_centre = 0.5 * (domain_.lo[gradient_axis] + domain_.hi[gradient_axis]);
  // The flow's velocity per unit of height (a vector, so that the pass never indexes a register).
  Vec3 flow_per_height = Vec3::Zero();
  if (shear.enabled) flow_per_height[shear.flow_axis] = shear_rate;
  const DriftArrays arrays = drift_arrays();
  DriftParameters parameters;
  parameters.half_dt = half_dt;
  parameters.dt = dt;
  parameters.gradient_axis = gradient_axis;
  parameters.flow_centre = flow_centre;
  parameters.flow_per_height = flow_per_height;
  parameters.no_image_limit = no_image_limit;
  parameters.image_test_sq = image_test_sq;
  const DriftMaxima maxima = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, size(), kParticleGrain), DriftMaxima{},
      [&](const tbb::blocked_range<std::size_t>& range, DriftMaxima running_before) {
        return drift_particles(arrays, parameters, domain_, range.begin(), range.end(),
                               running_before);
      },
      [](const DriftMaxima& a, const DriftMaxima& b) {
        return DriftMaxima{std::max(a.moved_sq, b.moved_sq),
                           std::max(a.peculiar_speed_sq, b.peculiar_speed_sq)};
      });
  // A pair's separation changes in the drift by its two speeds against the flow and by the flow's
  // difference across it (the shear rate times its separation along the gradient, the image's
  // offset included).
  approach_bound_ +=
      (2.0 * std::sqrt(maxima.peculiar_speed_sq) + std::abs(shear_rate) * pair_separation_bound_) *
      dt;
  return neighbors_.needs_rebuild(domain_, size(), maxima.moved_sq);
}

double System::neighbor_travel() const {
  const std::span<const Vec3> reference = neighbors_.reference_positions();
  if (reference.empty()) return 0.0;
  double max_displacement_sq = 0.0;
  for (std::size_t i = 0; i < reference.size() && i < size(); ++i) {
    max_displacement_sq =
        std::max(max_displacement_sq, domain_.separation(reference[i], position_[i]).squaredNorm());
  }
  return neighbors_.travel(domain_, max_displacement_sq);
}

void System::update_neighbors(bool rebuild) {
  if (!rebuild) return;
  const std::vector<NeighborPair> old_pairs = neighbors_.pairs();
  const std::vector<std::uint32_t> old_slot = std::move(pair_slot_);
  rebuild_neighbors(old_pairs, old_slot);
}

void System::rebuild_neighbors(std::span<const NeighborPair> old_pairs,
                               std::vector<ContactHistory> old_history) {
  contact_history_ = std::move(old_history);
  contact_force_.assign(contact_history_.size(), ContactForce{});
  std::vector<std::uint32_t> slot(contact_history_.size());
  for (std::size_t c = 0; c < slot.size(); ++c) slot[c] = static_cast<std::uint32_t>(c);
  rebuild_neighbors(old_pairs, slot);
}

void System::rebuild_neighbors(std::span<const NeighborPair> old_pairs,
                               std::span<const std::uint32_t> old_slot) {
  neighbors_.build(domain_, position_, radius_);
  const auto& pairs = neighbors_.pairs();
  reset_sleeping_pairs();

  // Carry the contacts over to the new list (both lists are sorted by (i, j)): the store is laid
  // out in the new pairs' order, in place (a second store beside it would take a dense cell's
  // memory at the rebuild up by half, and its fresh pages, which the kernel zeroes, 2% of the
  // steps: docs/benchmarks.md, "The contact store carried over in place").
  auto key = [](const NeighborPair& p) { return (std::uint64_t{p.i} << 32) | p.j; };
  std::vector<std::uint32_t> target(contact_history_.size(), kNoContact);
  assign_on_huge_pages(pair_slot_, pairs.size(), kNoContact);
  assign_on_huge_pages(pair_touching_, pairs.size(), std::uint8_t{0});
  std::uint32_t carried = 0;
  std::size_t o = 0;
  for (std::size_t k = 0; k < pairs.size() && o < old_pairs.size(); ++k) {
    while (o < old_pairs.size() && key(old_pairs[o]) < key(pairs[k])) ++o;
    if (o < old_pairs.size() && key(old_pairs[o]) == key(pairs[k]) && old_slot[o] != kNoContact) {
      target[old_slot[o]] = carried;
      pair_slot_[k] = carried++;
      pair_touching_[k] = 1;
    }
  }
  place_contacts(target, carried);
  // The store keeps room beyond the carried contacts for those that start before the next
  // rebuild (growth_room: while contacts grow, in a compaction, each is copied about 16 times),
  // and is fitted again when it holds more than an eighth beyond that (a steady cell's contacts
  // swing by a few per cent; a dilating one's store is given back).
  const std::size_t room = carried + growth_room(carried);
  const auto fit = [room](auto& store) {
    if (store.capacity() < room || store.capacity() > room + room / 8)
      reserve_on_huge_pages(store, room);
  };
  fit(contact_history_);
  fit(contact_force_);
  free_contact_slots_.clear();
  contacts_placed_since_compaction_ = 0;
  // A rebuild follows every reorder, checkpoint restore and added particle: no force is known to
  // be a weight, and the next gather writes them all.
  particle_force_state_.assign(size(), kForceSummed);

  // Per-particle pair lists in pair order, so force sums run in a fixed order; each list starts at
  // a multiple of 8 slots, so that the force gather reads its in-force bytes 8 at a time without
  // reading another particle's.
  const auto padded_offsets = [n = size()](std::vector<std::uint32_t>& offset) {
    for (std::size_t p = 0; p < n; ++p) offset[p + 1] = offset[p] + ((offset[p + 1] + 7u) & ~7u);
  };
  second_offset_.assign(size() + 1, 0);
  first_offset_.assign(size() + 1, 0);
  for (const auto& pair : pairs) {
    ++first_offset_[pair.i + 1];
    ++second_offset_[pair.j + 1];
  }
  padded_offsets(second_offset_);
  padded_offsets(first_offset_);
  resize_with_room(second_contact_slot_, second_offset_[size()]);
  assign_on_huge_pages(second_in_force_, second_offset_[size()], std::uint8_t{0});
  assign_on_huge_pages(first_in_force_, first_offset_[size()], std::uint8_t{0});
  resize_with_room(pair_second_slot_, pairs.size());
  particle_first_shift_.resize(size());
  std::vector<std::uint32_t> second_fill(second_offset_.begin(), second_offset_.end() - 1);
  for (std::uint32_t k = 0; k < pairs.size(); ++k) {
    const auto [i, j] = pairs[k];
    // Row i's pairs are consecutive: pair k's slot in i's row list is k + the same shift for all
    // (never negative: the row lists before i's hold at least the k pairs of earlier rows).
    if (k == 0 || pairs[k - 1].i != i) particle_first_shift_[i] = first_offset_[i] - k;
    pair_second_slot_[k] = second_fill[j];
    second_contact_slot_[second_fill[j]++] = pair_slot_[k];
  }
}

void System::reset_sleeping_pairs() {
  assign_on_huge_pages(pair_wake_, neighbors_.pairs().size(), 0.0f);
  approach_bound_ = 0.0;
  const double largest_radius =
      radius_.empty() ? 0.0 : *std::max_element(radius_.begin(), radius_.end());
  // A candidate pair was within its reach plus the skin at the build, and each particle moves at
  // most half a skin before the next (NeighborSearch::travel); the factor covers rounding.
  pair_separation_bound_ = (2.0 * largest_radius + 2.0 * skin_) * (1.0 + 1e-9);
  // Another periodic image of a pair could close faster than the bound says (a Lees-Edwards image
  // streams at the image velocity); it stays out of reach while every period holds two
  // separations and more.
  pairs_may_sleep_ = true;
  const Vec3 length = domain_.length();
  for (int axis = 0; axis < 3; ++axis) {
    if (domain_.periodic[axis] && length[axis] < 2.0 * (pair_separation_bound_ + skin_))
      pairs_may_sleep_ = false;
  }
}

void System::restore_pair_forces(std::span<const NeighborPair> pairs,
                                 std::span<const Vec3> forces) {
  const auto& rebuilt = neighbors_.pairs();
  std::size_t k = 0;
  for (std::size_t c = 0; c < pairs.size(); ++c) {
    while (k < rebuilt.size() && !(rebuilt[k] == pairs[c])) ++k;
    if (k == rebuilt.size() || pair_slot_[k] == kNoContact)
      throw std::logic_error(fmt::format(
          "a touching pair ({}, {}) is out of reach of its particles", pairs[c].i, pairs[c].j));
    if (!forces.empty()) contact_force_[pair_slot_[k]].force = forces[c];
  }
}

std::uint32_t System::allocate_contact() {
  ++contacts_placed_since_compaction_;
  std::uint32_t slot;
  if (!free_contact_slots_.empty()) {
    slot = free_contact_slots_.back();
    free_contact_slots_.pop_back();
    contact_history_[slot] = ContactHistory{};
  } else {
    slot = static_cast<std::uint32_t>(contact_history_.size());
    resize_with_room(contact_history_, slot + 1);
    resize_with_room(contact_force_, slot + 1);
  }
  return slot;
}

void System::place_contacts(std::vector<std::uint32_t>& target, std::uint32_t kept) {
  // The slots not given one go after the kept, in slot order: a permutation of the store.
  std::uint32_t next = kept;
  for (std::uint32_t& t : target) {
    if (t == kNoContact) t = next++;
  }
  // In place, cycle by cycle: no second store.
  for (std::uint32_t s = 0; s < target.size(); ++s) {
    while (target[s] != s) {
      const std::uint32_t t = target[s];
      std::swap(contact_history_[s], contact_history_[t]);
      std::swap(contact_force_[s], contact_force_[t]);
      std::swap(target[s], target[t]);
    }
  }
  contact_history_.resize(kept);
  contact_force_.resize(kept);
}

void System::compact_contacts() {
  const std::size_t store = contact_history_.size();
  // The slot each one moves to: the pairs in force in pair order first, the free slots after.
  std::vector<std::uint32_t> target(store, kNoContact);
  std::uint32_t next = 0;
  for (std::size_t k = 0; k < pair_slot_.size(); ++k) {
    const std::uint32_t slot = pair_slot_[k];
    if (slot == kNoContact) continue;
    target[slot] = next;
    pair_slot_[k] = next;
    second_contact_slot_[pair_second_slot_[k]] = next;
    ++next;
  }
  place_contacts(target, next);
  free_contact_slots_.clear();
  contacts_placed_since_compaction_ = 0;
  ++compaction_count_;
}

namespace {

// Spreads the low 21 bits of v to every third bit (bit b goes to bit 3 b).
std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

template <class T>
void permute(std::vector<T>& values, std::span<const ParticleId> old_of) {
  std::vector<T> permuted;
  reserve_on_huge_pages(permuted, values.size());
  for (std::size_t p = 0; p < old_of.size(); ++p) permuted.push_back(values[old_of[p]]);
  values = std::move(permuted);
}

}  // namespace

std::vector<ParticleId> System::reorder_particles() {
  const std::size_t n = size();
  if (n == 0) return {};
  if (!prepared_) prepare_first_step();
  // The Morton key of each particle's cell.
  // The cell is that of the finest neighbour-list level at the default skin, whatever the skin:
  // the skin then changes no result.
  const double smallest = *std::min_element(radius_.begin(), radius_.end());
  const double cell = 2.0 * smallest + kDefaultSkinPerSmallestRadius * smallest;
  std::vector<std::pair<std::uint64_t, ParticleId>> keyed;
  std::vector<ParticleId> free_slots;
  for (std::size_t p = 0; p < n; ++p) {
    if (!is_free(p)) continue;
    std::uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      const double c = std::floor((position_[p][a] - domain_.lo[a]) / cell);
      key |= spread_bits(static_cast<std::uint64_t>(std::clamp(c, 0.0, 2097151.0))) << a;
    }
    keyed.emplace_back(key, static_cast<ParticleId>(p));
    free_slots.push_back(static_cast<ParticleId>(p));
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<ParticleId> old_of(n), new_of(n);
  for (std::size_t p = 0; p < n; ++p) old_of[p] = static_cast<ParticleId>(p);
  for (std::size_t r = 0; r < keyed.size(); ++r) old_of[free_slots[r]] = keyed[r].second;
  for (std::size_t p = 0; p < n; ++p) new_of[old_of[p]] = static_cast<ParticleId>(p);

  for (auto* array : {&position_, &velocity_, &angular_velocity_, &force_, &torque_,
                      &predicted_velocity_, &predicted_angular_velocity_})
    permute(*array, old_of);
  for (auto* array : {&radius_, &mass_, &inv_mass_, &inv_inertia_}) permute(*array, old_of);
  permute(material_, old_of);
  permute(group_, old_of);
  if (!walls_.empty()) {
    // Only the current buffer holds contacts between steps; the other is refilled by the next.
    WallSlots& current = wall_slots_[wall_current_];
    WallSlots permuted;
    permuted.resize(n);
    for (std::size_t p = 0; p < n; ++p) {
      permuted.count[p] = current.count[old_of[p]];
      std::copy_n(current.of(old_of[p]), kMaxWallContactsPerParticle, permuted.of(p));
    }
    current = std::move(permuted);
  }

  // The pairs in force, renumbered, with their histories and forces, sorted for the rebuild.
  std::vector<TouchingSlot> carried = touching_pairs();
  for (TouchingSlot& c : carried) {
    c.pair = {new_of[c.pair.i], new_of[c.pair.j]};
    if (c.pair.i > c.pair.j) {
      // The spring and the force are those of the first particle against the second.
      std::swap(c.pair.i, c.pair.j);
      contact_history_[c.slot].spring = -contact_history_[c.slot].spring;
      contact_force_[c.slot].force = -contact_force_[c.slot].force;
    }
  }
  std::sort(carried.begin(), carried.end(), [](const TouchingSlot& a, const TouchingSlot& b) {
    return a.pair.i != b.pair.i ? a.pair.i < b.pair.i : a.pair.j < b.pair.j;
  });
  rebuild_with_touching(carried);
  return old_of;
}

// The contact law of the candidate pairs that touch (they have a contact slot), with every array
// it reads or writes held in a local pointer (the member vectors' addresses are read once per
// task, not once per contact).
struct System::PairContactKernel {
  explicit PairContactKernel(System& s, double step_dt)
      : system(s),
        images(s.domain_),
        pair(s.neighbors_.pairs().data()),
        radius(s.radius_.data()),
        position(s.position_.data()),
        predicted_velocity(s.predicted_velocity_.data()),
        predicted_angular_velocity(s.predicted_angular_velocity_.data()),
        step_velocity(s.velocity_.data()),
        step_angular_velocity(s.angular_velocity_.data()),
        material(s.material_.data()),
        params(&s.materials_.pair(0, 0)),
        material_count(s.materials_.size()),
        slot_of(s.pair_slot_.data()),
        history_of(s.contact_history_.data()),
        force_of(s.contact_force_.data()),
        touching_flag(s.pair_touching_.data()),
        first_shift(s.particle_first_shift_.data()),
        second_slot(s.pair_second_slot_.data()),
        first_in_force(s.first_in_force_.data()),
        second_in_force(s.second_in_force_.data()),
        force_state(s.particle_force_state_.data()),
        time(s.time_),
        dt(step_dt) {}

  // The flags of pair k (particles i, j) in force. Each slot belongs to one pair: no other task
  // writes it; another task may mark the same particle: both store kPairInForce, so the order
  // does not matter.
  [[gnu::always_inline]] void mark_in_force(std::size_t k, ParticleId i, ParticleId j) const {
    first_in_force[k + first_shift[i]] = 1;
    second_in_force[second_slot[k]] = 1;
    std::atomic_ref<std::uint8_t>(force_state[i]).store(kPairInForce, std::memory_order_relaxed);
    std::atomic_ref<std::uint8_t>(force_state[j]).store(kPairInForce, std::memory_order_relaxed);
  }

  [[gnu::always_inline]] void operator()(const TouchingPair& touching) const {
    using V = ContactVec3;
    const std::size_t k = touching.k;
    const auto [i, j] = pair[k];
    const double reach = radius[i] + radius[j];
    const double distance = touching.distance;
    const V normal =
        load_contact_vec3(touching.separation) * (-1.0 / distance);  // from j towards i
    const double overlap = reach - distance;
    const double lever_i = radius[i] - 0.5 * overlap, lever_j = radius[j] - 0.5 * overlap;
    const V arm_i = -lever_i * normal;  // the contact point from i's centre (j's: lever_j n)
    // Zero but across the Lees-Edwards boundary (built in registers, not read back from memory).
    const V image_velocity =
        touching.gradient_images == 0.0
            ? V(V::Zero())
            : V(load_contact_vec3(images.image_velocity(touching.gradient_images)));
    // Contact point i minus contact point j: the two spins' parts w_i x (-lever_i n) -
    // w_j x (lever_j n) are one cross product, n x (lever_i w_i + lever_j w_j).
    const auto relative_velocity = [&](const Vec3* v, const Vec3* w) -> V {
      return load_contact_vec3(v[i]) - load_contact_vec3(v[j]) - image_velocity +
             normal.cross(lever_i * load_contact_vec3(w[i]) + lever_j * load_contact_vec3(w[j]));
    };
    const ContactGeometryOf<V> geometry{
        normal, overlap, relative_velocity(predicted_velocity, predicted_angular_velocity),
        relative_velocity(step_velocity, step_angular_velocity)};
    const std::uint32_t slot = slot_of[k];
    ContactHistory& history = history_of[slot];
    if (!touching_flag[k]) [[unlikely]] {  // the contact starts
      touching_flag[k] = 1;
      history.start_time = time;
      history.normal_damping = system.pair_normal_damping(i, j);
      const double v_n = geometry.relative_velocity.dot(normal);
      history.impact_speed = std::max(-v_n, 0.0);
      history.impact_energy = 0.5 * system.pair_effective_mass(i, j) * v_n * v_n;
    }
    const ContactResponseOf<V> response = linear_spring_dashpot_damped(
        params[material[i] * material_count + material[j]], history.normal_damping, geometry,
        load_contact_vec3(history.spring), dt);
    store_contact_vec3(history.spring, response.spring);
    history.elastic_energy = response.elastic_energy;
    history.dissipated += Dissipation{response.dissipated_normal, response.dissipated_tangential,
                                      response.dissipated_friction};
    store_contact_vec3(history.point, load_contact_vec3(position[i]) + arm_i);
    mark_in_force(k, i, j);
    ContactForce& out = force_of[slot];
    store_contact_vec3(out.force, response.force_on_a);
    out.branch = touching.separation;
    // arm_i x F and arm_j x (-F) are both multiples of F x n.
    const V turning = response.force_on_a.cross(normal);
    store_contact_vec3(out.torque_a, lever_i * turning);
    store_contact_vec3(out.torque_b, lever_j * turning);
  }

#if defined(__AVX2__)
  // Four contacts in force, one per lane (dem/contact_lanes.hpp): the same operations as above
  // on each, so each gets the bits it gets alone. Contacts that start go one at a time, above.
  [[gnu::always_inline]] void operator()(const TouchingPair* const* four) const {
    using V = Vec3Lanes;
    using S = Lanes4;
    // Lane l's number or vector is *at[l].
    const auto lanes = [](const auto& at) { return S::of(*at[0], *at[1], *at[2], *at[3]); };
    const auto vectors = [](const auto& at) { return V::gather(*at[0], *at[1], *at[2], *at[3]); };
    const auto scatter = [](const V& v, const auto& at) {
      v.scatter(*at[0], *at[1], *at[2], *at[3]);
    };
    const auto member = [](const auto& of, auto field) {
      return std::array{&(of[0]->*field), &(of[1]->*field), &(of[2]->*field), &(of[3]->*field)};
    };
    std::array<NeighborPair, kContactLanes> ij;
    std::array<ContactHistory*, kContactLanes> history;
    std::array<ContactForce*, kContactLanes> out;
    for (std::size_t l = 0; l < kContactLanes; ++l) {
      ij[l] = pair[four[l]->k];
      history[l] = &history_of[slot_of[four[l]->k]];
      out[l] = &force_of[slot_of[four[l]->k]];
    }
    const auto of_i = [&](const auto* array) {
      return std::array{&array[ij[0].i], &array[ij[1].i], &array[ij[2].i], &array[ij[3].i]};
    };
    const auto of_j = [&](const auto* array) {
      return std::array{&array[ij[0].j], &array[ij[1].j], &array[ij[2].j], &array[ij[3].j]};
    };
    const S radius_i = lanes(of_i(radius)), radius_j = lanes(of_j(radius));
    const S reach = radius_i + radius_j;
    const S distance = lanes(member(four, &TouchingPair::distance));
    const V normal =
        vectors(member(four, &TouchingPair::separation)) * (-1.0 / distance);  // from j towards i
    const S overlap = reach - distance;
    const S lever_i = radius_i - 0.5 * overlap, lever_j = radius_j - 0.5 * overlap;
    const V arm_i = -lever_i * normal;
    V image_velocity = V::Zero();
    if (four[0]->gradient_images != 0.0 || four[1]->gradient_images != 0.0 ||
        four[2]->gradient_images != 0.0 || four[3]->gradient_images != 0.0) [[unlikely]] {
      const auto image = [&](int l) { return images.image_velocity(four[l]->gradient_images); };
      image_velocity = V::gather(image(0), image(1), image(2), image(3));
    }
    const auto relative_velocity = [&](const Vec3* v, const Vec3* w) -> V {
      return vectors(of_i(v)) - vectors(of_j(v)) - image_velocity +
             normal.cross(lever_i * vectors(of_i(w)) + lever_j * vectors(of_j(w)));
    };
    const ContactGeometryOf<V> geometry{
        normal, overlap, relative_velocity(predicted_velocity, predicted_angular_velocity),
        relative_velocity(step_velocity, step_angular_velocity)};
    const auto law_params = [&](int l) -> const PairParams& {
      return params[material[ij[l].i] * material_count + material[ij[l].j]];
    };
    const ContactResponseOf<V> response = linear_spring_dashpot_damped(
        gather_pair_params(law_params(0), law_params(1), law_params(2), law_params(3)),
        lanes(member(history, &ContactHistory::normal_damping)), geometry,
        vectors(member(history, &ContactHistory::spring)), dt);
    scatter(response.spring, member(history, &ContactHistory::spring));
    scatter(vectors(of_i(position)) + arm_i, member(history, &ContactHistory::point));
    scatter(response.force_on_a, member(out, &ContactForce::force));
    const V turning = response.force_on_a.cross(normal);
    scatter(lever_i * turning, member(out, &ContactForce::torque_a));
    scatter(lever_j * turning, member(out, &ContactForce::torque_b));
    const std::array<double, 4> elastic = response.elastic_energy.values(),
                                normal_loss = response.dissipated_normal.values(),
                                tangential_loss = response.dissipated_tangential.values(),
                                friction_loss = response.dissipated_friction.values();
    for (std::size_t l = 0; l < kContactLanes; ++l) {
      history[l]->elastic_energy = elastic[l];
      history[l]->dissipated += Dissipation{normal_loss[l], tangential_loss[l], friction_loss[l]};
      out[l]->branch = four[l]->separation;
      mark_in_force(four[l]->k, ij[l].i, ij[l].j);
    }
  }
#endif

  const System& system;
  const PeriodicImages images;
  const NeighborPair* const pair;
  const double* const radius;
  const Vec3* const position;
  const Vec3* const predicted_velocity;
  const Vec3* const predicted_angular_velocity;
  // The half-step velocities of the drift that moved the particles (the closing kick comes after
  // the pair pass).
  const Vec3* const step_velocity;
  const Vec3* const step_angular_velocity;
  const MaterialId* const material;
  const PairParams* const params;
  const std::size_t material_count;
  const std::uint32_t* const slot_of;
  ContactHistory* const history_of;
  ContactForce* const force_of;
  std::uint8_t* const touching_flag;
  const std::uint32_t* const first_shift;
  const std::uint32_t* const second_slot;
  std::uint8_t* const first_in_force;
  std::uint8_t* const second_in_force;
  std::uint8_t* const force_state;
  const double time;
  const double dt;
};

void System::compute_pair_forces(double dt) {
  const std::span<const NeighborPair> pairs = neighbors_.pairs();
  const bool has_groups = !groups_.empty();
  const std::array<double, 3> no_image_limit = no_image_limits();
  // The pairs in fixed chunks; each chunk queues the pairs that start touching this step (they get
  // a contact slot after the pass, in pair order: chunk by chunk) and those that stop (collected
  // after the step, in pair order too). The queues keep their capacity from step to step.
  const std::size_t chunk_count = (pairs.size() + kPairGrain - 1) / kPairGrain;
  if (queues_by_chunk_.size() < chunk_count) queues_by_chunk_.resize(chunk_count);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunk_count, 1), [&](const auto& chunks) {
    const PeriodicImages images(domain_);
    const PairContactKernel contact(*this, dt);
    // Screening first, in a tight loop over blocks of pairs: most candidate pairs are apart.
    // The touching ones of a block are queued with their separation and their contact law
    // runs after; each pair writes only its own slots, so the order does not matter.
    constexpr std::size_t kBlock = 256;
    std::array<TouchingPair, kBlock> touching;
    std::array<std::uint32_t, kBlock> finishing, awake;
    // The contacts in force of a block, four at a time through the law in lanes, the last few
    // each alone; every one alone where the lanes are off (the tests compare the two) or not built.
    std::array<const TouchingPair*, kBlock> in_force;
    std::size_t in_force_count = 0;
    [[maybe_unused]] const std::size_t lanes_group =
        contacts_in_lanes_ ? kContactLanes : kBlock + 1;
    const NeighborPair* const pair = pairs.data();
    const Vec3* const x = position_.data();
    const double* const radius = radius_.data();
    const GroupId* const group = group_.data();
    const std::uint8_t* const was_touching = pair_touching_.data();
    float* const wake = pair_wake_.data();
    const double bound = approach_bound_;
    const double sleep = pairs_may_sleep_ ? 1.0 : 0.0;
    const bool skip_wall_balls = has_groups;
    const double limit_x = no_image_limit[0], limit_y = no_image_limit[1],
                 limit_z = no_image_limit[2];
    const double image_test_sq = square(std::min({limit_x, limit_y, limit_z}));
    for (std::size_t chunk = chunks.begin(); chunk != chunks.end(); ++chunk) {
      std::vector<TouchingPair>& starting_here = queues_by_chunk_[chunk].starting;
      std::vector<std::uint32_t>& finishing_here = queues_by_chunk_[chunk].finishing;
      starting_here.clear();
      queues_by_chunk_[chunk].screened = 0;
      const std::size_t chunk_end = std::min((chunk + 1) * kPairGrain, pairs.size());
      for (std::size_t block = chunk * kPairGrain; block < chunk_end; block += kBlock) {
        const std::size_t block_end = std::min(block + kBlock, chunk_end);
        // The pairs of the block that may touch by now (the others sleep: their gap cannot have
        // closed yet).
        const std::size_t awake_count =
            collect_awake_pairs(wake, bound, block, block_end, awake.data());
        const std::size_t last_awake = awake_count - 1;
        queues_by_chunk_[chunk].screened += awake_count;
        // The loop twice, with and without the kinematic groups' test (the compiler keeps the
        // test in the loop otherwise).
        const auto screen = [&](auto skip_wall_balls) {
          std::size_t touching_count = 0, finishing_count = 0;
          for (std::size_t a = 0; a != awake_count; ++a) {
            const std::size_t k = awake[a];
            const auto [i, j] = pair[k];
            // A hint, which changes no result: pairs come in rows, so x[i] is mostly in the cache
            // already and x[j] is what the pass would wait for.
            __builtin_prefetch(&x[pair[awake[std::min(a + kScreeningLookahead, last_awake)]].j]);
            if (skip_wall_balls() && group[i] != kFreeParticle && group[j] != kFreeParticle)
              continue;  // two wall balls never interact
            Vec3 d = x[j] - x[i];
            double gradient_images = 0.0;
            double distance_sq = d.squaredNorm();
            // Below the smallest limit squared, no component can reach its limit: most pairs
            // skip the test of each axis.
            if (!(distance_sq < image_test_sq) &&
                !(std::abs(d[0]) < limit_x && std::abs(d[1]) < limit_y &&
                  std::abs(d[2]) < limit_z)) {
              d = images.separation(x[i], x[j], gradient_images);
              distance_sq = d.squaredNorm();
            }
            const double reach = radius[i] + radius[j];
            // Without a branch: in a dense cell whether a pair touches is close to a coin toss,
            // which the predictor misses about a third of the time. Every pair writes the next
            // slot of both queues; only those that belong there are counted (docs/benchmarks.md,
            // "Branch-free screening").
            const bool touches = distance_sq < reach * reach;
            const double distance = std::sqrt(distance_sq);
            touching[touching_count] =
                TouchingPair{d, distance, gradient_images, static_cast<std::uint32_t>(k)};
            touching_count += touches;
            // Apart now: collect_finished_contacts() records the event and clears the history.
            finishing[finishing_count] = static_cast<std::uint32_t>(k);
            finishing_count += !touches & (was_touching[k] != 0);
            // Apart by a gap g: it sleeps until the approach bound has grown by g (a margin
            // for rounding; a float's rounding taken off too, so that it never wakes late).
            const double gap = distance - reach * (1.0 + 1e-9);
            wake[k] = touches ? 0.0f : static_cast<float>((bound + sleep * gap) * (1.0 - 1e-6));
          }
          return std::pair{touching_count, finishing_count};
        };
        const auto [touching_count, finishing_count] =
            skip_wall_balls ? screen(std::true_type{}) : screen(std::false_type{});
        finishing_here.insert(finishing_here.end(), finishing.begin(),
                              finishing.begin() + static_cast<std::ptrdiff_t>(finishing_count));
        for (std::size_t t = 0; t < touching_count; ++t) {
          if (t + kContactLookahead < touching_count) {
            const ParticleId ahead = pair[touching[t + kContactLookahead].k].j;
            __builtin_prefetch(&contact.predicted_velocity[ahead]);
            __builtin_prefetch(&contact.predicted_angular_velocity[ahead]);
            __builtin_prefetch(&contact.step_velocity[ahead]);
            __builtin_prefetch(&contact.step_angular_velocity[ahead]);
          }
          if (!was_touching[touching[t].k]) {
            starting_here.push_back(touching[t]);  // no contact slot yet
            continue;
          }
          in_force[in_force_count++] = &touching[t];
#if defined(__AVX2__)
          if (in_force_count == lanes_group) {
            contact(in_force.data());
            in_force_count = 0;
          }
#endif
        }
        for (std::size_t r = 0; r < in_force_count; ++r) contact(*in_force[r]);
        in_force_count = 0;
      }
    }
  });
  // New contacts: slots handed out in pair order (the store's layout does not change a result:
  // every sum runs in pair order), then their contact law, each writing only its own slots.
  starting_.clear();
  for (std::size_t chunk = 0; chunk < chunk_count; ++chunk) {
    const std::vector<TouchingPair>& here = queues_by_chunk_[chunk].starting;
    starting_.insert(starting_.end(), here.begin(), here.end());
    pairs_screened_ += queues_by_chunk_[chunk].screened;
  }
  if (starting_.empty()) return;
  for (const TouchingPair& t : starting_) {
    pair_slot_[t.k] = allocate_contact();
    second_contact_slot_[pair_second_slot_[t.k]] = pair_slot_[t.k];
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, starting_.size(), kParticleGrain),
                    [&](const auto& range) {
                      const PairContactKernel contact(*this, dt);
                      for (std::size_t t = range.begin(); t != range.end(); ++t)
                        contact(starting_[t]);
                    });
}

double System::pair_effective_mass(ParticleId i, ParticleId j) const {
  const bool free_i = is_free(i), free_j = is_free(j);
  return free_i && free_j ? effective_mass(mass_[i], mass_[j]) : (free_i ? mass_[i] : mass_[j]);
}

double System::pair_normal_damping(ParticleId i, ParticleId j) const {
  const PairParams& params = materials_.pair(material_[i], material_[j]);
  return normal_damping_coefficient(params.normal_stiffness, pair_effective_mass(i, j),
                                    params.damping_ratio);
}

namespace {

// Calls add(slot) for the slots of [begin, end) in force, in order, 8 in-force bytes at a time
// (each 0 or 1), clearing them as read. Inlined by force, like the callers' add: this file is at
// GCC's inlining limit, and the force gather runs it twice per particle and step.
template <class Add>
[[gnu::always_inline]] inline void for_each_in_force(std::uint8_t* in_force, std::uint32_t begin,
                                                     std::uint32_t end, Add&& add) {
  for (std::uint32_t base = begin; base < end; base += 8) {
    std::uint64_t word;
    std::memcpy(&word, in_force + base, sizeof word);
    if (word == 0) continue;
    std::memset(in_force + base, 0, sizeof word);
    for (; word != 0; word &= word - 1) add(base + (std::countr_zero(word) >> 3));
  }
}

}  // namespace

void System::compute_particle_forces(double dt, bool closing_kick) {
  const double half_dt = 0.5 * dt_;
  const DriftArrays particles = drift_arrays();
  const WallSlots& before = wall_slots_[wall_current_];
  WallSlots& after = wall_slots_[1 - wall_current_];
  std::vector<WallPose> poses;
  for (const Wall& wall : walls_) poses.push_back(wall_pose(wall));
  // The virial is summed per particle over the pairs it is first of (in pair order, so the sum
  // does not depend on which candidates the neighbour list holds), then over blocks of particles
  // joined in a fixed order: the same bits at any thread count, and across a checkpoint.
  contact_virial_ = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, size(), kParticleGrain), Eigen::Matrix3d::Zero().eval(),
      [&](const tbb::blocked_range<std::size_t>& range,
          const Eigen::Matrix3d& virial_before) -> Eigen::Matrix3d {
        // A local sum, which the stores below to the particle arrays cannot alias, in three
        // columns: the compiler keeps a column in registers (a whole matrix it keeps in memory,
        // loaded and stored for every contact). virial.col(c) += F b_c is what Eigen's outer
        // product does, element by element: the same bits.
        using V = ContactVec3;
        V virial_x = load_contact_vec3(virial_before.col(0)),
          virial_y = load_contact_vec3(virial_before.col(1)),
          virial_z = load_contact_vec3(virial_before.col(2));
        const auto virial = [&] {
          Vec3 x, y, z;
          store_contact_vec3(x, virial_x);
          store_contact_vec3(y, virial_y);
          store_contact_vec3(z, virial_z);
          Eigen::Matrix3d sum;
          sum << x, y, z;
          return sum;
        };
        const bool free_of_groups = groups_.empty();
        const Vec3 gravity = gravity_;
        const double* const mass = mass_.data();
        const std::uint32_t* const second_offset = second_offset_.data();
        const std::uint32_t* const second_contact_slot = second_contact_slot_.data();
        const std::uint32_t* const first_offset = first_offset_.data();
        const std::uint32_t* const first_shift = particle_first_shift_.data();
        std::uint8_t* const second_in_force = second_in_force_.data();
        std::uint8_t* const first_in_force = first_in_force_.data();
        const std::uint32_t* const slot_of = pair_slot_.data();
        const ContactForce* const contact = contact_force_.data();
        std::uint8_t* const force_state = particle_force_state_.data();
        // Gravity plus the pairs in force on p, in pair order: those p is second of, then its row.
        struct ForceAndTorque {
          V force, torque;
        };
        const V packed_gravity = load_contact_vec3(gravity);
        const auto pair_sum = [&](std::size_t p) __attribute__((always_inline)) {
          ForceAndTorque sum{free_of_groups || is_free(p) ? V(mass[p] * packed_gravity) : V::Zero(),
                             V::Zero()};
          if (force_state[p] != kPairInForce) return sum;  // no pair in force: nothing to add
          for_each_in_force(
              second_in_force, second_offset[p],
              second_offset[p + 1], [&](std::uint32_t s) __attribute__((always_inline)) {
                const ContactForce& c = contact[second_contact_slot[s]];
                sum.force -= load_contact_vec3(c.force);
                sum.torque += load_contact_vec3(c.torque_b);
              });
          const std::uint32_t shift = first_shift[p];
          for_each_in_force(
              first_in_force, first_offset[p],
              first_offset[p + 1], [&](std::uint32_t s) __attribute__((always_inline)) {
                const ContactForce& c = contact[slot_of[s - shift]];
                const V force = load_contact_vec3(c.force);
                sum.force += force;
                sum.torque += load_contact_vec3(c.torque_a);
                virial_x += force * c.branch[0];
                virial_y += force * c.branch[1];
                virial_z += force * c.branch[2];
              });
          return sum;
        };
        // The sums; then, over the chunk, the closing half kick from them (on four lanes,
        // dem/drift.hpp), while the chunk's forces are still in the cache.
        Vec3* const force_of = force_.data();
        Vec3* const torque_of = torque_.data();
        const auto store = [&](std::size_t p, const auto& force, const auto& torque) {
          store_contact_vec3(force_of[p], force);
          store_contact_vec3(torque_of[p], torque);
          force_state[p] = kForceSummed;
        };
        const auto kick = [&] {
          if (closing_kick) kick_particles(particles, half_dt, range.begin(), range.end());
        };
        if (walls_.empty()) {  // a loop of its own: without the wall code it keeps its values in
                               // registers
          if (free_of_groups) {
            // The sums of the particles with a pair in force, and the weight of those whose
            // pairs all left force; the rest (in a sparse cell, most) hold their weight already.
            for (std::size_t p = range.begin(); p != range.end(); ++p) {
              if (force_state[p] == kWeightOnly) {  // and the next eight, while they are too
                while (p + 9 <= range.end() && all_weight_only<8>(force_state + p + 1)) p += 8;
                continue;
              }
              if (force_state[p] == kPairInForce) {
                const auto [force, torque] = pair_sum(p);
                store(p, force, torque);
              } else {
                store(p, V(mass[p] * packed_gravity), V::Zero());
                force_state[p] = kWeightOnly;
              }
            }
          } else {
            for (std::size_t p = range.begin(); p != range.end(); ++p) {
              const auto [force, torque] = pair_sum(p);
              store(p, force, torque);
            }
          }
          kick();
          return virial();
        }
        std::vector<SurfaceContact> surface;  // reused for every particle of this chunk
        // Copies, held in registers (the byte stores below may alias any member).
        const Wall* const walls = walls_.data();
        const std::size_t wall_count = walls_.size();
        const Vec3* const position = position_.data();
        const double* const radius = radius_.data();
        const std::uint8_t* const old_count_of = before.count.data();
        std::uint8_t* const count_of = after.count.data();
        std::uint8_t* const finished_mask = finished_wall_mask_.data();
        // Off every wall last step and clear of each by its cheap test now: most of a mill's
        // charge, which needs no more than its count of wall contacts set to 0.
        const auto off_the_walls = [&](std::size_t p) {
          if (old_count_of[p] != 0) return false;
          for (std::size_t w = 0; w < wall_count; ++w) {
            if (!sphere_certainly_clear_of(walls[w], position[p], radius[p])) return false;
          }
          return true;
        };
        for (std::size_t p = range.begin(); p != range.end(); ++p) {
          const auto [pairs_force, pairs_torque] = pair_sum(p);
          Vec3 force, torque;
          store_contact_vec3(force, pairs_force);
          store_contact_vec3(torque, pairs_torque);
          if (!is_free(p)) {  // no wall slots in use, in either buffer
            store(p, force, torque);
            continue;
          }
          if (off_the_walls(p)) {
            count_of[p] = 0;
            finished_mask[p] = 0;
            store(p, force, torque);
            continue;
          }
          const int old_count = old_count_of[p];
          const WallContactHistory* old_slots = before.of(p);
          WallContactHistory* slots = after.of(p);
          std::uint8_t matched = 0;
          int count = 0;
          for (std::size_t w = 0; w < wall_count; ++w) {
            surface.clear();
            wall_contacts(walls[w], poses[w], position[p], radius[p], surface);
            for (const SurfaceContact& contact : surface) {
              if (count == kMaxWallContactsPerParticle) {
                throw std::runtime_error(fmt::format(
                    "particle {} touches more than {} wall features at once at t = {} s", p,
                    kMaxWallContactsPerParticle, time_));
              }
              WallContactHistory& slot = slots[count++];
              slot.wall = static_cast<std::int32_t>(w);
              slot.feature = contact.feature;
              slot.history = ContactHistory{};
              bool continues = false;
              for (int o = 0; o < old_count; ++o) {
                if (!(matched & (1u << o)) && old_slots[o].wall == slot.wall &&
                    old_slots[o].feature == slot.feature) {
                  slot.history = old_slots[o].history;
                  matched |= static_cast<std::uint8_t>(1u << o);
                  continues = true;
                  break;
                }
              }
              const Vec3 arm = -(radius[p] - 0.5 * contact.overlap) * contact.normal;
              const Vec3 surface_velocity = wall_surface_velocity(walls[w], contact.point);
              const Vec3 relative_velocity = predicted_velocity_[p] +
                                             predicted_angular_velocity_[p].cross(arm) -
                                             surface_velocity;
              const ContactGeometry geometry{
                  contact.normal, contact.overlap, relative_velocity,
                  velocity_[p] + angular_velocity_[p].cross(arm) - surface_velocity};
              const ContactResponse response =
                  linear_spring_dashpot(materials_.pair(material_[p], walls[w].material), mass_[p],
                                        geometry, slot.history.spring, dt);
              ContactHistory& history = slot.history;
              if (!continues) {
                history.start_time = time_;
                const double v_n = relative_velocity.dot(contact.normal);
                history.impact_speed = std::max(-v_n, 0.0);
                history.impact_energy = 0.5 * mass_[p] * v_n * v_n;
              }
              history.spring = response.spring;
              history.elastic_energy = response.elastic_energy;
              history.dissipated +=
                  Dissipation{response.dissipated_normal, response.dissipated_tangential,
                              response.dissipated_friction};
              history.point = contact.point;
              slot.force_on_particle = response.force_on_a;
              force += response.force_on_a;
              torque += arm.cross(response.force_on_a);
            }
          }
          count_of[p] = static_cast<std::uint8_t>(count);
          finished_mask[p] = static_cast<std::uint8_t>(~matched & ((1u << old_count) - 1u));
          store(p, force, torque);
        }
        kick();
        return virial();
      },
      [](const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) -> Eigen::Matrix3d { return a + b; });
  wall_current_ = 1 - wall_current_;
}

void System::reduce_loads(double dt) {
  const std::size_t wall_n = walls_.size(), load_n = wall_n + groups_.size();
  if (load_n == 0) return;
  using Loads = std::vector<WallLoad>;
  const WallSlots& current = current_wall_slots();
  const Loads totals = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, size(), kReduceGrain), Loads(load_n),
      [&](const tbb::blocked_range<std::size_t>& range, Loads loads) {
        for (std::size_t p = range.begin(); p != range.end(); ++p) {
          if (!is_free(p)) {
            // force_[p] is what the free particles do to this wall ball.
            WallLoad& load = loads[wall_n + group_[p] - 1];
            load.force += force_[p];
            load.torque += position_[p].cross(force_[p]);
            continue;
          }
          if (wall_n == 0) continue;
          const WallContactHistory* slots = current.of(p);
          for (int s = 0; s < current.count[p]; ++s) {
            const WallContactHistory& slot = slots[s];
            WallLoad& load = loads[slot.wall];
            load.force -= slot.force_on_particle;
            load.torque += slot.history.point.cross(-slot.force_on_particle);
          }
        }
        return loads;
      },
      [](Loads a, const Loads& b) {
        for (std::size_t l = 0; l < a.size(); ++l) {
          a[l].force += b[l].force;
          a[l].torque += b[l].torque;
        }
        return a;
      });
  // Work by the trapezoidal rule over the step, both ends at the velocity the wall moved with
  // during this step (a servo may have changed it since the last step).
  auto store = [dt](WallLoad& load, const WallLoad& now, auto power_of) {
    const double power = power_of(now);
    load.work += 0.5 * (power_of(load) + power) * dt;
    load.force = now.force;
    load.torque = now.torque;
    load.power = power;
  };
  for (std::size_t w = 0; w < wall_n; ++w) {
    store(wall_loads_[w], totals[w],
          [&](const WallLoad& load) { return wall_power(walls_[w], load); });
  }
  for (std::size_t g = 0; g < groups_.size(); ++g) {
    const Vec3& velocity = groups_[g].velocity;
    store(group_loads_[g], totals[wall_n + g],
          [&](const WallLoad& load) { return -load.force.dot(velocity); });
  }
}

void System::collect_finished_contacts() {
  auto finish = [&](ContactHistory& history, std::uint32_t category, ParticleId a, std::uint32_t b,
                    bool with_wall, double tangential_stiffness) {
    // A contact that lets go while its tangential spring is still loaded (pulled apart within a
    // step, e.g. by a barostat's stretch) loses that spring's energy: friction's share.
    history.dissipated.friction += 0.5 * tangential_stiffness * history.spring.squaredNorm();
    finished_dissipation_[category] += history.dissipated;
    if (record_collisions_) {
      record_collision(CollisionEvent{.category = category,
                                      .a = a,
                                      .b = b,
                                      .with_wall = with_wall,
                                      .start_time = history.start_time,
                                      .duration = time_ - history.start_time,
                                      .impact_speed = history.impact_speed,
                                      .impact_energy = history.impact_energy,
                                      .dissipated = history.dissipated.total(),
                                      .point = history.point});
    }
    history = ContactHistory{};
  };
  const auto& pairs = neighbors_.pairs();
  for (ChunkQueues& queues : queues_by_chunk_) {  // in chunk order: in pair order
    for (const std::uint32_t k : queues.finishing) {
      const auto [i, j] = pairs[k];
      finish(contact_history_[pair_slot_[k]], pair_category(material_[i], material_[j]), i, j,
             false, materials_.pair(material_[i], material_[j]).tangential_stiffness);
      free_contact_slots_.push_back(pair_slot_[k]);
      pair_slot_[k] = kNoContact;
      pair_touching_[k] = 0;
    }
    queues.finishing.clear();
  }
  if (walls_.empty()) return;
  WallSlots& previous = wall_slots_[1 - wall_current_];
  for_each_nonzero(finished_wall_mask_, [&](std::size_t p) {
    WallContactHistory* slots = previous.of(p);
    for (int s = 0; s < kMaxWallContactsPerParticle; ++s) {
      if (!(finished_wall_mask_[p] & (1u << s))) continue;
      finish(slots[s].history, wall_category(slots[s].wall, material_[p]),
             static_cast<ParticleId>(p), static_cast<std::uint32_t>(slots[s].wall), true,
             materials_.pair(material_[p], walls_[static_cast<std::size_t>(slots[s].wall)].material)
                 .tangential_stiffness);
    }
    finished_wall_mask_[p] = 0;
  });
}

std::size_t System::active_contact_count() const {
  std::size_t count = 0;
  for (const std::uint8_t touching : pair_touching_) count += touching;
  for (std::size_t p = 0; p < size(); ++p) count += wall_contact_count(p);
  return count;
}

std::vector<ActiveContact> System::active_contacts() const {
  std::vector<ActiveContact> contacts;
  const auto& pairs = neighbors_.pairs();
  for (std::size_t k = 0; k < pair_touching_.size(); ++k) {
    if (!pair_touching_[k]) continue;
    const auto [i, j] = pairs[k];
    contacts.push_back(ActiveContact{.a = i,
                                     .b = j,
                                     .with_wall = false,
                                     .point = pair_history(k).point,
                                     .force_on_a = pair_force(k),
                                     .branch = domain_.separation(position_[i], position_[j])});
  }
  for (std::size_t p = 0; p < size(); ++p) {
    for (int s = 0; s < wall_contact_count(p); ++s) {
      const WallContactHistory* slots = current_wall_slots().of(p);
      contacts.push_back(ActiveContact{.a = static_cast<ParticleId>(p),
                                       .b = static_cast<std::uint32_t>(slots[s].wall),
                                       .with_wall = true,
                                       .point = slots[s].history.point,
                                       .force_on_a = slots[s].force_on_particle,
                                       .branch = slots[s].history.point - position_[p]});
    }
  }
  return contacts;
}

std::vector<Dissipation> System::dissipation_by_category() const {
  std::vector<Dissipation> total = finished_dissipation_;
  const auto& pairs = neighbors_.pairs();
  for (std::size_t k = 0; k < pair_touching_.size() && k < pairs.size(); ++k) {
    if (pair_touching_[k]) {
      total[pair_category(material_[pairs[k].i], material_[pairs[k].j])] +=
          pair_history(k).dissipated;
    }
  }
  for (std::size_t p = 0; p < size(); ++p) {
    for (int s = 0; s < wall_contact_count(p); ++s) {
      const WallContactHistory* slots = current_wall_slots().of(p);
      total[wall_category(slots[s].wall, material_[p])] += slots[s].history.dissipated;
    }
  }
  return total;
}

EnergyBudget System::energy() const {
  EnergyBudget budget;
  for (std::size_t p = 0; p < size(); ++p) {
    if (!is_free(p)) continue;
    const double inertia = 0.4 * mass_[p] * radius_[p] * radius_[p];
    budget.kinetic += 0.5 * mass_[p] * velocity_[p].squaredNorm() +
                      0.5 * inertia * angular_velocity_[p].squaredNorm();
    budget.potential -= mass_[p] * gravity_.dot(position_[p]);
  }
  for (std::size_t k = 0; k < pair_touching_.size(); ++k) {
    if (pair_touching_[k]) budget.elastic += pair_history(k).elastic_energy;
  }
  for (std::size_t p = 0; p < size(); ++p) {
    for (int s = 0; s < wall_contact_count(p); ++s)
      budget.elastic += current_wall_slots().of(p)[s].history.elastic_energy;
  }
  for (const Dissipation& d : dissipation_by_category()) budget.dissipated += d.total();
  for (const WallLoad& load : wall_loads_) budget.wall_work += load.work;
  for (const WallLoad& load : group_loads_) budget.wall_work += load.work;
  return budget;
}

namespace {

template <class T>
std::size_t bytes_of(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}

}  // namespace

System::MemoryUse System::memory_use() const {
  MemoryUse use;
  use.particles = neighbors_.reference_bytes() + bytes_of(material_) + bytes_of(group_) +
                  bytes_of(second_offset_) + bytes_of(first_offset_) +
                  bytes_of(particle_first_shift_) + bytes_of(particle_force_state_);
  for (const auto* array : {&position_, &velocity_, &angular_velocity_, &force_, &torque_,
                            &predicted_velocity_, &predicted_angular_velocity_})
    use.particles += bytes_of(*array);
  for (const auto* array : {&radius_, &mass_, &inv_mass_, &inv_inertia_})
    use.particles += bytes_of(*array);
  use.candidate_pairs = neighbors_.pair_bytes() + bytes_of(pair_slot_) + bytes_of(pair_touching_) +
                        bytes_of(pair_second_slot_) + bytes_of(second_contact_slot_) +
                        bytes_of(second_in_force_) + bytes_of(first_in_force_) +
                        bytes_of(pair_wake_);
  use.contacts =
      bytes_of(contact_history_) + bytes_of(contact_force_) + bytes_of(free_contact_slots_);
  use.wall_contacts = bytes_of(finished_wall_mask_);
  for (const WallSlots& buffer : wall_slots_)
    use.wall_contacts += bytes_of(buffer.slot) + bytes_of(buffer.count);
  use.step_queues = bytes_of(queues_by_chunk_) + bytes_of(starting_);
  for (const ChunkQueues& queues : queues_by_chunk_)
    use.step_queues += bytes_of(queues.starting) + bytes_of(queues.finishing);
  use.collision_events = bytes_of(events_);
  return use;
}

}  // namespace millflow::dem
