#include "method/coarse_grain.hpp"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "util/sphere.hpp"

namespace millflow::method {
namespace {

using Eigen::Vector3d;

Vector3d to_vector(const dem::Float3& v) {
  return {v[0], v[1], v[2]};
}

// The cells a kernel centred at one point reaches, with their weights W_c (sum_c W_c A = 1).
struct Footprint {
  std::vector<std::size_t> cells;
  std::vector<double> weights;
  std::vector<double> gx, gy;  // scratch: the separable Gaussian factors
};

class Kernel {
 public:
  Kernel(const CrossSectionGrid& grid, double width)
      : grid_(grid), width_(width), reach_(3.0 * width) {}

  // Fills `out` for the point (x, y). Throws std::invalid_argument when no cell inside the mill is
  // in reach, i.e. the point lies outside the mill.
  void evaluate(double x, double y, Footprint& out) const {
    out.cells.clear();
    out.weights.clear();
    const auto [i0, i1] = index_range(x, grid_.dx(), grid_.nx);
    const auto [j0, j1] = index_range(y, grid_.dy(), grid_.ny);
    gaussian_factors(
        x, i0, i1, [&](int i) { return grid_.x(i); }, out.gx);
    gaussian_factors(
        y, j0, j1, [&](int j) { return grid_.y(j); }, out.gy);
    double sum = 0.0;
    for (int j = j0; j <= j1; ++j) {
      const double ry = grid_.y(j) - y;
      for (int i = i0; i <= i1; ++i) {
        const double rx = grid_.x(i) - x;
        const std::size_t cell = grid_.index(i, j);
        if (rx * rx + ry * ry > reach_ * reach_ || !grid_.inside_mill(cell)) continue;
        const double weight =
            out.gx[static_cast<std::size_t>(i - i0)] * out.gy[static_cast<std::size_t>(j - j0)];
        out.cells.push_back(cell);
        out.weights.push_back(weight);
        sum += weight;
      }
    }
    if (out.cells.empty()) {
      throw std::invalid_argument(
          fmt::format("a particle, contact or collision at ({:.4g}, {:.4g}) m lies outside the "
                      "mill of radius {:.4g} m: "
                      "check that the mill radius matches the flow sample",
                      x, y, grid_.half_width));
    }
    const double scale = 1.0 / (sum * grid_.cell_area());
    for (double& weight : out.weights) weight *= scale;
  }

 private:
  // Cells along one axis whose centres lie within the reach of coordinate u.
  std::pair<int, int> index_range(double u, double h, int n) const {
    const double half = grid_.half_width;
    const int lo = static_cast<int>(std::ceil((u - reach_ + half) / h - 0.5));
    const int hi = static_cast<int>(std::floor((u + reach_ + half) / h - 0.5));
    return {std::max(lo, 0), std::min(hi, n - 1)};
  }

  template <class Centre>
  void gaussian_factors(double u, int lo, int hi, Centre centre,
                        std::vector<double>& factors) const {
    factors.clear();
    for (int k = lo; k <= hi; ++k) {
      const double r = centre(k) - u;
      factors.push_back(std::exp(-r * r / (2.0 * width_ * width_)));
    }
  }

  CrossSectionGrid grid_;
  double width_;
  double reach_;
};

// Per-cell sums over frames, before dividing by the slice length and the frame count.
struct Sums {
  Sums(std::size_t cells, std::size_t categories)
      : mass(cells, 0.0),
        volume(cells, 0.0),
        momentum(cells, Vector3d::Zero()),
        contact(cells, Tensor3::Zero()),
        fluctuation(cells, Tensor3::Zero()),
        events(categories, std::vector<double>(cells, 0.0)),
        dissipated(categories, std::vector<double>(cells, 0.0)) {}

  std::vector<double> mass, volume;
  std::vector<Vector3d> momentum;
  std::vector<Tensor3> contact;                         // sum f (x) b W (line kernel)
  std::vector<Tensor3> fluctuation;                     // sum m v' (x) v' W
  std::vector<std::vector<double>> events, dissipated;  // [category][cell]
  double particle_volume = 0.0;
  std::size_t frames = 0;

  Sums& operator+=(const Sums& o) {
    for (std::size_t c = 0; c < mass.size(); ++c) {
      mass[c] += o.mass[c];
      volume[c] += o.volume[c];
      momentum[c] += o.momentum[c];
      contact[c] += o.contact[c];
      fluctuation[c] += o.fluctuation[c];
    }
    for (std::size_t k = 0; k < events.size(); ++k) {
      for (std::size_t c = 0; c < mass.size(); ++c) {
        events[k][c] += o.events[k][c];
        dissipated[k][c] += o.dissipated[k][c];
      }
    }
    particle_volume += o.particle_volume;
    frames += o.frames;
    return *this;
  }
};

// Pass 1: mass, volume, momentum, contact stress and collision events of one frame.
class FirstPass {
 public:
  FirstPass(const CoarseGrainSettings& settings, const Kernel& kernel)
      : settings_(settings), kernel_(kernel) {}

  void add(const dem::FlowFrame& frame, Sums& sums) {
    add_particles(frame, sums);
    add_contacts(frame, sums);
    add_events(frame, sums);
    ++sums.frames;
  }

 private:
  void add_particles(const dem::FlowFrame& frame, Sums& sums) {
    for (std::size_t p = 0; p < frame.position.size(); ++p) {
      const double volume = util::sphere_volume_of_radius(frame.radius[p]);
      const double mass = settings_.media_density * volume;
      const Vector3d momentum = mass * to_vector(frame.velocity[p]);
      sums.particle_volume += volume;
      kernel_.evaluate(frame.position[p][0], frame.position[p][1], footprint_);
      for (std::size_t k = 0; k < footprint_.cells.size(); ++k) {
        const std::size_t c = footprint_.cells[k];
        const double w = footprint_.weights[k];
        sums.mass[c] += mass * w;
        sums.volume[c] += volume * w;
        sums.momentum[c] += momentum * w;
      }
    }
  }

  // f (x) b spread along the branch by the midpoint rule.
  void add_contacts(const dem::FlowFrame& frame, Sums& sums) {
    const double piece = 0.5 * settings_.kernel_width;
    for (std::size_t c = 0; c < frame.contact_a.size(); ++c) {
      const Vector3d start = to_vector(frame.position.at(frame.contact_a[c]));
      const Vector3d branch = to_vector(frame.contact_branch[c]);
      const int pieces =
          std::max(1, static_cast<int>(std::ceil(std::hypot(branch.x(), branch.y()) / piece)));
      const Tensor3 dyad = to_vector(frame.contact_force[c]) * branch.transpose() / pieces;
      for (int k = 0; k < pieces; ++k) {
        const Vector3d point = start + (k + 0.5) / pieces * branch;
        kernel_.evaluate(point.x(), point.y(), footprint_);
        for (std::size_t n = 0; n < footprint_.cells.size(); ++n) {
          sums.contact[footprint_.cells[n]] += dyad * footprint_.weights[n];
        }
      }
    }
  }

  void add_events(const dem::FlowFrame& frame, Sums& sums) {
    for (std::size_t e = 0; e < frame.event_point.size(); ++e) {
      const std::uint32_t category = frame.event_category[e];
      if (category >= settings_.categories.size()) {
        throw std::invalid_argument(
            fmt::format("a collision names contact category {}, but only {} categories are named: "
                        "pass every category of the run",
                        category, settings_.categories.size()));
      }
      kernel_.evaluate(frame.event_point[e][0], frame.event_point[e][1], footprint_);
      for (std::size_t k = 0; k < footprint_.cells.size(); ++k) {
        sums.events[category][footprint_.cells[k]] += footprint_.weights[k];
        sums.dissipated[category][footprint_.cells[k]] +=
            frame.event_dissipated[e] * footprint_.weights[k];
      }
    }
  }

  const CoarseGrainSettings& settings_;
  const Kernel& kernel_;
  Footprint footprint_;
};

// Pass 2: velocity fluctuations about the time-mean field, V(x_p) = sum_c W_c A V_c.
class SecondPass {
 public:
  SecondPass(const CoarseGrainSettings& settings, const Kernel& kernel,
             const std::vector<Vector3d>& mean_velocity)
      : settings_(settings), kernel_(kernel), mean_velocity_(mean_velocity) {}

  void add(const dem::FlowFrame& frame, Sums& sums) {
    const double area = settings_.grid.cell_area();
    for (std::size_t p = 0; p < frame.position.size(); ++p) {
      const double mass = settings_.media_density * util::sphere_volume_of_radius(frame.radius[p]);
      kernel_.evaluate(frame.position[p][0], frame.position[p][1], footprint_);
      Vector3d local_mean = Vector3d::Zero();
      for (std::size_t k = 0; k < footprint_.cells.size(); ++k) {
        local_mean += mean_velocity_[footprint_.cells[k]] * (footprint_.weights[k] * area);
      }
      const Vector3d fluctuation = to_vector(frame.velocity[p]) - local_mean;
      const Tensor3 dyad = mass * fluctuation * fluctuation.transpose();
      for (std::size_t k = 0; k < footprint_.cells.size(); ++k) {
        sums.fluctuation[footprint_.cells[k]] += dyad * footprint_.weights[k];
      }
    }
    ++sums.frames;
  }

 private:
  const CoarseGrainSettings& settings_;
  const Kernel& kernel_;
  const std::vector<Vector3d>& mean_velocity_;
  Footprint footprint_;
};

// Sums a pass over every frame: kParallelSegments segments at a time, each into its own sums,
// added in segment order (see the header on determinism). `make_pass()` gives a pass object with
// add(frame, sums), one per segment.
template <class MakePass>
Sums sum_segments(const CoarseGrainSettings& settings, std::size_t segment_count,
                  const SegmentLoader& load, MakePass make_pass) {
  const std::size_t cells = settings.grid.size(), categories = settings.categories.size();
  Sums total(cells, categories);
  for (std::size_t first = 0; first < segment_count; first += kParallelSegments) {
    const std::size_t batch = std::min(kParallelSegments, segment_count - first);
    std::vector<Sums> partial(batch, Sums(cells, categories));
    tbb::parallel_for(std::size_t{0}, batch, [&](std::size_t k) {
      auto pass = make_pass();
      for (const dem::FlowFrame& frame : load(first + k)) pass.add(frame, partial[k]);
    });
    for (const Sums& sums : partial) total += sums;
  }
  return total;
}

// dV/du at cell (i, j) along one axis (di, dj), from the neighbours where V is defined.
Vector3d derivative(const CoarseFields& f, const std::vector<std::uint8_t>& defined, int i, int j,
                    int di, int dj, double h) {
  const CrossSectionGrid& g = f.grid;
  auto usable = [&](int a, int b) {
    return a >= 0 && b >= 0 && a < g.nx && b < g.ny && defined[g.index(a, b)];
  };
  const bool plus = usable(i + di, j + dj), minus = usable(i - di, j - dj);
  const Vector3d& here = f.velocity[g.index(i, j)];
  if (plus && minus)
    return (f.velocity[g.index(i + di, j + dj)] - f.velocity[g.index(i - di, j - dj)]) / (2.0 * h);
  if (plus) return (f.velocity[g.index(i + di, j + dj)] - here) / h;
  if (minus) return (here - f.velocity[g.index(i - di, j - dj)]) / h;
  return Vector3d::Zero();
}

void compute_velocity_gradient(CoarseFields& f, double min_solid_fraction) {
  const CrossSectionGrid& g = f.grid;
  std::vector<std::uint8_t> defined(g.size());
  for (std::size_t c = 0; c < g.size(); ++c) defined[c] = f.solid_fraction[c] >= min_solid_fraction;
  f.velocity_gradient.assign(g.size(), Tensor3::Zero());
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t c = g.index(i, j);
      if (!defined[c]) continue;
      f.velocity_gradient[c].col(0) = derivative(f, defined, i, j, 1, 0, g.dx());
      f.velocity_gradient[c].col(1) = derivative(f, defined, i, j, 0, 1, g.dy());
    }
  }
}

double shear_rate_of(const Tensor3& strain_rate) {
  const Tensor3 deviator = strain_rate - strain_rate.trace() / 3.0 * Tensor3::Identity();
  return std::sqrt(2.0 * (deviator.array() * deviator.array()).sum());
}

}  // namespace

ShearPlaneTraction shear_plane_traction(const Tensor3& gradient, const Tensor3& strain_rate,
                                        const Tensor3& stress) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> principal(
      strain_rate.topLeftCorner<2, 2>().eval());
  const Eigen::Vector2d e_compress = principal.eigenvectors().col(0),
                        e_extend = principal.eigenvectors().col(1);
  const Eigen::Vector2d first = (e_extend + e_compress) / std::sqrt(2.0);
  const Eigen::Vector2d second = (e_extend - e_compress) / std::sqrt(2.0);
  const Eigen::Matrix2d in_plane_gradient = gradient.topLeftCorner<2, 2>();
  const bool second_is_layers =
      (in_plane_gradient * second).norm() > (in_plane_gradient * first).norm();
  const Eigen::Vector2d n = second_is_layers ? second : first;
  const Eigen::Vector2d t(-n.y(), n.x());
  const Eigen::Vector2d traction = stress.topLeftCorner<2, 2>() * n;
  return {-n.dot(traction), std::abs(t.dot(traction))};
}

namespace {

void derive_rates_and_stresses(CoarseFields& f, double min_solid_fraction) {
  compute_velocity_gradient(f, min_solid_fraction);
  const std::size_t cells = f.grid.size();
  f.strain_rate.resize(cells);
  f.stress.resize(cells);
  f.shear_rate.resize(cells);
  f.pressure.resize(cells);
  f.shear_plane_normal_stress.resize(cells);
  f.shear_plane_shear_stress.resize(cells);
  f.granular_temperature.assign(cells, 0.0);
  for (std::size_t c = 0; c < cells; ++c) {
    f.strain_rate[c] = 0.5 * (f.velocity_gradient[c] + f.velocity_gradient[c].transpose());
    f.stress[c] = f.kinetic_stress[c] + f.contact_stress[c];
    f.shear_rate[c] = shear_rate_of(f.strain_rate[c]);
    f.pressure[c] = -f.stress[c].trace() / 3.0;
    const ShearPlaneTraction traction =
        shear_plane_traction(f.velocity_gradient[c], f.strain_rate[c], f.stress[c]);
    f.shear_plane_normal_stress[c] = traction.normal;
    f.shear_plane_shear_stress[c] = traction.shear;
    if (f.density[c] > 0.0)
      f.granular_temperature[c] = -f.kinetic_stress[c].trace() / (3.0 * f.density[c]);
  }
}

void fill_mass_and_momentum(const Sums& sums, double per_volume_frame, CoarseFields& f) {
  const std::size_t cells = f.grid.size();
  f.solid_fraction.resize(cells);
  f.density.resize(cells);
  f.velocity.assign(cells, Vector3d::Zero());
  f.contact_stress.resize(cells);
  for (std::size_t c = 0; c < cells; ++c) {
    f.solid_fraction[c] = sums.volume[c] * per_volume_frame;
    f.density[c] = sums.mass[c] * per_volume_frame;
    if (sums.mass[c] > 0.0) f.velocity[c] = sums.momentum[c] / sums.mass[c];
    f.contact_stress[c] = sums.contact[c] * per_volume_frame;
  }
}

void fill_collision_rates(const Sums& sums, double per_volume_time, CoarseFields& f) {
  const std::size_t cells = f.grid.size();
  f.collision_frequency.assign(cells, 0.0);
  f.dissipation.assign(cells, 0.0);
  f.collision_frequency_by_category.assign(sums.events.size(), std::vector<double>(cells));
  f.dissipation_by_category.assign(sums.events.size(), std::vector<double>(cells));
  for (std::size_t k = 0; k < sums.events.size(); ++k) {
    for (std::size_t c = 0; c < cells; ++c) {
      f.collision_frequency_by_category[k][c] = sums.events[k][c] * per_volume_time;
      f.dissipation_by_category[k][c] = sums.dissipated[k][c] * per_volume_time;
      f.collision_frequency[c] += f.collision_frequency_by_category[k][c];
      f.dissipation[c] += f.dissipation_by_category[k][c];
    }
  }
}

void append_tensor_array(std::vector<CellArray>& out, const char* name,
                         const std::vector<Tensor3>& tensors) {
  CellArray array{name, 9, {}};
  array.values.reserve(tensors.size() * 9);
  for (const Tensor3& t : tensors) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) array.values.push_back(t(r, c));
    }
  }
  out.push_back(std::move(array));
}

}  // namespace

void CoarseGrainSettings::validate() const {
  auto refuse = [](const std::string& message) { throw std::invalid_argument(message); };
  if (grid.nx < 1 || grid.ny < 1)
    refuse(fmt::format("grid of {} x {} cells: give at least one cell per axis", grid.nx, grid.ny));
  if (!(grid.half_width > 0.0))
    refuse(fmt::format("mill radius {} m: must be positive", grid.half_width));
  if (!(slice_length > 0.0))
    refuse(fmt::format("slice length {} m: must be positive", slice_length));
  if (!(media_density > 0.0))
    refuse(fmt::format("media density {} kg/m^3: must be positive", media_density));
  if (!(event_window > 0.0))
    refuse(fmt::format("collision event window {} s: must be positive", event_window));
  const double cell = std::max(grid.dx(), grid.dy());
  if (!(kernel_width >= 0.5 * cell)) {
    refuse(
        fmt::format("kernel width {:.4g} m is below half the cell size {:.4g} m, so the kernel can "
                    "miss every cell "
                    "centre: use a wider kernel or more cells",
                    kernel_width, cell));
  }
}

double CoarseFields::integral(const std::vector<double>& per_cell) const {
  double sum = 0.0;
  for (double value : per_cell) sum += value;
  return sum * grid.cell_area() * slice_length;
}

double CoarseFields::solid_volume() const {
  return integral(solid_fraction);
}

CoarseFields coarse_grain(const CoarseGrainSettings& settings, std::size_t segment_count,
                          const SegmentLoader& load) {
  settings.validate();
  const Kernel kernel(settings.grid, settings.kernel_width);
  const Sums first =
      sum_segments(settings, segment_count, load, [&] { return FirstPass(settings, kernel); });
  if (first.frames == 0)
    throw std::invalid_argument("the flow sample holds no frames: sample the macro run");

  CoarseFields f;
  f.grid = settings.grid;
  f.slice_length = settings.slice_length;
  f.frame_count = first.frames;
  f.media_volume = first.particle_volume / static_cast<double>(first.frames);
  f.categories = settings.categories;
  const double per_volume_frame = 1.0 / (settings.slice_length * static_cast<double>(first.frames));
  fill_mass_and_momentum(first, per_volume_frame, f);
  fill_collision_rates(first, 1.0 / (settings.slice_length * settings.event_window), f);

  const Sums second = sum_segments(settings, segment_count, load,
                                   [&] { return SecondPass(settings, kernel, f.velocity); });
  f.kinetic_stress.resize(f.grid.size());
  for (std::size_t c = 0; c < f.grid.size(); ++c)
    f.kinetic_stress[c] = -second.fluctuation[c] * per_volume_frame;
  derive_rates_and_stresses(f, settings.min_solid_fraction_for_velocity);
  return f;
}

std::vector<CellArray> cell_arrays(const CoarseFields& f) {
  std::vector<CellArray> out;
  out.push_back({"solid_fraction", 1, f.solid_fraction});
  out.push_back({"density_kg_m3", 1, f.density});
  CellArray velocity{"velocity_m_s", 3, {}};
  for (const Vector3d& v : f.velocity)
    velocity.values.insert(velocity.values.end(), {v.x(), v.y(), v.z()});
  out.push_back(std::move(velocity));
  append_tensor_array(out, "kinetic_stress_pa", f.kinetic_stress);
  append_tensor_array(out, "contact_stress_pa", f.contact_stress);
  append_tensor_array(out, "stress_pa", f.stress);
  append_tensor_array(out, "strain_rate_per_s", f.strain_rate);
  out.push_back({"shear_rate_per_s", 1, f.shear_rate});
  out.push_back({"pressure_pa", 1, f.pressure});
  out.push_back({"normal_stress_pa", 1, f.shear_plane_normal_stress});
  out.push_back({"shear_stress_pa", 1, f.shear_plane_shear_stress});
  out.push_back({"granular_temperature_m2_s2", 1, f.granular_temperature});
  out.push_back({"collision_frequency_per_m3_s", 1, f.collision_frequency});
  out.push_back({"dissipation_w_m3", 1, f.dissipation});
  for (std::size_t k = 0; k < f.categories.size(); ++k) {
    out.push_back({"collision_frequency_per_m3_s." + f.categories[k], 1,
                   f.collision_frequency_by_category[k]});
    out.push_back({"dissipation_w_m3." + f.categories[k], 1, f.dissipation_by_category[k]});
  }
  return out;
}

}  // namespace millflow::method
