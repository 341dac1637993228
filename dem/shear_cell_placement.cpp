// Filling a shear cell: the rough wall layers, the media (at random with walls, on a lattice with
// Lees-Edwards) and the powder, by random sequential addition.
#include "dem/shear_cell.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include <fmt/format.h>

#include "dem/shear_cell_geometry.hpp"

namespace millflow::dem {
using namespace shear_cell_detail;

namespace {

// Random sequential addition gives up after this many failed tries per particle.
constexpr int kInsertionTries = 20000;

// Random sequential addition against a cell grid of equal spheres: periodic axes wrap, the others
// clamp. Cells are one member diameter wide.
class InsertionGrid {
 public:
  InsertionGrid(const Domain& domain, double member_radius)
      : domain_(domain), radius_(member_radius) {
    for (int a = 0; a < 3; ++a) {
      cells_[a] =
          std::max(1, static_cast<int>(std::floor(domain.length()[a] / (2.0 * member_radius))));
      cell_size_[a] = domain.length()[a] / cells_[a];
    }
    members_.resize(static_cast<std::size_t>(cells_[0]) * cells_[1] * cells_[2]);
  }

  void insert(const Vec3& x) {
    members_[cell_id(cell_of(x))].push_back(static_cast<std::uint32_t>(positions_.size()));
    positions_.push_back(x);
  }

  // Whether a sphere of `radius` at x would overlap a member.
  bool overlaps(const Vec3& x, double radius) const {
    const double reach = radius + radius_;
    const std::array<int, 3> centre = cell_of(x);
    std::array<std::vector<int>, 3> rows;
    for (int a = 0; a < 3; ++a) rows[a] = cells_near(a, centre[a], reach);
    for (int i : rows[0]) {
      for (int j : rows[1]) {
        for (int k : rows[2]) {
          for (std::uint32_t m : members_[cell_id({i, j, k})]) {
            if (domain_.separation(x, positions_[m]).squaredNorm() < reach * reach) return true;
          }
        }
      }
    }
    return false;
  }

 private:
  std::array<int, 3> cell_of(const Vec3& x) const {
    std::array<int, 3> c{};
    for (int a = 0; a < 3; ++a) {
      const int u = static_cast<int>(std::floor((x[a] - domain_.lo[a]) / cell_size_[a]));
      c[a] = domain_.periodic[a] ? ((u % cells_[a]) + cells_[a]) % cells_[a]
                                 : std::clamp(u, 0, cells_[a] - 1);
    }
    return c;
  }

  // Distinct cells along axis a within `reach` of cell c.
  std::vector<int> cells_near(int a, int c, double reach) const {
    const int span = static_cast<int>(std::ceil(reach / cell_size_[a]));
    std::vector<int> cells;
    if (domain_.periodic[a] && 2 * span + 1 >= cells_[a]) {
      for (int u = 0; u < cells_[a]; ++u) cells.push_back(u);
      return cells;
    }
    for (int u = c - span; u <= c + span; ++u) {
      if (domain_.periodic[a]) {
        cells.push_back(((u % cells_[a]) + cells_[a]) % cells_[a]);
      } else if (u >= 0 && u < cells_[a]) {
        cells.push_back(u);
      }
    }
    return cells;
  }

  std::size_t cell_id(const std::array<int, 3>& c) const {
    return (static_cast<std::size_t>(c[0]) * cells_[1] + c[1]) * cells_[2] + c[2];
  }

  Domain domain_;
  double radius_;
  std::array<int, 3> cells_{};
  Vec3 cell_size_ = Vec3::Ones();
  std::vector<std::vector<std::uint32_t>> members_;
  std::vector<Vec3> positions_;
};

}  // namespace

void ShearCell::place_wall_layer(GroupId group, double y) {
  const double d = setup_.media_diameter;
  const Vec3 length = system_.domain().length();
  const std::size_t nx = wall_layer_columns(length.x(), d);
  const std::size_t nz = wall_layer_columns(length.z(), d);
  for (std::size_t i = 0; i < nx; ++i) {
    for (std::size_t k = 0; k < nz; ++k) {
      const double height = y + kWallBallJitter * d * system_.rng().uniform(-1.0, 1.0);
      const Vec3 x((i + 0.5) * length.x() / nx, height, (k + 0.5) * length.z() / nz);
      system_.add_particle(
          {.position = x, .radius = 0.5 * d, .material = wall_material_, .group = group});
      ++wall_ball_count_;
    }
  }
}

void ShearCell::place_media_dilute(double gap0) {
  const double r = 0.5 * setup_.media_diameter;
  InsertionGrid grid(system_.domain(), r);
  const Vec3 lo = system_.domain().lo, hi = system_.domain().hi;
  Rng& rng = system_.rng();
  for (std::size_t n = 0; n < media_count_; ++n) {
    for (int attempt = 0;; ++attempt) {
      require(
          attempt < kInsertionTries,
          fmt::format(
              "could not place media ball {} of {} without overlaps; lower media_solid_fraction", n,
              media_count_));
      // Centres at least r above the highest wall ball's top and below the lowest of the top layer.
      const double clear = (0.5 + kWallBallJitter) * setup_.media_diameter + r;
      const Vec3 x(rng.uniform(lo.x(), hi.x()), rng.uniform(clear, gap0 - clear),
                   rng.uniform(lo.z(), hi.z()));
      if (grid.overlaps(x, r)) continue;
      grid.insert(x);
      system_.add_particle({.position = x, .radius = r, .material = media_});
      break;
    }
  }
}

void ShearCell::place_media_lattice() {
  // FCC conventional cells of side >= sqrt(2) d (touching neighbours), stretched to fit the box;
  // the media take a random subset of the sites.
  const double d = setup_.media_diameter;
  const Vec3 length = system_.domain().length();
  std::array<int, 3> cells{};
  for (int a = 0; a < 3; ++a)
    cells[a] = static_cast<int>(std::floor(length[a] / (std::numbers::sqrt2 * d * 1.001)));
  std::vector<Vec3> sites;
  const std::array<Vec3, 4> basis{Vec3(0, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 0.5),
                                  Vec3(0, 0.5, 0.5)};
  for (int i = 0; i < cells[0]; ++i) {
    for (int j = 0; j < cells[1]; ++j) {
      for (int k = 0; k < cells[2]; ++k) {
        for (const Vec3& b : basis) {
          const Vec3 unit = (Vec3(i, j, k) + b + Vec3::Constant(0.25));
          sites.push_back(system_.domain().lo + Vec3(unit.x() * length.x() / cells[0],
                                                     unit.y() * length.y() / cells[1],
                                                     unit.z() * length.z() / cells[2]));
        }
      }
    }
  }
  require(sites.size() >= media_count_,
          fmt::format(
              "a Lees-Edwards cell of {} x {} x {} media diameters holds at most {} media balls on "
              "its FCC "
              "lattice, {} are needed for media_solid_fraction {}; lower it or enlarge the cell",
              setup_.size_diameters.x(), setup_.size_diameters.y(), setup_.size_diameters.z(),
              sites.size(), media_count_, setup_.media_solid_fraction));
  Rng& rng = system_.rng();
  // The imposed profile plus a random velocity of a tenth of the shear velocity across one ball,
  // without net momentum: the lattice's z-planes can lie exactly d apart (cells 2-2.8 d or
  // 4-4.2 d deep), and a fill moving only in the x-y plane would then shear for ever as a stack
  // of 2-D layers (p_zz = 0).
  const double agitation = 0.1 * setup_.shear_rate * d;
  std::vector<Vec3> agitations(media_count_);
  Vec3 mean_agitation = Vec3::Zero();
  for (std::size_t n = 0; n < media_count_; ++n) {  // partial Fisher-Yates shuffle
    const std::size_t pick =
        n + static_cast<std::size_t>(rng.uniform() * static_cast<double>(sites.size() - n));
    std::swap(sites[n], sites[pick]);
    agitations[n] =
        agitation * Vec3(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
    mean_agitation += agitations[n] / static_cast<double>(media_count_);
  }
  const double y_mid = system_.domain().lo.y() + 0.5 * length.y();
  for (std::size_t n = 0; n < media_count_; ++n) {
    const Vec3 velocity =
        Vec3(setup_.shear_rate * (sites[n].y() - y_mid), 0.0, 0.0) + agitations[n] - mean_agitation;
    system_.add_particle(
        {.position = sites[n], .velocity = velocity, .radius = 0.5 * d, .material = media_});
  }
}

void ShearCell::place_powder(double y_lo, double y_hi) {
  if (powder_count_ == 0) return;
  const double r = 0.5 * powder_diameter(setup_);
  const double r_media = 0.5 * setup_.media_diameter;
  InsertionGrid media_grid(system_.domain(), r_media), powder_grid(system_.domain(), r);
  for (std::size_t p = 0; p < system_.size(); ++p) {
    if (system_.particle_groups()[p] == kFreeParticle) media_grid.insert(system_.positions()[p]);
  }
  const Vec3 lo = system_.domain().lo, hi = system_.domain().hi;
  const bool periodic_y = system_.domain().periodic[1];
  Rng& rng = system_.rng();
  for (std::size_t n = 0; n < powder_count_; ++n) {
    for (int attempt = 0;; ++attempt) {
      require(attempt < kInsertionTries,
              fmt::format(
                  "could not place powder particle {} of {} without overlaps; lower powder_load", n,
                  powder_count_));
      const double y = periodic_y ? rng.uniform(y_lo, y_hi) : rng.uniform(y_lo + r, y_hi - r);
      const Vec3 x(rng.uniform(lo.x(), hi.x()), y, rng.uniform(lo.z(), hi.z()));
      if (media_grid.overlaps(x, r) || powder_grid.overlaps(x, r)) continue;
      powder_grid.insert(x);
      Vec3 velocity = Vec3::Zero();
      if (!walls()) velocity.x() = setup_.shear_rate * (y - (lo.y() + 0.5 * (hi.y() - lo.y())));
      system_.add_particle({.position = x, .velocity = velocity, .radius = r, .material = powder_});
      break;
    }
  }
}

}  // namespace millflow::dem
