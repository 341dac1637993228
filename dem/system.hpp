#pragma once
// A DEM system of spheres: particles, walls, kinematic groups, contact history, and the time
// integrator (velocity Verlet: half kick, drift, forces, half kick).
//
// Determinism: every parallel loop writes only its own element, and every sum runs in a fixed
// order (per-particle sums in contact order; totals with tbb::parallel_deterministic_reduce), so
// a run gives the same bits at any thread count. The caller picks the thread count by running
// step() inside a tbb::task_arena.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "dem/domain.hpp"
#include "dem/drift.hpp"
#include "dem/material.hpp"
#include "dem/neighbor_search.hpp"
#include "dem/rng.hpp"
#include "dem/vec.hpp"
#include "dem/walls.hpp"

namespace millflow::dem {

using ParticleId = std::uint32_t;
using GroupId = std::uint32_t;
inline constexpr GroupId kFreeParticle = 0;

struct ParticleSpec {
  Vec3 position = Vec3::Zero();
  Vec3 velocity = Vec3::Zero();
  Vec3 angular_velocity = Vec3::Zero();
  double radius = 0.0;
  MaterialId material = 0;
  GroupId group = kFreeParticle;  // > 0: member of a kinematic group (e.g. a rough wall)
};

// Particles of a kinematic group move rigidly with the group's velocity and do not rotate (the
// balls glued to a shear cell's rough wall). Whoever owns the group sets its velocity.
struct KinematicGroup {
  std::string name;
  Vec3 velocity = Vec3::Zero();
};

// Energy dissipated in contacts, J.
struct Dissipation {
  double normal = 0.0;      // normal dashpot
  double tangential = 0.0;  // tangential dashpot
  double friction = 0.0;    // Coulomb sliding, and the tangential spring a contact held as it ended
  double total() const { return normal + tangential + friction; }
  Dissipation& operator+=(const Dissipation& o) {
    normal += o.normal;
    tangential += o.tangential;
    friction += o.friction;
    return *this;
  }
  Dissipation& operator-=(const Dissipation& o) {
    normal -= o.normal;
    tangential -= o.tangential;
    friction -= o.friction;
    return *this;
  }
};

// One finished contact (collision): from first touch to separation.
struct CollisionEvent {
  std::uint32_t category = 0;  // see System::category_name
  ParticleId a = 0;
  std::uint32_t b = 0;  // the other particle, or the wall index for a wall contact
  bool with_wall = false;
  double start_time = 0.0;
  double duration = 0.0;
  double impact_speed = 0.0;   // normal approach speed at first touch, m/s
  double impact_energy = 0.0;  // 1/2 m_eff v_n^2 at first touch, J
  double dissipated = 0.0;     // energy this contact dissipated, J
  Vec3 point = Vec3::Zero();   // where the contact was last touching
};

// Takes each finished contact as it finishes (System::set_collision_sink): an owner that only
// tallies the contacts holds no buffer of them.
class CollisionSink {
 public:
  virtual void add(const CollisionEvent& event) = 0;

 protected:
  ~CollisionSink() = default;
};

// A contact in force now, for coarse-graining the stress.
struct ActiveContact {
  ParticleId a = 0;
  std::uint32_t b = 0;  // the other particle, or the wall index
  bool with_wall = false;
  Vec3 point = Vec3::Zero();       // contact point
  Vec3 force_on_a = Vec3::Zero();  // b (or the wall) pushes a with this force
  Vec3 branch = Vec3::Zero();      // from a's centre to b's centre (minimum image); for a wall,
                                   // from a's centre to the contact point
};

// The energy budget. For a closed system:
//   wall_work = (kinetic + potential + elastic) - (same at start) + dissipated.
struct EnergyBudget {
  double kinetic = 0.0;    // translational + rotational of free particles
  double potential = 0.0;  // gravitational, -m g.x of free particles
  double elastic = 0.0;    // stored in active contact springs
  double dissipated = 0.0;
  double wall_work = 0.0;  // work done on the particles by walls and kinematic groups
  double mechanical() const { return kinetic + potential + elastic; }
};

// The contact history of one particle pair (or particle-wall contact), kept while touching: a
// history exists only for a contact in force (whether a pair's contact is new this step is its
// pair's touching flag, a wall contact's match with the last step's).
struct ContactHistory {
  Vec3 spring = Vec3::Zero();
  double start_time = 0.0;
  double impact_speed = 0.0;
  double impact_energy = 0.0;
  double elastic_energy = 0.0;
  Dissipation dissipated;
  Vec3 point = Vec3::Zero();  // contact point at the last step in force
  // C_n of the normal dashpot (normal_damping_coefficient of the pair's effective mass), set at
  // first touch. Derived: checkpoints do not hold it, loading works it out again.
  double normal_damping = 0.0;
};

struct WallContactHistory {
  ContactHistory history;  // its point is this step's contact point
  std::int32_t wall = -1;
  std::int32_t feature = 0;
  Vec3 force_on_particle = Vec3::Zero();  // this step
};

inline constexpr int kMaxWallContactsPerParticle = 4;

class System {
 public:
  System(MaterialTable materials, Domain domain, Vec3 gravity);

  // Adding things. Each throws std::invalid_argument naming the bad value.
  ParticleId add_particle(const ParticleSpec& spec);
  GroupId add_group(const KinematicGroup& group);
  std::size_t add_wall(const Wall& wall);

  // Time step. The smallest contact duration over the material pairs present (lightest particles
  // of each material, walls as infinitely heavy) sets dt = t_c / steps_per_collision; the derived
  // values are logged. set_time_step refuses a dt above the stability limit.
  double min_collision_duration() const;
  double stable_time_step() const;
  void set_time_step_from_collisions(int steps_per_collision = 20);
  void set_time_step(double dt);
  double time_step() const { return dt_; }

  // Neighbour-list skin, m (default: 0.3 x smallest diameter, set on the first step). A system
  // already stepping rebuilds its list and keeps its state. No result's bits depend on the skin
  // (forces are summed over the touching pairs in (i, j) order, and reorder_particles' cells are
  // those of the default skin), only the time a step takes.
  void set_neighbor_skin(double skin);
  double neighbor_skin() const { return skin_; }
  // Neighbour rebuilds the skin test asked for since the first step (not those of a new skin or a
  // renumbering).
  std::uint64_t neighbor_rebuild_count() const { return rebuild_count_; }
  // Lays the contact store out in pair order again, in place, as a neighbour rebuild does. Between
  // rebuilds a contact that starts takes the slot of one that finished, anywhere in the store, so
  // a cell whose contacts come and go (a sparse one: at the stiffness policy's contacts the list
  // may go thousands of steps unbuilt) reads its contacts from all over memory; a step calls this
  // once contacts placed since the store was last in order exceed half of those in force and a
  // 256th of the candidate pairs (so that in a cell of few contacts the pass over the pairs stays
  // a small part of the steps). Moves no result (every sum runs in pair order), only the time a
  // step takes (docs/benchmarks.md, "The contact store kept in pair order").
  void compact_contacts();
  std::uint64_t contact_compaction_count() const { return compaction_count_; }
  // What the rebuild test compares with the skin now: 2 x the largest displacement since the
  // list's last build + the Lees-Edwards offset's change (0 before a build). The list is rebuilt
  // once it reaches the skin, so travel / skin is the part of the list's life already used.
  double neighbor_travel() const;
  // Throws if two particles overlap by more than `tolerance` x the smaller radius, naming them.
  void check_overlaps(double tolerance) const;

  void step(std::size_t count = 1);

  // Renumbers the free particles in the order of their cells along a Z-order (Morton) curve:
  // cells of the finest neighbour-list level at the default skin (2 x smallest radius + 0.3 x
  // smallest diameter, whatever the skin), in the box from its lower corner; ties by the current
  // index. Members of kinematic groups keep their indices (a
  // caller may know where they are); the free particles take the remaining indices in that
  // order. Contact histories go with their pairs (a pair whose particles swap order has its
  // tangential spring and force negated, exactly), and the neighbour list is rebuilt. Particles
  // that touch then sit close in memory, which makes the contact and force passes several times
  // faster on a large shuffled system. Results are the same physics with the per-particle force
  // sums taken in another order. Returns, per new index, the old one. Collision events already
  // recorded keep the old numbers.
  std::vector<ParticleId> reorder_particles();
  // Calls reorder_particles() before every step whose step count is a multiple of `steps` (0:
  // never, the default). A fixed step count, not the neighbour rebuilds, decides, so a run
  // continued from a checkpoint (which keeps this setting) renumbers at the same steps.
  void set_reorder_interval(std::uint64_t steps) { reorder_every_ = steps; }
  std::uint64_t reorder_interval() const { return reorder_every_; }

  // Stretches the box and every particle affinely along a periodic axis by `factor` about the
  // box's lower face (x_a -> lo_a + factor (x_a - lo_a)), the homogeneous strain of a barostat.
  // Velocities are left alone, except that a Lees-Edwards image velocity scales with the length
  // of its gradient axis (the shear rate stays). The neighbour list is kept: the stretch counts
  // as displacement, and a pair's separation changes by at most (factor - 1) times itself, never
  // more than twice the largest displacement, so the usual skin test decides the rebuild. The
  // contact virial's column `axis` scales by `factor` (every branch vector's component does).
  // Throws std::invalid_argument for a non-periodic axis, kinematic particles, or a factor that
  // is not positive and finite.
  void deform_affinely(int axis, double factor);

  // State.
  std::size_t size() const { return position_.size(); }
  double time() const { return time_; }
  std::uint64_t step_count() const { return step_count_; }
  const MaterialTable& materials() const { return materials_; }
  const Domain& domain() const { return domain_; }
  Domain& domain() { return domain_; }
  const Vec3& gravity() const { return gravity_; }
  std::span<const Vec3> positions() const { return position_; }
  std::span<const Vec3> velocities() const { return velocity_; }
  std::span<const Vec3> angular_velocities() const { return angular_velocity_; }
  std::span<const Vec3> forces() const { return force_; }
  std::span<const double> radii() const { return radius_; }
  std::span<const double> masses() const { return mass_; }
  std::span<const MaterialId> particle_materials() const { return material_; }
  std::span<const GroupId> particle_groups() const { return group_; }
  void set_velocity(ParticleId id, const Vec3& v) { velocity_.at(id) = v; }
  void set_angular_velocity(ParticleId id, const Vec3& w) { angular_velocity_.at(id) = w; }

  std::size_t wall_count() const { return walls_.size(); }
  const Wall& wall(std::size_t i) const { return walls_.at(i); }
  Wall& wall(std::size_t i) { return walls_.at(i); }
  const WallLoad& wall_load(std::size_t i) const { return wall_loads_.at(i); }
  std::size_t group_count() const { return groups_.size(); }
  const KinematicGroup& group(GroupId g) const { return groups_.at(g - 1); }
  KinematicGroup& group(GroupId g) { return groups_.at(g - 1); }
  const WallLoad& group_load(GroupId g) const { return group_loads_.at(g - 1); }

  // Contacts now in force: pairs from the neighbour list with their history. Only the pairs that
  // touch hold a history and forces, in a compact store of contacts (a candidate pair that is
  // apart costs a few bytes, not the 216 of a contact).
  std::span<const NeighborPair> candidate_pairs() const { return neighbors_.pairs(); }
  // Whether candidate pair k touches (has a contact history).
  bool pair_touching(std::size_t k) const { return pair_touching_[k] != 0; }
  // The history of candidate pair k and the force on its first particle; k must touch.
  const ContactHistory& pair_history(std::size_t k) const {
    return contact_history_[pair_slot_[k]];
  }
  const Vec3& pair_force(std::size_t k) const { return contact_force_[pair_slot_[k]].force; }
  // The gap candidate pair k is known to keep at least, whatever happened since it was last
  // screened; positive while it sleeps (0 for a pair that touches, and for every pair where none
  // may sleep). The next screening skips it if the step's growth of the approach bound leaves this
  // positive.
  double pair_sleeping_gap(std::size_t k) const {
    return std::max(static_cast<double>(pair_wake_[k]) - approach_bound_, 0.0);
  }
  std::size_t active_contact_count() const;
  // Whether the pair pass takes a block's contacts in force four at a time, one per AVX2 lane
  // (dem/contact_lanes.hpp; the default where the library has AVX2), or each alone: the same bits
  // either way, which the tests check by switching it off. Not kept in checkpoints.
  bool contacts_in_lanes() const { return contacts_in_lanes_; }
  void set_contacts_in_lanes(bool on);
  // Candidate pairs screened since this System was made (those asleep are not; not kept in
  // checkpoints): per particle-step, what the screening costs.
  std::uint64_t pairs_screened() const { return pairs_screened_; }
  // Sum over the pair contacts in force of F b^T: F the force on the first particle, b the
  // minimum-image vector from its centre to the second's (the pair-contact part of -V sigma).
  // Summed in the force gather of the last step, in an order fixed by the touching pairs alone
  // (at any thread count, whatever the neighbour list holds), so reading it costs nothing.
  const Eigen::Matrix3d& contact_virial() const { return contact_virial_; }
  // Every contact in force, pairs first (in (i, j) order), then wall contacts by particle.
  std::vector<ActiveContact> active_contacts() const;

  // Contact categories: one per unordered material pair, and one per (wall, material).
  std::size_t category_count() const;
  std::uint32_t pair_category(MaterialId a, MaterialId b) const;
  std::uint32_t wall_category(std::size_t wall, MaterialId m) const;
  std::string category_name(std::uint32_t category) const;

  // Dissipation per category, finished contacts plus the ones still touching.
  std::vector<Dissipation> dissipation_by_category() const;
  EnergyBudget energy() const;

  // Collision events finished since the last call, in a deterministic order: by step, then the
  // pair contacts in pair order, then the wall contacts by particle and slot.
  std::vector<CollisionEvent> take_collision_events();
  void set_record_collisions(bool on) { record_collisions_ = on; }
  // While recording, each finished contact goes to `sink` as it finishes, in the order above,
  // instead of into the buffer of take_collision_events; installing a sink first hands it the
  // events buffered so far. nullptr: back to the buffer. The pointer is no part of the state
  // (checkpoints) but copies of the System hold it: install it only around the steps that feed
  // it (ScopedCollisionSink).
  void set_collision_sink(CollisionSink* sink);

  Rng& rng() { return rng_; }

  // Bytes held between steps by the arrays a step works on (their capacities), by what they grow
  // with. The neighbour search's build scratch is freed when a build ends and not counted.
  struct MemoryUse {
    std::size_t particles = 0;  // per particle: state, the list's reference positions, the start
                                // of its pair list and its force state
    std::size_t candidate_pairs = 0;   // per candidate pair: the list, the pair's slot and flags,
                                       // its two entries in the particles' pair lists (padding
                                       // included)
    std::size_t contacts = 0;          // per pair contact in force: the contact store
    std::size_t wall_contacts = 0;     // the wall contact slots and flags (none without walls)
    std::size_t step_queues = 0;       // the pairs that start and stop touching in a step
    std::size_t collision_events = 0;  // finished contacts buffered and not yet taken
    std::size_t total() const {
      return particles + candidate_pairs + contacts + wall_contacts + step_queues +
             collision_events;
    }
  };
  MemoryUse memory_use() const;
  std::size_t memory_bytes() const { return memory_use().total(); }

 private:
  friend class CheckpointAccess;

  bool is_free(ParticleId p) const { return group_[p] == kFreeParticle; }
  void prepare_first_step();

  // Per axis, the largest |b - a| that needs no periodic image: PeriodicImages::separation
  // returns b - a unchanged when every component is below it (half a box on a periodic axis, the
  // Lees-Edwards gradient axis included; infinite on an open one), so the hot loops call it only
  // for the few pairs (or displacements) that are not.
  std::array<double, 3> no_image_limits() const;
  // The first half kick and the drift in one pass; returns whether the neighbour list must be
  // rebuilt.
  bool kick_and_drift();
  // The particle arrays of the drift and the kicks (dem/drift.hpp).
  DriftArrays drift_arrays();
  void update_neighbors(bool rebuild);
  // After rebuild_neighbors from the touching pairs `pairs` (sorted): marks them in force and
  // puts their forces back (`forces`, or the ones their contacts hold when empty), so that what
  // reads the contacts in force before the next step sees them.
  void restore_pair_forces(std::span<const NeighborPair> pairs, std::span<const Vec3> forces = {});
  // A candidate pair that touches and its contact's slot.
  struct TouchingSlot {
    NeighborPair pair;
    std::uint32_t slot;
  };
  // The touching candidate pairs, in pair order.
  std::vector<TouchingSlot> touching_pairs() const;
  // Builds the neighbour list again keeping the contacts of `touching` (sorted by pair; slots in
  // the current store) and their forces, in force as before (set_neighbor_skin,
  // reorder_particles).
  void rebuild_with_touching(std::span<const TouchingSlot> touching);
  // Builds a new neighbour list and carries the contacts of `old_pairs` (sorted; old_slot[o] the
  // contact of old pair o, or kNoContact) over to it; the contact store is laid out again in
  // the new pairs' order.
  void rebuild_neighbors(std::span<const NeighborPair> old_pairs,
                         std::span<const std::uint32_t> old_slot);
  // The same from a history per old pair (a checkpoint's), forces zero.
  void rebuild_neighbors(std::span<const NeighborPair> old_pairs,
                         std::vector<ContactHistory> old_history);
  void compute_pair_forces(double dt);
  // A candidate pair found touching by the screening, with what the screening worked out.
  struct TouchingPair {
    Vec3 separation;         // from the first particle's centre to the second's (minimum image)
    double distance;         // its length
    double gradient_images;  // PeriodicImages::separation's
    std::uint32_t k;         // the pair's index
  };
  // Per chunk of kPairGrain pairs of the screening pass, the pairs that start touching in a step
  // and those that stop (their indices), each in pair order; then all the starting ones (kept, so
  // that a step allocates nothing once they have grown).
  struct ChunkQueues {
    std::vector<TouchingPair> starting;
    std::vector<std::uint32_t> finishing;
    std::size_t screened = 0;  // pairs screened (not asleep) in the step
  };
  std::vector<ChunkQueues> queues_by_chunk_;
  std::vector<TouchingPair> starting_;
  // The contact law of a candidate pair that touches (it has a contact slot).
  struct PairContactKernel;
  // A slot in the contact store for a pair that starts touching (one freed by a finished contact
  // first), its history cleared.
  std::uint32_t allocate_contact();
  // Moves each contact record from slot s to target[s] in place and keeps the first `kept`; the
  // slots target does not name (kNoContact) are dropped. target must give the kept slots 0 ..
  // kept - 1, each once; it is used up.
  void place_contacts(std::vector<std::uint32_t>& target, std::uint32_t kept);
  // m_eff of a pair of particles (a kinematic one counts as infinitely heavy) and C_n of their
  // contact.
  double pair_effective_mass(ParticleId i, ParticleId j) const;
  double pair_normal_damping(ParticleId i, ParticleId j) const;
  // The forces and torques on the particles, the contact virial, the wall contacts; with
  // `closing_kick`, the step's closing half kick in the same pass.
  void compute_particle_forces(double dt, bool closing_kick);
  void reduce_loads(double dt);
  void collect_finished_contacts();
  // A finished contact, recorded: to the sink or into the buffer. Defined with the rest of the
  // events' code in dem/system_collisions.cpp: system.cpp is at GCC's inline-unit-growth limit,
  // and code added there stops the contact law's periodic images being inlined (+0.6% of the
  // media cell's instructions, docs/benchmarks.md).
  void record_collision(const CollisionEvent& event);

  MaterialTable materials_;
  Domain domain_;
  Vec3 gravity_;
  double dt_ = 0.0;
  double time_ = 0.0;
  std::uint64_t step_count_ = 0;
  double skin_ = 0.0;
  std::uint64_t rebuild_count_ = 0;
  std::uint64_t compaction_count_ = 0;
  // Contacts given a slot since the store was last laid out in pair order.
  std::size_t contacts_placed_since_compaction_ = 0;
  bool prepared_ = false;
  bool record_collisions_ = false;
  CollisionSink* collision_sink_ = nullptr;
  std::uint64_t reorder_every_ = 0;
  Rng rng_;

  // Particles (structure of arrays).
  std::vector<Vec3> position_, velocity_, angular_velocity_, force_, torque_;
  std::vector<Vec3> predicted_velocity_, predicted_angular_velocity_;  // at t + dt, for dashpots
  std::vector<double> radius_, mass_, inv_mass_, inv_inertia_;
  std::vector<MaterialId> material_;
  std::vector<GroupId> group_;

  std::vector<KinematicGroup> groups_;
  std::vector<WallLoad> group_loads_;
  std::vector<Wall> walls_;
  std::vector<WallLoad> wall_loads_;

  // Pair contacts. Per candidate pair, aligned with neighbors_.pairs():
  NeighborSearch neighbors_;
  static constexpr std::uint32_t kNoContact = 0xffffffffu;
  std::vector<std::uint32_t> pair_slot_;  // its contact's slot in the store below, or kNoContact
  // pair_slot_[k] != kNoContact in one byte per pair, so that screening the pairs, most of them
  // apart, reads no more.
  std::vector<std::uint8_t> pair_touching_;
  // Pairs that cannot touch yet are not screened (docs/benchmarks.md, "Pairs apart sleep"):
  // approach_bound_ is the most any candidate pair's gap can have closed since the list was built
  // (each step adds twice the fastest particle's speed relative to the shear flow, plus the
  // shear rate times pair_separation_bound_, times dt; a stretch of the box adds its strain times
  // that bound); a pair found apart by a gap g sleeps until the bound has grown by g, in
  // pair_wake_ (0: screened every step). Screening the sleeping pairs would find them apart, so
  // no result changes. Without room for that argument in the box (pairs_may_sleep_), none sleeps.
  std::vector<float> pair_wake_;
  double approach_bound_ = 0.0;
  std::uint64_t pairs_screened_ = 0;
  double pair_separation_bound_ = 0.0;  // the largest separation of a candidate pair until the next
                                        // build: the largest reach plus twice the skin
  bool pairs_may_sleep_ = false;
  bool contacts_in_lanes_ = false;  // set by the constructor, where the library's ISA is known
  void reset_sleeping_pairs();

  // The contact store: one slot per pair that touches, in the pairs' order after each neighbour
  // rebuild, new contacts in the slots finished ones freed (or at the end). Split in what the
  // force gather reads (ContactForce, 96 bytes) and what the contact law keeps (the history).
  struct ContactForce {
    Vec3 force = Vec3::Zero();     // on the first particle
    Vec3 torque_a = Vec3::Zero();  // on the first particle
    Vec3 torque_b = Vec3::Zero();  // on the second
    Vec3 branch = Vec3::Zero();    // from the first particle's centre to the second's
  };
  std::vector<ContactHistory> contact_history_;
  std::vector<ContactForce> contact_force_;
  std::vector<std::uint32_t> free_contact_slots_;
  Eigen::Matrix3d contact_virial_ = Eigen::Matrix3d::Zero();
  // Per particle, its pairs in two lists, each starting at a multiple of 8 (unused slots pad
  // them): those it is second of (CSR: the pair's contact slot, valid while the pair is in
  // force, so that the gather reads the contact without going through the pair), then its own
  // row, those it is first of (no index kept: the row's pairs are consecutive, slot -
  // particle_first_shift_[p]). In pair order every pair a particle is second of comes before its
  // row, so the gather, reading the two lists in turn, sums in pair order.
  std::vector<std::uint32_t> second_offset_, second_contact_slot_, first_offset_;
  // Per slot of either list, whether its pair is in force this step (set by the contact law,
  // cleared by the force gather), so that the gather visits only those; where the contact law
  // finds a pair's two slots: k + particle_first_shift_[i] and pair_second_slot_[k].
  std::vector<std::uint8_t> second_in_force_, first_in_force_;
  std::vector<std::uint32_t> pair_second_slot_, particle_first_shift_;
  // Per particle what its force and torque hold (ParticleForceState, dem/drift.hpp).
  std::vector<std::uint8_t> particle_force_state_;

  // Wall contacts, kMaxWallContactsPerParticle slots per particle, double-buffered: each step
  // fills one buffer from the other, so no slot is copied or cleared for particles off the walls.
  // Allocated only once the system has a wall (they would be most of a wall-less cell's memory).
  struct WallSlots {
    std::vector<WallContactHistory> slot;
    std::vector<std::uint8_t> count;
    WallContactHistory* of(std::size_t p) { return &slot[p * kMaxWallContactsPerParticle]; }
    const WallContactHistory* of(std::size_t p) const {
      return &slot[p * kMaxWallContactsPerParticle];
    }
    void resize(std::size_t n) {
      slot.resize(n * kMaxWallContactsPerParticle);
      count.resize(n, 0);
    }
  };
  const WallSlots& current_wall_slots() const { return wall_slots_[wall_current_]; }
  int wall_contact_count(std::size_t p) const {
    return walls_.empty() ? 0 : current_wall_slots().count[p];
  }
  std::array<WallSlots, 2> wall_slots_;
  int wall_current_ = 0;
  // Per particle (once the system has a wall), bit s: slot s of the other buffer separated.
  std::vector<std::uint8_t> finished_wall_mask_;

  std::vector<Dissipation> finished_dissipation_;  // per category
  std::vector<CollisionEvent> events_;
};

// Installs a collision sink on a System for its own lifetime (System::set_collision_sink).
class ScopedCollisionSink {
 public:
  ScopedCollisionSink(System& system, CollisionSink& sink) : system_(system) {
    system_.set_collision_sink(&sink);
  }
  ~ScopedCollisionSink() { system_.set_collision_sink(nullptr); }
  ScopedCollisionSink(const ScopedCollisionSink&) = delete;
  ScopedCollisionSink& operator=(const ScopedCollisionSink&) = delete;

 private:
  System& system_;
};

}  // namespace millflow::dem
