#pragma once
// Materials and per-pair interaction parameters.
//
// Users give physical quantities per material pair (restitution, friction, normal stiffness or a
// collision time); the library derives the spring-dashpot coefficients from them. Damping is
// derived per contact from the pair's effective mass, so every pair of particle sizes bounces with
// the requested coefficient of restitution.
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace millflow::dem {

using MaterialId = std::uint32_t;

struct Material {
  std::string name;
  double density = 0.0;  // kg/m^3
};

// What the user specifies for one pair of materials.
struct InteractionSpec {
  double restitution = 0.5;                       // e in (0, 1]
  double friction = 0.5;                          // Coulomb mu >= 0
  double normal_stiffness = 0.0;                  // k_n, N/m, > 0
  double tangential_stiffness_ratio = 2.0 / 7.0;  // k_t / k_n in (0, 1]
  double tangential_damping_ratio = 0.5;          // C_t / C_n in [0, 1]
};

// What the contact law uses: derived once per pair of materials.
struct PairParams {
  double normal_stiffness = 0.0;      // k_n, N/m
  double tangential_stiffness = 0.0;  // k_t, N/m
  double damping_ratio = 0.0;         // zeta of the normal dashpot, from e
  double tangential_damping_ratio = 0.0;
  double friction = 0.0;
};

// zeta = -ln e / sqrt(pi^2 + ln^2 e): the damping ratio of a linear spring-dashpot whose
// rebound/impact normal velocity ratio is e (contact ends when the overlap returns to zero).
double damping_ratio_for_restitution(double restitution);

// C_n = 2 zeta sqrt(k_n m_eff). Inline, as effective_mass below: the contact law calls both for
// every contact and step.
inline double normal_damping_coefficient(double normal_stiffness, double effective_mass,
                                         double damping_ratio) {
  return 2.0 * damping_ratio * std::sqrt(normal_stiffness * effective_mass);
}

// Contact duration t_c = pi / (omega_0 sqrt(1 - zeta^2)), omega_0 = sqrt(k_n / m_eff).
double collision_duration(double normal_stiffness, double effective_mass, double damping_ratio);

// The k_n that gives contact duration t_c for a pair of effective mass m_eff.
double stiffness_for_collision_duration(double duration, double effective_mass,
                                        double damping_ratio);

// Largest stable time step of the library's integrator on a damped linear spring (omega_0 =
// sqrt(k / m), damping ratio zeta): velocity Verlet with the dashpot on the velocity predicted for
// the step's end from the last forces, v + dt a (System::step). The largest omega_0 dt at which
// one step's amplification of (x, v, a) has spectral radius at most 1, found by bisection: 2
// undamped, about 0.83 at zeta 0.5 and 1 / (2 zeta) when heavily damped. That is about half the
// (2 / omega_0)(sqrt(1 + zeta^2) - zeta) of a dashpot on the step's velocity, which the library
// took until 7 December 2026 and which let contacts damped near the critical (restitution 1e-7)
// grow without end.
double stable_time_step_limit(double normal_stiffness, double effective_mass, double damping_ratio);

// The largest stable step of a pair's contact: the smaller of its normal oscillator's limit and
// its tangential one's. The tangential spring k_t and dashpot C_t = tangential_damping_ratio C_n
// act on the contact points, whose effective mass is 2/7 m_eff (solid spheres roll: each adds
// 5/2 to its 1/m; against a wall m_eff is the sphere's mass). With the default k_t = 2/7 k_n it
// oscillates at omega_0 with a damping ratio 7/2 C_t / C_n times the normal one (1.75 times at
// C_t = C_n / 2): near the critical (restitution 1e-7) it, not the normal one, bounds the step,
// and a step inside the normal limit alone let a sticking contact's velocity grow without end.
double pair_stable_time_step_limit(const PairParams& params, double effective_mass);

// m_a m_b / (m_a + m_b); a wall is infinitely heavy: pass a non-positive m_b for a wall.
inline double effective_mass(double mass_a, double mass_b) {
  if (mass_b <= 0.0) return mass_a;
  return mass_a * mass_b / (mass_a + mass_b);
}

// Checks a spec and derives the contact-law parameters. Throws std::invalid_argument naming the
// pair and the bad value.
PairParams derive_pair_params(const InteractionSpec& spec, const std::string& pair_name);

class MaterialTable {
 public:
  // Throws std::invalid_argument on an empty or duplicate name or a density out of (0, inf).
  MaterialId add(const Material& material);
  // Sets the interaction of materials a and b (symmetric).
  void set_interaction(MaterialId a, MaterialId b, const InteractionSpec& spec);

  std::size_t size() const { return materials_.size(); }
  const Material& material(MaterialId id) const { return materials_.at(id); }
  MaterialId find(const std::string& name) const;  // throws if unknown
  bool has_interaction(MaterialId a, MaterialId b) const;
  const PairParams& pair(MaterialId a, MaterialId b) const { return pairs_[index(a, b)]; }
  const InteractionSpec& interaction(MaterialId a, MaterialId b) const {
    return specs_[index(a, b)];
  }
  std::string pair_name(MaterialId a, MaterialId b) const;

 private:
  std::size_t index(MaterialId a, MaterialId b) const { return a * materials_.size() + b; }
  void grow_pair_table(std::size_t old_size);

  std::vector<Material> materials_;
  std::vector<PairParams> pairs_;       // size() x size(), symmetric
  std::vector<InteractionSpec> specs_;  // what pairs_ was derived from
  std::vector<char> defined_;
};

}  // namespace millflow::dem
