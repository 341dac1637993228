#pragma once
// Candidate contact pairs by multi-level cell lists with a Verlet skin.
//
// Particles are binned into size levels whose cell sizes halve from level to level (each level's
// cells are at least its largest radius + the next finer level's largest radius + skin wide, the
// finest level's 2 * its largest radius + skin). A particle queries the grids of its own
// level and of the coarser ones only, so the fine particle of a media/powder pair does the
// cross-level query and scans a few big cells, and a media ball never scans the powder grid. In
// its own level a particle visits only the cells after its own (CellGrid::visit_after), so each
// pair there is seen once, not twice.
// Periodic axes use the minimum image, Lees-Edwards images included (Domain::separation).
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "dem/cell_grid.hpp"
#include "dem/domain.hpp"
#include "dem/vec.hpp"

namespace millflow::dem {

struct NeighborPair {
  std::uint32_t i, j;  // always i < j
  bool operator==(const NeighborPair&) const = default;
};

struct NeighborSearchOptions {
  double skin = 0.0;
  // false: a single uniform grid sized for the largest particle (benchmark baseline only).
  bool multilevel = true;
};

class SeparationBound;  // cheap candidate pre-test, internal to neighbor_search.cpp

class NeighborSearch {
 public:
  struct Stats {
    std::size_t levels = 0;
    std::size_t cells_visited = 0;
    std::size_t candidates_tested = 0;
  };

  // Throws std::invalid_argument if the skin is negative or not finite.
  explicit NeighborSearch(NeighborSearchOptions options);

  // Candidate list: every pair with |domain.separation(x_i, x_j)| < r_i + r_j + skin, sorted by
  // (i, j), i < j. Records the reference positions and Lees-Edwards offset for needs_rebuild.
  // Throws std::invalid_argument for an invalid domain, mismatched sizes, a non-finite position
  // or a radius that is not positive and finite.
  void build(const Domain& domain, std::span<const Vec3> positions, std::span<const double> radii);

  // True if never built, the particle count changed, or a contact could have been missed:
  // 2 * (max minimum-image displacement since build) + |change of the Lees-Edwards offset since
  // build, taken modulo L_flow to its smallest magnitude| >= skin.
  bool needs_rebuild(const Domain& domain, std::span<const Vec3> positions) const;
  // The same decision from the caller's own max over i of
  // |domain.separation(reference_positions()[i], x_i)|^2, so that it can ride along another pass
  // over the particles.
  bool needs_rebuild(const Domain& domain, std::size_t particle_count,
                     double max_displacement_sq) const;
  // Positions at the last build (empty before the first).
  std::span<const Vec3> reference_positions() const { return reference_positions_; }
  // What the rebuild test compares with the skin: 2 * sqrt(max_displacement_sq) + |change of the
  // Lees-Edwards offset since build| (see needs_rebuild).
  double travel(const Domain& domain, double max_displacement_sq) const;
  // Forces a rebuild at the next needs_rebuild (after the box itself changed).
  void invalidate() { built_ = false; }

  const std::vector<NeighborPair>& pairs() const { return pairs_; }
  std::size_t build_count() const { return build_count_; }
  const Stats& last_build_stats() const { return stats_; }
  const NeighborSearchOptions& options() const { return options_; }
  // Bytes held between builds (capacities): the candidate list, and the reference positions.
  std::size_t pair_bytes() const { return pairs_.capacity() * sizeof(NeighborPair); }
  std::size_t reference_bytes() const { return reference_positions_.capacity() * sizeof(Vec3); }

 private:
  // Candidates of a block of consecutive particles, found by one task.
  struct Chunk {
    std::vector<std::uint32_t> partners;
    std::size_t cells_visited = 0;
    std::size_t candidates_tested = 0;
  };

  void assign_levels(std::span<const double> radii);
  void bin_levels(const Domain& domain, std::span<const Vec3> positions,
                  std::span<const double> radii);
  void search(const Domain& domain, std::span<const Vec3> positions, std::span<const double> radii);
  void search_chunk(const Domain& domain, const SeparationBound& bound,
                    std::span<const Vec3> positions, std::span<const double> radii,
                    std::size_t chunk_index, double reach_padding);
  void assemble_pairs(std::size_t particle_count);
  std::span<const std::uint32_t> partners_of(std::uint32_t q) const;

  // What only a build reads, freed when it ends: between rebuilds the list is its pairs and
  // reference positions alone (allocating the scratch again costs a rebuild 1-2% more
  // instructions, docs/benchmarks.md).
  struct BuildScratch {
    std::vector<CellGrid> grids;               // coarsest first
    std::vector<double> level_max_radius;      // per grid
    std::vector<std::uint8_t> level_of;        // per particle: index into grids
    std::vector<std::uint32_t> level_members;  // particles of one level
    std::vector<Chunk> chunks;
    // Per particle q: its candidates (sorted, unique) are chunks[q / kChunk].partners
    // [partner_begin[q], + partner_count[q]); the first lower_count[q] of them are < q.
    std::vector<std::uint32_t> partner_begin, partner_count, lower_count;
    // Per particle p: the particles q > p that found p (from a finer level, or from a cell before
    // p's in its own level), in increasing order:
    // incoming[incoming_begin[p], incoming_begin[p + 1]).
    std::vector<std::size_t> incoming_begin;
    std::vector<std::uint32_t> incoming;
    std::vector<std::size_t> row_begin;  // per particle: where its pairs start in pairs_
  };

  NeighborSearchOptions options_;
  BuildScratch build_;
  std::vector<NeighborPair> pairs_;

  std::vector<Vec3> reference_positions_;
  double reference_offset_ = 0.0;
  bool built_ = false;
  std::size_t build_count_ = 0;
  Stats stats_;
};

// O(N^2) reference, for tests and tiny systems. Same criterion and order as NeighborSearch.
std::vector<NeighborPair> brute_force_pairs(const Domain& domain, std::span<const Vec3> positions,
                                            std::span<const double> radii, double skin);

}  // namespace millflow::dem
