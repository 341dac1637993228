#include "dem/material.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>
#include <Eigen/Eigenvalues>

namespace millflow::dem {

double damping_ratio_for_restitution(double restitution) {
  const double log_e = std::log(restitution);
  return -log_e / std::sqrt(std::numbers::pi * std::numbers::pi + log_e * log_e);
}

double collision_duration(double normal_stiffness, double effective_mass, double damping_ratio) {
  const double omega0 = std::sqrt(normal_stiffness / effective_mass);
  return std::numbers::pi / (omega0 * std::sqrt(1.0 - damping_ratio * damping_ratio));
}

double stiffness_for_collision_duration(double duration, double effective_mass,
                                        double damping_ratio) {
  const double omega0 =
      std::numbers::pi / (duration * std::sqrt(1.0 - damping_ratio * damping_ratio));
  return effective_mass * omega0 * omega0;
}

namespace {

// The spectral radius of one step of the integrator on x'' = -x - 2 zeta v (omega_0 = 1) at step
// h, acting on (x, v, a): the half kick and drift, the predicted velocity v + h a, the new force,
// the closing half kick.
double step_amplification(double zeta, double h) {
  Eigen::Matrix3d step;
  step << 1.0, h, 0.5 * h * h,                                                            // x
      -0.5 * h, 1.0 - 0.5 * h * h - zeta * h, 0.5 * h - 0.25 * h * h * h - zeta * h * h,  // v
      -1.0, -h - 2.0 * zeta, -0.5 * h * h - 2.0 * zeta * h;                               // a
  return step.eigenvalues().cwiseAbs().maxCoeff();
}

// The largest stable omega_0 dt: 2 undamped (the eigenvalues on the unit circle, where rounding
// would put the bisection's test on either side), else by bisection to a double's precision.
double stable_omega_dt(double zeta) {
  if (zeta == 0.0) return 2.0;
  double stable = 0.0, unstable = 2.0;
  for (int k = 0; k < 64; ++k) {
    const double h = 0.5 * (stable + unstable);
    (step_amplification(zeta, h) <= 1.0 ? stable : unstable) = h;
  }
  return stable;
}

}  // namespace

double stable_time_step_limit(double normal_stiffness, double effective_mass,
                              double damping_ratio) {
  return stable_omega_dt(damping_ratio) / std::sqrt(normal_stiffness / effective_mass);
}

double pair_stable_time_step_limit(const PairParams& params, double effective_mass) {
  const double contact_point_mass = 2.0 / 7.0 * effective_mass;
  const double tangential_damping =
      params.tangential_damping_ratio *
      normal_damping_coefficient(params.normal_stiffness, effective_mass, params.damping_ratio);
  const double tangential_damping_ratio =
      tangential_damping / (2.0 * std::sqrt(params.tangential_stiffness * contact_point_mass));
  return std::min(
      stable_time_step_limit(params.normal_stiffness, effective_mass, params.damping_ratio),
      stable_time_step_limit(params.tangential_stiffness, contact_point_mass,
                             tangential_damping_ratio));
}

PairParams derive_pair_params(const InteractionSpec& spec, const std::string& pair_name) {
  auto fail = [&](const std::string& what) {
    throw std::invalid_argument(fmt::format("interaction {}: {}", pair_name, what));
  };
  if (!(spec.restitution > 0.0 && spec.restitution <= 1.0)) {
    fail(fmt::format(
        "restitution = {} is outside (0, 1]; give the ratio of rebound to impact normal speed",
        spec.restitution));
  }
  if (!(spec.friction >= 0.0) || !std::isfinite(spec.friction)) {
    fail(fmt::format("friction = {} must be a finite number >= 0", spec.friction));
  }
  if (!(spec.normal_stiffness > 0.0) || !std::isfinite(spec.normal_stiffness)) {
    fail(fmt::format("normal stiffness = {} N/m must be a finite number > 0",
                     spec.normal_stiffness));
  }
  if (!(spec.tangential_stiffness_ratio > 0.0 && spec.tangential_stiffness_ratio <= 1.0)) {
    fail(fmt::format("tangential stiffness ratio = {} is outside (0, 1]; 2/7 is usual for spheres",
                     spec.tangential_stiffness_ratio));
  }
  if (!(spec.tangential_damping_ratio >= 0.0 && spec.tangential_damping_ratio <= 1.0)) {
    fail(fmt::format("tangential damping ratio = {} is outside [0, 1]",
                     spec.tangential_damping_ratio));
  }
  return PairParams{.normal_stiffness = spec.normal_stiffness,
                    .tangential_stiffness = spec.tangential_stiffness_ratio * spec.normal_stiffness,
                    .damping_ratio = damping_ratio_for_restitution(spec.restitution),
                    .tangential_damping_ratio = spec.tangential_damping_ratio,
                    .friction = spec.friction};
}

MaterialId MaterialTable::add(const Material& material) {
  if (material.name.empty()) throw std::invalid_argument("material: the name is empty");
  for (const auto& m : materials_) {
    if (m.name == material.name) {
      throw std::invalid_argument(fmt::format("material '{}' is defined twice", material.name));
    }
  }
  if (!(material.density > 0.0) || !std::isfinite(material.density)) {
    throw std::invalid_argument(fmt::format("material '{}': density = {} kg/m^3 must be > 0",
                                            material.name, material.density));
  }
  const std::size_t old_size = materials_.size();
  materials_.push_back(material);
  grow_pair_table(old_size);
  return static_cast<MaterialId>(old_size);
}

void MaterialTable::grow_pair_table(std::size_t old_size) {
  const std::size_t n = materials_.size();
  std::vector<PairParams> pairs(n * n);
  std::vector<InteractionSpec> specs(n * n);
  std::vector<char> defined(n * n, 0);
  for (std::size_t a = 0; a < old_size; ++a) {
    for (std::size_t b = 0; b < old_size; ++b) {
      pairs[a * n + b] = pairs_[a * old_size + b];
      specs[a * n + b] = specs_[a * old_size + b];
      defined[a * n + b] = defined_[a * old_size + b];
    }
  }
  pairs_ = std::move(pairs);
  specs_ = std::move(specs);
  defined_ = std::move(defined);
}

void MaterialTable::set_interaction(MaterialId a, MaterialId b, const InteractionSpec& spec) {
  if (a >= size() || b >= size()) {
    throw std::invalid_argument(fmt::format(
        "interaction: material id {} or {} is not defined ({} materials)", a, b, size()));
  }
  const PairParams params = derive_pair_params(spec, pair_name(a, b));
  pairs_[index(a, b)] = pairs_[index(b, a)] = params;
  specs_[index(a, b)] = specs_[index(b, a)] = spec;
  defined_[index(a, b)] = defined_[index(b, a)] = 1;
}

MaterialId MaterialTable::find(const std::string& name) const {
  for (std::size_t i = 0; i < materials_.size(); ++i) {
    if (materials_[i].name == name) return static_cast<MaterialId>(i);
  }
  throw std::invalid_argument(fmt::format("material '{}' is not defined", name));
}

bool MaterialTable::has_interaction(MaterialId a, MaterialId b) const {
  return a < size() && b < size() && defined_[index(a, b)] != 0;
}

std::string MaterialTable::pair_name(MaterialId a, MaterialId b) const {
  return fmt::format("{}-{}", materials_.at(a).name, materials_.at(b).name);
}

}  // namespace millflow::dem
