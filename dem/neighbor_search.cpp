#include "dem/neighbor_search.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "dem/array_growth.hpp"

namespace millflow::dem {

// A lower bound of |domain.separation(a, b)|^2 for a cheap first test of each candidate. Per axis
// it is the minimum image of |b - a| when that is at most one box length (evaluated exactly as
// separation does), and 0 where it cannot tell: the Lees-Edwards flow axis, or positions more
// than a box apart.
class SeparationBound {
 public:
  explicit SeparationBound(const Domain& domain) {
    for (int a = 0; a < 3; ++a) {
      // An infinite length makes the periodic formula return |b - a| on open axes, a zero one
      // returns 0 (the Lees-Edwards flow axis) without a weight to multiply by per candidate.
      const bool flow = domain.lees_edwards.enabled && a == domain.lees_edwards.flow_axis;
      period_[a] = flow                 ? 0.0
                   : domain.periodic[a] ? domain.length()[a]
                                        : std::numeric_limits<double>::infinity();
    }
  }

  double squared(const Vec3& a, const Vec3& b) const {
    double sum = 0.0;
    for (int axis = 0; axis < 3; ++axis) {
      double d = std::abs(b[axis] - a[axis]);
      d = d <= period_[axis] ? std::min(d, period_[axis] - d) : 0.0;
      sum += d * d;
    }
    return sum;
  }

 private:
  std::array<double, 3> period_{};
};

namespace {

// Candidates whose bound exceeds the cutoff by this relative margin are rejected unchecked; the
// margin covers the summation order of the squares, the only rounding difference.
constexpr double kBoundMargin = 1.0 + 1e-9;
// Levels halve the cell size: 8 levels cover size ratios up to ~128 with cells within 2x of the
// particles; smaller particles all share the finest level.
constexpr int kMaxLevels = 8;
// Particles per parallel task; the candidate lists do not depend on it.
constexpr std::size_t kChunkSize = 256;

// The pair criterion shared by the search and the reference; a has the smaller index, so both
// evaluate exactly the same floating-point expression. `images` is the domain's, built once per
// pass (Domain::separation builds one per call, with the same bits).
bool within_cutoff(const PeriodicImages& images, const Vec3& xa, double ra, const Vec3& xb,
                   double rb, double skin) {
  const double cutoff = ra + rb + skin;
  return images.separation(xa, xb).squaredNorm() < cutoff * cutoff;
}

void validate_particles(std::span<const Vec3> positions, std::span<const double> radii) {
  if (positions.size() != radii.size()) {
    throw std::invalid_argument(
        fmt::format("neighbour search: {} positions but {} radii; pass one radius per particle",
                    positions.size(), radii.size()));
  }
  if (positions.size() > std::numeric_limits<std::uint32_t>::max()) {
    throw std::invalid_argument(fmt::format(
        "neighbour search: {} particles exceed the 32-bit particle index", positions.size()));
  }
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (!positions[i].allFinite()) {
      throw std::invalid_argument(
          fmt::format("neighbour search: position of particle {} = ({}, {}, {}) is not finite", i,
                      positions[i].x(), positions[i].y(), positions[i].z()));
    }
    if (!(radii[i] > 0.0) || !std::isfinite(radii[i])) {
      throw std::invalid_argument(fmt::format(
          "neighbour search: radius of particle {} = {} must be positive and finite", i, radii[i]));
    }
  }
}

void validate_skin(double skin) {
  if (!(skin >= 0.0) || !std::isfinite(skin)) {
    throw std::invalid_argument(
        fmt::format("neighbour search: skin = {} must be finite and >= 0", skin));
  }
}

// Margin added to every query reach so that rounding in cell indices and image shifts (a few ulps
// of the coordinates) can never hide a pair that is within the cutoff.
double reach_padding(const Domain& domain, double largest_reach) {
  const double scale = std::max(domain.lo.cwiseAbs().maxCoeff(), domain.hi.cwiseAbs().maxCoeff()) +
                       domain.length().maxCoeff() + largest_reach;
  return 1e-10 * scale;
}

// Most cells a level's grid may have: enough for dense packings, bounded for sparse fine levels
// in big boxes.
std::size_t max_cells_for(std::size_t member_count) {
  return std::max<std::size_t>(4096, 8 * member_count);
}

}  // namespace

NeighborSearch::NeighborSearch(NeighborSearchOptions options) : options_(options) {
  validate_skin(options_.skin);
}

void NeighborSearch::build(const Domain& domain, std::span<const Vec3> positions,
                           std::span<const double> radii) {
  domain.validate();
  validate_particles(positions, radii);
  assign_levels(radii);
  bin_levels(domain, positions, radii);
  search(domain, positions, radii);
  assemble_pairs(positions.size());
  build_ = BuildScratch{};

  reference_positions_.assign(positions.begin(), positions.end());
  reference_offset_ = domain.lees_edwards.offset;
  built_ = true;
  ++build_count_;
}

void NeighborSearch::assign_levels(std::span<const double> radii) {
  const double skin = options_.skin;
  const double r_max = radii.empty() ? 0.0 : *std::max_element(radii.begin(), radii.end());
  const double top_cell = 2.0 * r_max + skin;
  // Nominal level: how many times the top cell size can be halved and still hold the particle.
  const auto nominal_level = [&](double r) {
    int level = 0;
    for (double cell = 0.5 * top_cell;
         options_.multilevel && level + 1 < kMaxLevels && cell >= 2.0 * r + skin; cell *= 0.5) {
      ++level;
    }
    return level;
  };
  std::array<double, kMaxLevels> level_r_max{};
  build_.level_of.resize(radii.size());
  for (std::size_t i = 0; i < radii.size(); ++i) {
    const int level = nominal_level(radii[i]);
    build_.level_of[i] = static_cast<std::uint8_t>(level);
    level_r_max[level] = std::max(level_r_max[level], radii[i]);
  }
  // Drop empty levels (radii are positive, so an empty level has r_max 0).
  std::array<std::uint8_t, kMaxLevels> compact{};
  build_.level_max_radius.clear();
  for (int level = 0; level < kMaxLevels; ++level) {
    compact[level] = static_cast<std::uint8_t>(build_.level_max_radius.size());
    if (level_r_max[level] > 0.0) build_.level_max_radius.push_back(level_r_max[level]);
  }
  for (auto& level : build_.level_of) level = compact[level];
}

void NeighborSearch::bin_levels(const Domain& domain, std::span<const Vec3> positions,
                                std::span<const double> radii) {
  build_.grids.resize(build_.level_max_radius.size());
  for (std::size_t level = 0; level < build_.grids.size(); ++level) {
    build_.level_members.clear();
    for (std::uint32_t i = 0; i < build_.level_of.size(); ++i) {
      if (build_.level_of[i] == level) build_.level_members.push_back(i);
    }
    // Cells as wide as the reach of the next finer level's particles into this one (2 r_max +
    // skin on the finest): the finer particles' queries, the most numerous, then scan a few
    // cells of about their reach, not the cells of twice this level's radius (the pairs within
    // this level span a few more cells, whatever their width).
    const double finer_radius = level + 1 < build_.grids.size() ? build_.level_max_radius[level + 1]
                                                                : build_.level_max_radius[level];
    build_.grids[level].configure(domain,
                                  build_.level_max_radius[level] + finer_radius + options_.skin,
                                  max_cells_for(build_.level_members.size()));
    build_.grids[level].bin(positions, radii, build_.level_members);
  }
}

void NeighborSearch::search(const Domain& domain, std::span<const Vec3> positions,
                            std::span<const double> radii) {
  const std::size_t n = positions.size();
  build_.chunks.resize((n + kChunkSize - 1) / kChunkSize);
  build_.partner_begin.resize(n);
  build_.partner_count.resize(n);
  build_.lower_count.resize(n);
  const double largest_reach =
      build_.level_max_radius.empty() ? 0.0 : 2.0 * build_.level_max_radius.front() + options_.skin;
  const double padding = reach_padding(domain, largest_reach);
  const SeparationBound bound(domain);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, build_.chunks.size()),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t c = range.begin(); c != range.end(); ++c) {
                        search_chunk(domain, bound, positions, radii, c, padding);
                      }
                    });
  stats_ = Stats{build_.grids.size(), 0, 0};
  for (const Chunk& chunk : build_.chunks) {
    stats_.cells_visited += chunk.cells_visited;
    stats_.candidates_tested += chunk.candidates_tested;
  }
}

void NeighborSearch::search_chunk(const Domain& domain, const SeparationBound& bound,
                                  std::span<const Vec3> positions, std::span<const double> radii,
                                  std::size_t chunk_index, double reach_padding) {
  Chunk& chunk = build_.chunks[chunk_index];
  const PeriodicImages images(domain);
  chunk.partners.clear();
  chunk.cells_visited = 0;
  chunk.candidates_tested = 0;
  const auto first = static_cast<std::uint32_t>(chunk_index * kChunkSize);
  const auto last =
      static_cast<std::uint32_t>(std::min(positions.size(), (chunk_index + 1) * kChunkSize));
  for (std::uint32_t q = first; q < last; ++q) {
    const std::size_t begin = chunk.partners.size();
    const std::size_t own_level = build_.level_of[q];
    const Vec3& xq = positions[q];
    const double rq = radii[q];
    for (std::size_t level = 0; level <= own_level; ++level) {
      const double reach = rq + build_.level_max_radius[level] + options_.skin + reach_padding;
      // What the visitor reads for every member, held by value (one load each, not a reference
      // and its target) and the count kept in the visitor until the level is done.
      std::size_t tested = 0;
      const auto test = [&chunk, &images, &tested, bound, q, xq = Vec3(xq), rq,
                         skin = options_.skin](const CellGrid::Member& m) {
        ++tested;
        const double cutoff = rq + m.radius + skin;
        if (bound.squared(xq, m.position) > kBoundMargin * cutoff * cutoff) return;
        const bool found = m.index > q ? within_cutoff(images, xq, rq, m.position, m.radius, skin)
                                       : within_cutoff(images, m.position, m.radius, xq, rq, skin);
        if (found) chunk.partners.push_back(m.index);
      };
      // Across levels the finer particle finds the pair; within its own level, one of the two
      // (CellGrid::visit_after), and assemble_pairs files it in the row of the smaller index.
      const CellGrid& grid = build_.grids[level];
      chunk.cells_visited += level == own_level ? grid.visit_after(xq, reach, q, test)
                                                : grid.visit_near(xq, reach, test);
      chunk.candidates_tested += tested;
    }
    // Cells visited twice (tiny Lees-Edwards boxes) repeat partners: sort and drop repeats.
    const auto found_begin = chunk.partners.begin() + static_cast<std::ptrdiff_t>(begin);
    std::sort(found_begin, chunk.partners.end());
    chunk.partners.erase(std::unique(found_begin, chunk.partners.end()), chunk.partners.end());
    build_.partner_begin[q] = static_cast<std::uint32_t>(begin);
    build_.partner_count[q] = static_cast<std::uint32_t>(chunk.partners.size() - begin);
    build_.lower_count[q] = static_cast<std::uint32_t>(
        std::lower_bound(found_begin, chunk.partners.end(), q) - found_begin);
  }
}

std::span<const std::uint32_t> NeighborSearch::partners_of(std::uint32_t q) const {
  return std::span<const std::uint32_t>(build_.chunks[q / kChunkSize].partners)
      .subspan(build_.partner_begin[q], build_.partner_count[q]);
}

void NeighborSearch::assemble_pairs(std::size_t particle_count) {
  // Candidates q found for a lower p (from a finer level or an earlier cell) belong to row p:
  // counting sort them by p, in increasing q, so each row is the merge of two sorted lists.
  build_.incoming_begin.assign(particle_count + 1, 0);
  for (std::uint32_t q = 0; q < particle_count; ++q) {
    for (const std::uint32_t p : partners_of(q).first(build_.lower_count[q]))
      ++build_.incoming_begin[p + 1];
  }
  for (std::size_t p = 0; p < particle_count; ++p)
    build_.incoming_begin[p + 1] += build_.incoming_begin[p];
  build_.incoming.resize(build_.incoming_begin[particle_count]);
  for (std::uint32_t q = 0; q < particle_count; ++q) {
    for (const std::uint32_t p : partners_of(q).first(build_.lower_count[q]))
      build_.incoming[build_.incoming_begin[p]++] = q;
  }
  // The fill advanced each begin to the next row's begin: shift back.
  for (std::size_t p = particle_count; p > 0; --p)
    build_.incoming_begin[p] = build_.incoming_begin[p - 1];
  if (particle_count > 0) build_.incoming_begin[0] = 0;

  build_.row_begin.assign(particle_count + 1, 0);
  for (std::uint32_t p = 0; p < particle_count; ++p) {
    const std::size_t incoming = build_.incoming_begin[p + 1] - build_.incoming_begin[p];
    build_.row_begin[p + 1] =
        build_.row_begin[p] + (build_.partner_count[p] - build_.lower_count[p]) + incoming;
  }
  resize_with_room(pairs_, build_.row_begin[particle_count]);
  tbb::parallel_for(
      tbb::blocked_range<std::uint32_t>(0, static_cast<std::uint32_t>(particle_count)),
      [&](const tbb::blocked_range<std::uint32_t>& range) {
        for (std::uint32_t p = range.begin(); p != range.end(); ++p) {
          const auto upper = partners_of(p).subspan(build_.lower_count[p]);
          const std::span<const std::uint32_t> incoming(
              build_.incoming.data() + build_.incoming_begin[p],
              build_.incoming.data() + build_.incoming_begin[p + 1]);
          std::size_t a = 0, b = 0;
          NeighborPair* out = pairs_.data() + build_.row_begin[p];
          while (a < upper.size() || b < incoming.size()) {
            const bool take_upper =
                b == incoming.size() || (a < upper.size() && upper[a] < incoming[b]);
            *out++ = NeighborPair{p, take_upper ? upper[a++] : incoming[b++]};
          }
        }
      });
}

bool NeighborSearch::needs_rebuild(const Domain& domain, std::span<const Vec3> positions) const {
  if (!built_ || positions.size() != reference_positions_.size()) return true;
  // The maximum is exact and order-independent, so any split gives the same answer. Squared
  // lengths spare a square root per particle.
  const double max_displacement_sq = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, positions.size(), 1024), 0.0,
      [&](const tbb::blocked_range<std::size_t>& range, double running) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
          running = std::max(
              running, domain.separation(reference_positions_[i], positions[i]).squaredNorm());
        }
        return running;
      },
      [](double a, double b) { return std::max(a, b); });
  return needs_rebuild(domain, positions.size(), max_displacement_sq);
}

bool NeighborSearch::needs_rebuild(const Domain& domain, std::size_t particle_count,
                                   double max_displacement_sq) const {
  if (!built_ || particle_count != reference_positions_.size()) return true;
  return travel(domain, max_displacement_sq) >= options_.skin;
}

double NeighborSearch::travel(const Domain& domain, double max_displacement_sq) const {
  double offset_change = 0.0;
  if (domain.lees_edwards.enabled) {
    const double flow_length = domain.length()[domain.lees_edwards.flow_axis];
    offset_change = domain.lees_edwards.offset - reference_offset_;
    offset_change -= std::round(offset_change / flow_length) * flow_length;
  }
  const double max_displacement = std::sqrt(max_displacement_sq);
  return 2.0 * max_displacement + std::abs(offset_change);
}

std::vector<NeighborPair> brute_force_pairs(const Domain& domain, std::span<const Vec3> positions,
                                            std::span<const double> radii, double skin) {
  validate_skin(skin);
  domain.validate();
  validate_particles(positions, radii);
  const PeriodicImages images(domain);
  std::vector<NeighborPair> pairs;
  for (std::uint32_t i = 0; i < positions.size(); ++i) {
    for (std::uint32_t j = i + 1; j < positions.size(); ++j) {
      if (within_cutoff(images, positions[i], radii[i], positions[j], radii[j], skin))
        pairs.push_back({i, j});
    }
  }
  return pairs;
}

}  // namespace millflow::dem
