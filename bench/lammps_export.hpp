#pragma once
// What the benchmarks hand LAMMPS to run the same state (bench/lammps/): an atom_style sphere data
// file (type 1 media, i.e. material 0; type 2 everything else) and a file of `variable` lines.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "dem/material.hpp"
#include "dem/system.hpp"

namespace millflow::bench {

// A scene's parameters for LAMMPS, written as `variable` lines.
struct LammpsParams {
  std::vector<std::pair<std::string, double>> values;
  std::vector<std::string> notes;  // written as comments
  void set(const std::string& name, double value) { values.emplace_back(name, value); }
};

// LAMMPS's gran/hooke dashpot is m_eff * gamma * v: gamma = 2 zeta sqrt(k_n / m_eff) gives our
// C_n = 2 zeta sqrt(k_n m_eff) exactly for that one m_eff.
inline double lammps_gamma(const dem::InteractionSpec& spec, double m_eff) {
  return 2.0 * dem::damping_ratio_for_restitution(spec.restitution) *
         std::sqrt(spec.normal_stiffness / m_eff);
}

// kn, kt, gamman, gammat and xmu of gran/hooke/history, each name prefixed.
inline void add_contact_params(LammpsParams& out, const std::string& prefix,
                               const dem::InteractionSpec& spec, double m_eff) {
  const double gamma_n = lammps_gamma(spec, m_eff);
  out.set(prefix + "kn", spec.normal_stiffness);
  out.set(prefix + "kt", spec.tangential_stiffness_ratio * spec.normal_stiffness);
  out.set(prefix + "gamman", gamma_n);
  out.set(prefix + "gammat", spec.tangential_damping_ratio * gamma_n);
  out.set(prefix + "xmu", spec.friction);
}

// The first ball (material 0, LAMMPS type 1) and the first powder grain (any other material, type
// 2) of a system; system.size() for a kind it lacks. The cells renumber their particles along a
// space-filling curve, so the kinds are looked up, not taken at index 0.
struct FirstOfKinds {
  std::size_t ball;
  std::size_t grain;
};
inline FirstOfKinds first_of_kinds(const dem::System& system) {
  const auto materials = system.particle_materials();
  const auto index_of = [&](auto it) { return static_cast<std::size_t>(it - materials.begin()); };
  return {index_of(std::find(materials.begin(), materials.end(), dem::MaterialId{0})),
          index_of(std::find_if(materials.begin(), materials.end(),
                                [](dem::MaterialId m) { return m != 0; }))};
}

// A media + powder system's contact parameters per pair of LAMMPS types (write_lammps_data's:
// type 1 material 0, the media; type 2 the powder), prefixed mm_, mp_ and pp_, each pair's
// gamma_n for the effective mass of its two particles: with one size per type, pair_style
// granular's mass_velocity damping (m_eff gamma_n v_n) is then millflow's C_n v_n for every pair.
// Also each pair's restitution (mm_e, mp_e, pp_e) and media_ and powder_ diameter and density.
// False (nothing set) without media or without powder.
inline bool add_pair_type_params(LammpsParams& out, const dem::System& system) {
  const auto [ball, grain] = first_of_kinds(system);
  if (ball == system.size() || grain == system.size()) return false;
  const double ball_mass = system.masses()[ball], grain_mass = system.masses()[grain];
  const dem::MaterialTable& table = system.materials();
  const dem::MaterialId powder = system.particle_materials()[grain];
  const std::array<std::pair<std::string, const dem::InteractionSpec*>, 3> pairs{
      {{"mm_", &table.interaction(0, 0)},
       {"mp_", &table.interaction(0, powder)},
       {"pp_", &table.interaction(powder, powder)}}};
  const std::array<double, 3> effective_masses{
      0.5 * ball_mass, dem::effective_mass(ball_mass, grain_mass), 0.5 * grain_mass};
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    add_contact_params(out, pairs[k].first, *pairs[k].second, effective_masses[k]);
    out.set(pairs[k].first + "e", pairs[k].second->restitution);
  }
  for (const auto& [kind, p] : {std::pair{std::string("media_"), ball}, {"powder_", grain}}) {
    const double diameter = 2.0 * system.radii()[p];
    out.set(kind + "diameter", diameter);
    out.set(kind + "density",
            system.masses()[p] / (std::numbers::pi * diameter * diameter * diameter / 6.0));
  }
  return true;
}

inline void write_lammps_data(const dem::System& s, const std::string& name,
                              const std::filesystem::path& path) {
  const dem::Domain& d = s.domain();
  std::ofstream out(path);
  out << fmt::format("millflow scene {} (warm state, t = {} s)\n\n{} atoms\n2 atom types\n\n", name,
                     s.time(), s.size());
  out << fmt::format("{:.17g} {:.17g} xlo xhi\n{:.17g} {:.17g} ylo yhi\n{:.17g} {:.17g} zlo zhi\n",
                     d.lo.x(), d.hi.x(), d.lo.y(), d.hi.y(), d.lo.z(), d.hi.z());
  if (d.lees_edwards.enabled) {
    // LAMMPS keeps the tilt in [-L/2, L/2]; the images are the same modulo L.
    const double length = d.length().x();
    double tilt = std::fmod(d.lees_edwards.offset, length);
    if (tilt > 0.5 * length) tilt -= length;
    out << fmt::format("{:.17g} 0 0 xy xz yz\n", tilt);
  }
  out << "\nAtoms # sphere\n\n";
  for (std::size_t p = 0; p < s.size(); ++p) {
    const double diameter = 2.0 * s.radii()[p];
    const double density =
        s.masses()[p] / (std::numbers::pi * diameter * diameter * diameter / 6.0);
    const dem::Vec3& x = s.positions()[p];
    out << fmt::format("{} {} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", p + 1,
                       s.particle_materials()[p] == 0 ? 1 : 2, diameter, density, x.x(), x.y(),
                       x.z());
  }
  out << "\nVelocities\n\n";
  for (std::size_t p = 0; p < s.size(); ++p) {
    const dem::Vec3& v = s.velocities()[p];
    const dem::Vec3& w = s.angular_velocities()[p];
    out << fmt::format("{} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", p + 1, v.x(), v.y(),
                       v.z(), w.x(), w.y(), w.z());
  }
  if (!out) throw std::runtime_error(fmt::format("could not write {}", path.string()));
}

inline void write_lammps_params(const std::string& name, const std::string& description,
                                const LammpsParams& params, const std::filesystem::path& path) {
  std::ofstream out(path);
  out << fmt::format("# millflow scene {}: {}\n", name, description);
  for (const std::string& note : params.notes) out << "# " << note << "\n";
  for (const auto& [variable, value] : params.values)
    out << fmt::format("variable {} equal {:.17g}\n", variable, value);
  if (!out) throw std::runtime_error(fmt::format("could not write {}", path.string()));
}

}  // namespace millflow::bench
