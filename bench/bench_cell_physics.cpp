// Shear-cell physics against the outside world (issue 12, "Check it against the outside world";
// the measured tables are in docs/cell_validation.md). Not a timing benchmark: it runs whole cells
// (compaction, warm-up to stationarity, measurement to convergence) through the campaign's code
// path (tasks::shear_cell_setup, tasks::apply_stiffness_policy, tasks::shear_cell_protocol,
// dem::ShearCellRun) and prints these tables:
//
//   1 stiffness  a media-only cell and a cell with powder (--powder_ratio d at --load) at the
//                policy's default stiffness and at --stiffer_factor x it (or at each of
//                --stiffness_factors x it, for the convergence to rigid particles): friction (tau /
//                p_yy), friction_mean_pressure (tau / p), the powder's share of the dissipation and
//                the cushioning (media-media dissipation with powder / without), each with its
//                standard error, and the difference in units of the combined standard error.
//                --stiffness_pairs picks the pairs the factors multiply, --media_kappa floors the
//                balls' k_n / (sigma_n d_m) first (the policy's media_rigidity), and
//                --dissipation_probe_every splits each cell's dissipation by term and contact age.
//   2 mu(I)      the media-only cell at inertial numbers --inertial_numbers (the shear rate set
//                from I at the site's normal stress), against Jop, Forterre & Pouliquen (Nature
//                441, 2006): mu(I) = mu_s + (mu_2 - mu_s) / (1 + I_0 / I), fitted three ways
//                (weighted by the friction's standard error): mu_s alone with their glass
//                beads' mu_2 - mu_s = 0.26 and I_0 = 0.279 held; mu_s and mu_2 - mu_s with I_0
//                held; mu_s and I_0 with mu_2 - mu_s held.
//   3 dilute     the cell at powder load --dilute_load against the media-only one, at the site's
//                rate and again with the media-only cell's rate set so that its measured I
//                equals the dilute cell's.
//   4 walls      the rough-wall cell at the site against the Lees-Edwards cell run at the wall
//                cell's measured bulk inertial number (bulk rate fitted over the middle half of
//                the gap, wall load as the normal stress).
//   5 overlap    a cell with powder --overlap_ratio d at --overlap_load, at the policy's default
//                stiffness, for its overlaps per contact type (mean, p95, max), with the
//                protocol's strains scaled by --overlap_strain_factor (fine powder is costly).
//   6 lammps     (with --lammps_dir) a media-only Lees-Edwards cell brought to a stationary state
//                at --lammps_inertial_number, its state and contact parameters written for
//                bench/lammps/in.cell_physics, then sheared on at FIXED volume for
//                --lammps_strain, the stress tensor written every --lammps_sample_every steps
//                (bench/run_cell_physics_comparison.sh runs both and compares). With
//                --lammps_load > 0 the cell holds powder (--powder_ratio d at that load, as
//                table 1's), its parameters are written per pair of types for
//                bench/lammps/in.cell_physics_mixture, and every --lammps_contact_every steps the
//                contact stress, contacts and mean overlap by pair type are written as well.
//                --lammps_pairs_only: only the pair collisions (head-on and oblique) of the
//                cell's pair types and the parameters in.restitution_pair needs, from the cell
//                as placed (seconds instead of the preparation's minutes), at the cell's dt
//                over --lammps_pair_refine (the integrators' share of a difference).
//                --lammps_dt_refine R: millflow's run at the cell's dt / R (LAMMPS's stays at
//                the cell's dt; under stress control the barostat's interval R times as many
//                steps), its rows still numbered in the cell's steps.
//                --lammps_stress_control: both codes shear on holding the normal stress instead of
//                the volume (millflow under the cell's own barostat, LAMMPS under its
//                Nose-Hoover barostat on y, fix nph/sphere), the solid fraction written with each
//                stress sample; the sample interval is then the first from
//                --lammps_sample_every prime to the barostat's interval, and the contact interval
//                the first multiple of it from --lammps_contact_every.
//
// The scene is campaigns/cement_ball_mill.json's cell (50 mm steel balls, clinker powder, steel
// 7800 and clinker 3150 kg/m^3, Lees-Edwards, stiffness policy "overlap_bound") at a site of
// --shear_rate and --normal_stress; --size sets the cell (in ball diameters), the strains and the
// convergence target scale the run up, --steps_per_collision sets every cell's time step.
// Standard errors are the cells' batch means; a ratio's is propagated from its two parts as if
// independent (the dissipation terms of one cell are positively correlated, so the share's error
// is overstated).
//
//   bench_cell_physics [--tables 1,2,3] [--size 5 6 5] [--threads 1] ...  (--help lists all)
#include <tbb/task_arena.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "bench/lammps_export.hpp"
#include "bench/process_measures.hpp"
#include "dem/contact_categories.hpp"
#include "dem/pair_collision.hpp"
#include "dem/shear_cell.hpp"
#include "dem/stiffness_policy.hpp"
#include "dem/stress_control.hpp"
#include "method/sites.hpp"
#include "tasks/campaign.hpp"
#include "tasks/shear_cell.hpp"
#include "util/sphere.hpp"

namespace {

using namespace millflow;
using bench::process_cpu_seconds;
using nlohmann::json;

// Jop, Forterre & Pouliquen 2006, glass beads: mu_2 - mu_s and I_0 (their mu_s = 0.38 and
// mu_2 = 0.64).
constexpr double kJfpFrictionRise = 0.64 - 0.38;
constexpr double kJfpInertialNumber = 0.279;

struct Options {
  std::vector<int> tables{1, 2, 3};
  std::vector<double> size{5, 6, 5};
  int threads = 1;
  double shear_rate = 10.0;               // 1/s, tables 1, 3, 4 and 5
  double normal_stress = 2e4;             // Pa
  double powder_ratio = 0.25;             // powder / ball diameter
  double load = 1.0;                      // table 1's powder load
  double dilute_load = 0.01;              // table 3's
  double stiffer_factor = 4.0;            // table 1's second stiffness, x the policy's
  std::vector<double> stiffness_factors;  // table 1's stiffnesses, x the policy's (a sequence)
  // Which pairs table 1's factors multiply: all, powder (media-powder and powder-powder), media
  // (media-media), media_powder, powder_powder.
  std::string stiffness_pairs = "all";
  // > 0: every cell's media-media k_n raised to at least this k_n / (sigma_n d_m) after the
  // policy and before the factors (a rigidity bound for the balls, a candidate default).
  double media_kappa = 0.0;
  // Table 1: each cell's measured dissipation split by term and by contact age (probes every
  // this many steps; 0: off).
  std::uint64_t dissipation_probe_every = 0;
  std::vector<double> inertial_numbers{0.01, 0.03, 0.1, 0.2, 0.3};
  double overlap_ratio = 0.125;  // table 5's powder
  double overlap_load = 0.05;
  // Not 4 d along z: a Lees-Edwards cell 4 d wide stacks its FCC planes d apart
  // (docs/cell_validation.md).
  std::vector<double> overlap_size{5, 5, 5};
  double overlap_strain_factor = 0.25;  // table 5's strains, x the protocol's
  double warmup_strain = 1.0, max_warmup_strain = 3.0;
  double measure_strain = 2.0, max_strain = 4.0;
  double standard_error = 0.03;
  std::uint64_t seed = 1;
  std::optional<std::filesystem::path> lammps_dir;  // table 6
  double lammps_inertial_number = 0.1;
  double lammps_strain = 10.0;
  int lammps_sample_every = 50;
  double lammps_load = 0.0;            // table 6's powder load (0: media only)
  int lammps_contact_every = 500;      // table 6 with powder: contacts by pair type, every this
  bool lammps_pairs_only = false;      // table 6 with powder: the pair collisions alone
  double lammps_pair_refine = 1.0;     // ... at the cell's dt over this
  int steps_per_collision = 0;         // every cell's /shear_cell/steps_per_collision (0: default)
  int lammps_dt_refine = 1;            // table 6: millflow's fixed-volume run at dt over this
  bool lammps_stress_control = false;  // table 6: both codes hold the normal stress, not the volume
  double wall_speed = 0.0;             // table 4 open loop: > 0 holds the walls at this speed, m/s
  double open_loop_strain = 8.0;       // table 4 open loop: strain after compaction
  // Table 4: both cells run the rough walls' protocol (dem::kRoughWallStrains) unless a strain
  // flag was given, and at 8 x 10 x 8 d unless --size was given (at 5 x 6 x 5 the wall cell's
  // tau / p_yy sits about 5% below its own at 8 x 10 x 8 and 12 x 10 x 12, the Lees-Edwards
  // cell's does not: docs/cell_validation.md, table 4 a seventh time).
  bool wall_strains = true;
  bool wall_size = true;
  // Table 4: > 0 sets both cells' media-media (and wall) contacts to k_n = this x p d in place
  // of the stiffness policy's (the servo's stiffness sweep).
  double wall_kappa = 0.0;
};

struct Cell {
  double powder_load = 0.0;
  double shear_rate = 0.0;
  double stiffness_factor = 1.0;
  std::string stiffness_pairs = "all";  // which pairs stiffness_factor multiplies (Options)
  bool walls = false;
  double powder_ratio = 0.0;       // 0: Options::powder_ratio
  std::vector<double> size = {};   // empty: Options::size
  double strain_factor = 1.0;      // x every strain of the protocol
  double exact_media_kappa = 0.0;  // > 0: media-media k_n / (p d), in place of the policy's
};

// Table 1's --dissipation_probe_every: where a cell's measured dissipation goes. Over the window,
// by contact type and term (normal dashpot, tangential dashpot, Coulomb sliding) from the
// system's dissipation by category. And from one-step probes, by the age of the contact in
// binary collision times t_c of its pair (pi / omega_0 / sqrt(1 - zeta^2), the particles' own
// masses): under 1.5 t_c a collision (a binary contact ends at t_c), above it a contact held by
// more than its own impact (enduring), in three classes. A probe reads every contact's
// dissipation before and after one step; a contact that ends within the step is missed.
class DissipationProbe {
 public:
  static constexpr std::array<double, 3> kAgeEdges{1.5, 5.0, 20.0};  // x t_c
  static constexpr std::size_t kAges = kAgeEdges.size() + 1;

  void start(const dem::System& system) { window0_ = system.dissipation_by_category(); }
  void finish(const dem::System& system) { window1_ = system.dissipation_by_category(); }

  void snapshot(const dem::System& system) {
    before_.clear();
    time0_ = system.time();
    const auto pairs = system.candidate_pairs();
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      if (!system.pair_touching(k)) continue;
      const dem::ContactHistory& h = system.pair_history(k);
      before_[key(pairs[k].i, pairs[k].j)] = {h.dissipated, h.start_time};
    }
  }

  void add_step(const dem::ShearCell& cell) {
    const dem::System& system = cell.system();
    const auto pairs = system.candidate_pairs();
    const auto mass = system.masses();
    const auto material = system.particle_materials();
    const double now = system.time(), dt = now - time0_;
    probes_ += 1.0;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      if (!system.pair_touching(k)) continue;
      const std::uint32_t i = pairs[k].i, j = pairs[k].j;
      const dem::ContactHistory& h = system.pair_history(k);
      dem::Dissipation step = h.dissipated;
      if (h.start_time < time0_) {  // touching before the step: only the step's part
        const auto it = before_.find(key(i, j));
        if (it == before_.end() || it->second.start_time != h.start_time) {
          ++lost_;
          continue;
        }
        step -= it->second.dissipated;
      }
      const dem::PairParams& pp = system.materials().pair(material[i], material[j]);
      const double m_eff = dem::effective_mass(mass[i], mass[j]);
      const double t_c = dem::collision_duration(pp.normal_stiffness, m_eff, pp.damping_ratio);
      const double age = (now - h.start_time) / t_c;
      const std::size_t a = static_cast<std::size_t>(
          std::upper_bound(kAgeEdges.begin(), kAgeEdges.end(), age) - kAgeEdges.begin());
      const auto t = static_cast<std::size_t>(
          cell.contact_type(system.pair_category(material[i], material[j])));
      Bin& b = bins_[t][a];
      b.dissipated += step;
      b.contacts += 1.0;
      // C_n v_n^2 dt is the normal dashpot's: the mean v_n^2 over the class's contact-steps.
      if (h.normal_damping > 0.0) b.vn2_sum += step.normal / (h.normal_damping * dt);
    }
  }

  // `m`: the cell's measurements, for the rates (its dissipation density by type, W/m^3).
  void print(const dem::ShearCell& cell, const dem::ShearCellMeasurements& m) const {
    double total = 0.0;
    std::array<dem::Dissipation, dem::kContactTypeCount> by_type{};
    for (std::size_t c = 0; c < window1_.size() && c < window0_.size(); ++c) {
      dem::Dissipation d = window1_[c];
      d -= window0_[c];
      by_type[static_cast<std::size_t>(cell.contact_type(static_cast<std::uint32_t>(c)))] += d;
      total += d.total();
    }
    if (total <= 0.0) return;
    fmt::print(
        "    dissipation over the window, % of the cell's, and W/m^3 (the type's rate "
        "split as its terms): type: normal dashpot, tangential dashpot, sliding (total)\n");
    for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) {
      const dem::Dissipation& d = by_type[t];
      if (d.total() <= 0.0) continue;
      const double rate = m.dissipation_density[t] / d.total();
      fmt::print(
          "      {:<14} {:6.2f} {:6.2f} {:6.2f}  ({:6.2f})   {:9.4g} {:9.4g} {:9.4g}  "
          "({:9.4g})\n",
          dem::contact_type_name(static_cast<dem::ContactType>(t)), 100.0 * d.normal / total,
          100.0 * d.tangential / total, 100.0 * d.friction / total, 100.0 * d.total() / total,
          rate * d.normal, rate * d.tangential, rate * d.friction, m.dissipation_density[t]);
    }
    fmt::print(
        "    probes ({:.0f} steps, {} contacts lost to a renumbering): by age in t_c of the pair, "
        "contacts per step, % of the type's probed dissipation, of it % normal / tangential / "
        "sliding, rms v_n m/s\n",
        probes_, lost_);
    for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) {
      double type_total = 0.0;
      for (const Bin& b : bins_[t]) type_total += b.dissipated.total();
      if (type_total <= 0.0) continue;
      fmt::print("      {:<14}", dem::contact_type_name(static_cast<dem::ContactType>(t)));
      for (std::size_t a = 0; a < kAges; ++a) {
        const Bin& b = bins_[t][a];
        const double d = b.dissipated.total();
        const std::string label =
            a == 0 ? fmt::format("<{:g}", kAgeEdges[0])
                   : (a == kAges - 1 ? fmt::format(">{:g}", kAgeEdges[a - 1])
                                     : fmt::format("{:g}-{:g}", kAgeEdges[a - 1], kAgeEdges[a]));
        fmt::print(" | {} {:.0f} {:.1f}% ({:.0f}/{:.0f}/{:.0f}) {:.2e}", label,
                   b.contacts / probes_, 100.0 * d / type_total,
                   d > 0.0 ? 100.0 * b.dissipated.normal / d : 0.0,
                   d > 0.0 ? 100.0 * b.dissipated.tangential / d : 0.0,
                   d > 0.0 ? 100.0 * b.dissipated.friction / d : 0.0,
                   b.contacts > 0.0 ? std::sqrt(b.vn2_sum / b.contacts) : 0.0);
      }
      fmt::print("\n");
    }
  }

 private:
  struct Before {
    dem::Dissipation dissipated;
    double start_time = 0.0;
  };
  struct Bin {
    dem::Dissipation dissipated;
    double contacts = 0.0, vn2_sum = 0.0;
  };
  static std::uint64_t key(std::uint32_t i, std::uint32_t j) {
    return (static_cast<std::uint64_t>(i) << 32) | j;
  }
  std::vector<dem::Dissipation> window0_, window1_;
  std::unordered_map<std::uint64_t, Before> before_;
  double time0_ = 0.0, probes_ = 0.0;
  std::size_t lost_ = 0;
  std::array<std::array<Bin, kAges>, dem::kContactTypeCount> bins_{};
};

// What a finished cell reports.
struct CellResult {
  dem::ShearCellMeasurements m;
  std::size_t particles = 0;
  double media_kappa = 0.0;  // k_n / (p d) of media-media contacts
  double cpu_seconds = 0.0;
};

json campaign_for(const Options& o, const Cell& c) {
  json campaign = tasks::load_campaign(std::filesystem::path(MILLFLOW_SOURCE_DIR) / "campaigns" /
                                       "cement_ball_mill.json");
  campaign.erase("sweep");
  campaign["dem"]["seed"] = o.seed;
  json& cell = campaign["shear_cell"];
  cell["boundary"] = c.walls ? "walls" : "lees_edwards";
  cell["size_diameters"] = c.size.empty() ? o.size : c.size;
  cell["powder"]["diameter_ratio"] = c.powder_ratio > 0.0 ? c.powder_ratio : o.powder_ratio;
  cell["powder"]["load"] = c.powder_load;
  const double f = c.strain_factor;
  cell["warmup_strain"] = f * o.warmup_strain;
  cell["max_warmup_strain"] = f * o.max_warmup_strain;
  cell["measure_strain"] = f * o.measure_strain;
  cell["convergence"] = {{"standard_error", o.standard_error}, {"max_strain", f * o.max_strain}};
  if (o.steps_per_collision > 0) cell["steps_per_collision"] = o.steps_per_collision;
  return tasks::validate_campaign(campaign);
}

// The shear rate that puts a cell of ball diameter d and density rho at inertial number I.
double shear_rate_for(const Options& o, double inertial_number) {
  const json campaign = campaign_for(o, {});
  const double diameter = campaign["media"]["diameter"].get<double>();
  const double density = campaign["materials"]["steel"]["density"].get<double>();
  return inertial_number * std::sqrt(o.normal_stress / density) / diameter;
}

dem::ShearCellSetup setup_for(const Options& o, const Cell& c, const json& campaign) {
  const json site = method::CellDrive{.shear_rate = c.shear_rate, .normal_stress = o.normal_stress};
  dem::ShearCellSetup setup = tasks::shear_cell_setup(campaign, site, "bench_cell_physics");
  for (const dem::PairStiffness& p : tasks::apply_stiffness_policy(campaign, setup))
    fmt::print(
        "    stiffness {:<14} k_n {:.4g} N/m ({}: given {:.4g}, static {:.4g}, impact {:.4g})\n",
        p.pair, p.chosen, p.governing, p.given, p.static_bound, p.impact_bound);
  if (o.media_kappa > 0.0) {
    const double rigid = o.media_kappa * setup.normal_stress * setup.media_diameter;
    setup.media_media.normal_stiffness = std::max(setup.media_media.normal_stiffness, rigid);
    fmt::print("    media-media k_n {:.4g} N/m after --media_kappa {:g}\n",
               setup.media_media.normal_stiffness, o.media_kappa);
  }
  const std::string& which = c.stiffness_pairs;  // checked by the option's IsMember
  if (which == "all" || which == "media") setup.media_media.normal_stiffness *= c.stiffness_factor;
  if (which == "all" || which == "powder" || which == "media_powder")
    setup.media_powder.normal_stiffness *= c.stiffness_factor;
  if (which == "all" || which == "powder" || which == "powder_powder")
    setup.powder_powder.normal_stiffness *= c.stiffness_factor;
  if (c.exact_media_kappa > 0.0)
    setup.media_media.normal_stiffness =
        c.exact_media_kappa * setup.normal_stress * setup.media_diameter;
  return setup;
}

void print_overlaps(const dem::ShearCellMeasurements& m) {
  for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) {
    const dem::OverlapStats& s = m.overlaps[t];
    if (s.contacts == 0.0) continue;
    fmt::print("    overlap {:<14} mean {:.4f} p95 {:.4f} max {:.4f} of d_s ({:.3g} samples)\n",
               dem::contact_type_name(static_cast<dem::ContactType>(t)), s.mean_fraction,
               s.p95_fraction, s.max_fraction, s.contacts);
  }
}

CellResult run_cell(const Options& o, const Cell& c) {
  const json campaign = campaign_for(o, c);
  const dem::ShearCellSetup setup = setup_for(o, c, campaign);
  CellResult result;
  result.media_kappa =
      setup.media_media.normal_stiffness / (setup.normal_stress * setup.media_diameter);
  const double cpu_start = process_cpu_seconds();
  dem::ShearCellRun run(setup, tasks::shear_cell_protocol(campaign));
  tbb::task_arena arena(o.threads);
  DissipationProbe probe;
  arena.execute([&] {
    if (o.dissipation_probe_every == 0) {
      while (!run.advance(100000)) {
      }
      return;
    }
    // In pieces of the probe interval: the window's dissipation by term from its first piece
    // (the measurement starts within the piece before; off by at most one piece of a window of
    // 1e5 steps and more), a probe of one step after each piece.
    bool measuring = false;
    while (!run.advance(o.dissipation_probe_every)) {
      if (run.phase_name() != "measuring") continue;
      if (!measuring) probe.start(run.cell().system());
      measuring = true;
      probe.snapshot(run.cell().system());
      if (run.advance(1)) break;
      probe.add_step(run.cell());
    }
    probe.finish(run.cell().system());
  });
  result.cpu_seconds = process_cpu_seconds() - cpu_start;
  result.m = run.measurements();
  result.particles = run.cell().system().size();
  const auto& m = result.m;
  fmt::print(
      "  cell {} load {:g}, {:.4g} 1/s, stiffness x{:g} (media k_n/(p d) {:.3g}): {} particles, "
      "{} steps of {:.4g} s, {:.1f} CPU s; I {:.3g}, p_yy {:.4g} Pa, p {:.4g} Pa, solid fraction "
      "{:.4f}, "
      "stationary strain {}, measured strain {:.2f}, steady {}, converged {}, overlap ok {}, "
      "energy balance {:.2g}\n",
      c.walls ? "walls" : "LE", c.powder_load, c.shear_rate, c.stiffness_factor, result.media_kappa,
      result.particles, run.cell().system().step_count(), run.cell().system().time_step(),
      result.cpu_seconds, m.inertial_number, m.normal_stress, m.mean_pressure,
      m.media_solid_fraction + m.powder_solid_fraction,
      m.stationary ? fmt::format("{:.2f}", m.stationary_strain) : std::string("none"), m.strain,
      m.steady, m.converged, m.overlap_ok, m.energy_balance_error);
  if (c.walls) {
    fmt::print(
        "    walls: bulk rate {:.4g} 1/s (target {:.4g}), wall slip {:.3g} m/s, gap {:.4g} m\n",
        m.bulk_shear_rate, m.target_shear_rate, m.wall_slip, m.gap);
  }
  fmt::print(
      "    tau / p_yy {:.4f} +- {:.4f}, tau / p {:.4f} +- {:.4f}, dissipation {:.4g} W/m^3 of "
      "which powder {:.4g} +- {:.3g}, media-media {:.4g} +- {:.3g}\n",
      m.friction, m.friction_error.standard_error, m.friction_mean_pressure,
      m.friction_mean_pressure_error.standard_error, m.dissipation_density_total,
      m.powder_dissipation_error.mean, m.powder_dissipation_error.standard_error,
      m.dissipation_density[static_cast<std::size_t>(dem::ContactType::MediaMedia)],
      m.dissipation_standard_error[static_cast<std::size_t>(dem::ContactType::MediaMedia)]);
  print_overlaps(m);
  if (o.dissipation_probe_every > 0) probe.print(run.cell(), m);
  std::fflush(stdout);
  return result;
}

struct Value {
  double mean = 0.0, error = 0.0;
};

Value ratio(Value a, Value b) {
  const double r = a.mean / b.mean;
  return {r, std::abs(r) * std::hypot(a.error / a.mean, b.error / b.mean)};
}

Value friction(const CellResult& r) {
  return {r.m.friction, r.m.friction_error.standard_error};
}
Value friction_mean_pressure(const CellResult& r) {
  return {r.m.friction_mean_pressure, r.m.friction_mean_pressure_error.standard_error};
}
Value media_dissipation(const CellResult& r) {
  const auto k = static_cast<std::size_t>(dem::ContactType::MediaMedia);
  return {r.m.dissipation_density[k], r.m.dissipation_standard_error[k]};
}
Value powder_share(const CellResult& r) {
  return ratio({r.m.powder_dissipation_error.mean, r.m.powder_dissipation_error.standard_error},
               {r.m.dissipation_density_total, r.m.dissipation_total_error.standard_error});
}

// Difference b - a in units of the combined standard error.
double separation(Value a, Value b) {
  return (b.mean - a.mean) / std::hypot(a.error, b.error);
}

void print_header(const std::string& first, const std::string& second) {
  fmt::print("  {:<24} {:>21} {:>21} {:>8} {:>8}\n", "quantity", first, second, "diff/se",
             "diff %");
}

void print_row(const std::string& name, Value a, Value b) {
  fmt::print("  {:<24} {:>9.4f} +- {:<8.4f} {:>9.4f} +- {:<8.4f} {:>+8.1f} {:>+8.1f}\n", name,
             a.mean, a.error, b.mean, b.error, separation(a, b),
             100.0 * (b.mean - a.mean) / a.mean);
}

void stiffness_table(const Options& o) {
  fmt::print(
      "\nTable 1: stiffness sensitivity ({:g} 1/s, {:g} Pa, powder {:g} d at load {:g}; the "
      "factors multiply the {} pairs)\n",
      o.shear_rate, o.normal_stress, o.powder_ratio, o.load, o.stiffness_pairs);
  // The factors, x the policy's default; without --stiffness_factors the default and
  // --stiffer_factor x it.
  const std::vector<double> factors = o.stiffness_factors.empty()
                                          ? std::vector<double>{1.0, o.stiffer_factor}
                                          : o.stiffness_factors;
  std::vector<CellResult> media, powder;
  for (double factor : factors) {
    media.push_back(run_cell(o, {.shear_rate = o.shear_rate,
                                 .stiffness_factor = factor,
                                 .stiffness_pairs = o.stiffness_pairs}));
    powder.push_back(run_cell(o, {.powder_load = o.load,
                                  .shear_rate = o.shear_rate,
                                  .stiffness_factor = factor,
                                  .stiffness_pairs = o.stiffness_pairs}));
  }
  // Each factor against the one before (the first pair: the policy's default against x4).
  for (std::size_t i = 1; i < factors.size(); ++i) {
    fmt::print("\n");
    print_header(factors[i - 1] == 1.0 ? std::string("policy default")
                                       : fmt::format("x{:g}", factors[i - 1]),
                 fmt::format("x{:g}", factors[i]));
    const std::size_t a = i - 1, b = i;
    print_row("friction media-only", friction(media[a]), friction(media[b]));
    print_row("friction powder", friction(powder[a]), friction(powder[b]));
    print_row("friction_mean_p media", friction_mean_pressure(media[a]),
              friction_mean_pressure(media[b]));
    print_row("friction_mean_p powder", friction_mean_pressure(powder[a]),
              friction_mean_pressure(powder[b]));
    print_row("powder dissipation share", powder_share(powder[a]), powder_share(powder[b]));
    print_row("cushioning", ratio(media_dissipation(powder[a]), media_dissipation(media[a])),
              ratio(media_dissipation(powder[b]), media_dissipation(media[b])));
  }
  if (factors.size() < 3) return;
  // The sequence, for a fit Q(k) = Q_rigid + a k^-beta.
  fmt::print("\n  {:<8} {:>18} {:>18} {:>18} {:>18} {:>8}\n", "factor", "friction powder",
             "friction_mean_p", "powder share", "cushioning", "CPU s");
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const Value q[4] = {friction(powder[i]), friction_mean_pressure(powder[i]),
                        powder_share(powder[i]),
                        ratio(media_dissipation(powder[i]), media_dissipation(media[i]))};
    fmt::print("  {:<8g}", factors[i]);
    for (const Value& v : q) fmt::print(" {:>8.4f} +- {:<6.4f}", v.mean, v.error);
    fmt::print(" {:>8.1f}\n", powder[i].cpu_seconds);
  }
}

// The JFP form's rise at inertial number I: (mu_2 - mu_s) / (1 + I_0 / I), per unit mu_2 - mu_s.
double jfp_shape(double inertial, double reference) {
  return 1.0 / (1.0 + reference / inertial);
}

struct Fit {
  double mu_s = 0.0, rise = 0.0, reference = 0.0;  // mu_s, mu_2 - mu_s, I_0
  double mu_s_error = 0.0, free_error = 0.0;       // of mu_s and of the second free parameter
  double chi2 = 0.0;
  double model(double inertial) const { return mu_s + rise * jfp_shape(inertial, reference); }
};

struct Point {
  double inertial = 0.0, friction = 0.0, error = 0.0;
};

double chi2_of(const Fit& fit, const std::vector<Point>& points) {
  double chi2 = 0.0;
  for (const Point& p : points) chi2 += std::pow((p.friction - fit.model(p.inertial)) / p.error, 2);
  return chi2;
}

// Weighted least squares of mu = mu_s + rise x shape(I) with I_0 = reference held; with
// fit_rise false the rise is held as well. Errors from the covariance (1 / sum of weights for
// mu_s alone).
Fit fit_linear(const std::vector<Point>& points, double rise, double reference, bool fit_rise) {
  double sw = 0.0, sx = 0.0, sxx = 0.0, sy = 0.0, sxy = 0.0;
  for (const Point& p : points) {
    const double w = 1.0 / (p.error * p.error), x = jfp_shape(p.inertial, reference);
    sw += w;
    sx += w * x;
    sxx += w * x * x;
    sy += w * p.friction;
    sxy += w * x * p.friction;
  }
  Fit fit{.rise = rise, .reference = reference};
  if (fit_rise) {
    const double det = sw * sxx - sx * sx;
    fit.rise = (sw * sxy - sx * sy) / det;
    fit.mu_s = (sy - fit.rise * sx) / sw;
    fit.mu_s_error = std::sqrt(sxx / det);
    fit.free_error = std::sqrt(sw / det);
  } else {
    fit.mu_s = (sy - rise * sx) / sw;
    fit.mu_s_error = 1.0 / std::sqrt(sw);
  }
  fit.chi2 = chi2_of(fit, points);
  return fit;
}

// mu_s and I_0 with the rise held: I_0 scanned on a logarithmic grid (mu_s linear at each), its
// error where chi^2 rises by 1 from the minimum.
Fit fit_reference(const std::vector<Point>& points, double rise) {
  constexpr int kGrid = 4000;
  const double lo = std::log(1e-3), hi = std::log(1e2);
  std::vector<Fit> grid;
  for (int k = 0; k <= kGrid; ++k)
    grid.push_back(fit_linear(points, rise, std::exp(lo + (hi - lo) * k / kGrid), false));
  const auto best = std::min_element(grid.begin(), grid.end(),
                                     [](const Fit& a, const Fit& b) { return a.chi2 < b.chi2; });
  double low = best->reference, high = best->reference;
  for (const Fit& f : grid) {
    if (f.chi2 > best->chi2 + 1.0) continue;
    low = std::min(low, f.reference);
    high = std::max(high, f.reference);
  }
  Fit fit = *best;
  fit.free_error = 0.5 * (high - low);
  return fit;
}

void inertial_number_table(const Options& o) {
  fmt::print("\nTable 2: mu(I), media only, Lees-Edwards, {:g} Pa\n", o.normal_stress);
  std::vector<CellResult> cells;
  std::vector<Point> points;
  for (const double inertial : o.inertial_numbers) {
    cells.push_back(run_cell(o, {.shear_rate = shear_rate_for(o, inertial)}));
    const auto& m = cells.back().m;
    points.push_back({m.inertial_number, m.friction, m.friction_error.standard_error});
  }
  const std::size_t n = points.size();
  const Fit held = fit_linear(points, kJfpFrictionRise, kJfpInertialNumber, false);
  const Fit rise = fit_linear(points, 0.0, kJfpInertialNumber, true);
  const Fit reference = fit_reference(points, kJfpFrictionRise);
  fmt::print("  {:>8} {:>8} {:>9} {:>21} {:>21} {:>8} {:>8} {:>8} {:>8}\n", "I target", "I", "phi",
             "tau/p_yy", "tau/p", "fit A", "res/se A", "res/se B", "res/se C");
  for (std::size_t i = 0; i < n; ++i) {
    const auto& m = cells[i].m;
    const Point& p = points[i];
    const auto pull = [&](const Fit& f) { return (p.friction - f.model(p.inertial)) / p.error; };
    fmt::print(
        "  {:>8.3g} {:>8.3g} {:>9.4f} {:>9.4f} +- {:<8.4f} {:>9.4f} +- {:<8.4f} {:>8.4f} "
        "{:>+8.1f} {:>+8.1f} {:>+8.1f}\n",
        o.inertial_numbers[i], p.inertial, m.media_solid_fraction, p.friction, p.error,
        m.friction_mean_pressure, m.friction_mean_pressure_error.standard_error,
        held.model(p.inertial), pull(held), pull(rise), pull(reference));
  }
  fmt::print(
      "  A: mu_s = {:.4f} +- {:.4f}, mu_2 - mu_s = {:.3f} and I_0 = {:.3f} held (JFP glass: mu_s "
      "0.38): chi^2 = {:.1f} over {} dof\n",
      held.mu_s, held.mu_s_error, kJfpFrictionRise, kJfpInertialNumber, held.chi2, n - 1);
  fmt::print(
      "  B: mu_s = {:.4f} +- {:.4f}, mu_2 - mu_s = {:.3f} +- {:.3f}, I_0 = {:.3f} held: chi^2 = "
      "{:.1f} over {} dof\n",
      rise.mu_s, rise.mu_s_error, rise.rise, rise.free_error, kJfpInertialNumber, rise.chi2, n - 2);
  fmt::print(
      "  C: mu_s = {:.4f} +- {:.4f}, I_0 = {:.3f} +- {:.3f} (chi^2 + 1), mu_2 - mu_s = {:.3f} "
      "held: chi^2 = {:.1f} over {} dof\n",
      reference.mu_s, reference.mu_s_error, reference.reference, reference.free_error,
      kJfpFrictionRise, reference.chi2, n - 2);
}

void dilute_table(const Options& o) {
  fmt::print(
      "\nTable 3: dilute powder ({:g} d at load {:g}) against media only, {:g} 1/s, {:g} Pa\n",
      o.powder_ratio, o.dilute_load, o.shear_rate, o.normal_stress);
  const CellResult dilute = run_cell(o, {.powder_load = o.dilute_load, .shear_rate = o.shear_rate});
  const CellResult media = run_cell(o, {.shear_rate = o.shear_rate});
  // I = gdot d sqrt(rho / p_yy): the media-only cell again at the rate that gives it the dilute
  // cell's measured I, if its normal stress stays where it was.
  const double matched_rate = o.shear_rate * dilute.m.inertial_number / media.m.inertial_number;
  const CellResult matched = run_cell(o, {.shear_rate = matched_rate});
  fmt::print("  I: dilute {:.4f}, media only {:.4f} at the site's rate, {:.4f} at {:.4g} 1/s\n",
             dilute.m.inertial_number, media.m.inertial_number, matched.m.inertial_number,
             matched_rate);
  print_header("media only", fmt::format("load {:g}", o.dilute_load));
  print_row("friction (site rate)", friction(media), friction(dilute));
  print_row("friction_mean_p (site)", friction_mean_pressure(media),
            friction_mean_pressure(dilute));
  print_row("friction (equal I)", friction(matched), friction(dilute));
  print_row("friction_mean_p (eq. I)", friction_mean_pressure(matched),
            friction_mean_pressure(dilute));
  // The barostat's bias differs from run to run, so the second media-only cell may miss the
  // dilute cell's I too; when the two bracket it, the media-only friction is interpolated
  // linearly in I (errors combined with the interpolation weights).
  const double i0 = media.m.inertial_number, i1 = matched.m.inertial_number;
  const double w = (dilute.m.inertial_number - i0) / (i1 - i0);
  if (w < 0.0 || w > 1.0) return;
  const auto interpolate = [w](Value a, Value b) {
    return Value{(1.0 - w) * a.mean + w * b.mean, std::hypot((1.0 - w) * a.error, w * b.error)};
  };
  print_row("friction (interpolated)", interpolate(friction(media), friction(matched)),
            friction(dilute));
  print_row("friction_mean_p (interp)",
            interpolate(friction_mean_pressure(media), friction_mean_pressure(matched)),
            friction_mean_pressure(dilute));
}

void walls_table(const Options& options) {
  Options o = options;
  if (o.wall_strains) {
    o.warmup_strain = dem::kRoughWallStrains.warmup_strain;
    o.max_warmup_strain = dem::kRoughWallStrains.max_warmup_strain;
    o.measure_strain = o.max_strain = dem::kRoughWallStrains.measure_strain;
  }
  if (o.wall_size) o.size = {8.0, 10.0, 8.0};
  fmt::print(
      "\nTable 4: rough walls against Lees-Edwards at the walls' bulk inertial number ({:g} 1/s, "
      "{:g} Pa; {:g} x {:g} x {:g} d; strains warm-up {:g} (max {:g}), measure {:g} (max "
      "{:g}){})\n",
      o.shear_rate, o.normal_stress, o.size[0], o.size[1], o.size[2], o.warmup_strain,
      o.max_warmup_strain, o.measure_strain, o.max_strain,
      o.wall_strains ? ", the rough walls' protocol" : "");
  const CellResult walls =
      run_cell(o, {.shear_rate = o.shear_rate, .walls = true, .exact_media_kappa = o.wall_kappa});
  const CellResult le = run_cell(o, {.shear_rate = shear_rate_for(o, walls.m.inertial_number),
                                     .exact_media_kappa = o.wall_kappa});
  fmt::print("  wall load / target {:.4f}\n", walls.m.normal_stress / o.normal_stress);
  fmt::print("  I: walls {:.4f} (bulk rate, wall load), Lees-Edwards {:.4f}\n",
             walls.m.inertial_number, le.m.inertial_number);
  print_header("Lees-Edwards", "rough walls");
  print_row("friction", friction(le), friction(walls));
  print_row("friction_mean_p", friction_mean_pressure(le), friction_mean_pressure(walls));
  // The same ratio from the stress tensor alone (-xy / yy of the virial), which does not use the
  // wall load; the window's mean, without a standard error.
  const auto virial_friction = [](const CellResult& r) {
    return -r.m.stress_tensor[3] / r.m.stress_tensor[1];
  };
  fmt::print("  {:<24} {:>9.4f} {:>24.4f} {:>19} {:>+8.1f}\n", "virial -xy/yy", virial_friction(le),
             virial_friction(walls), "",
             100.0 * (virial_friction(walls) - virial_friction(le)) / virial_friction(le));
  fmt::print("  virial yy: Lees-Edwards {:.4g} Pa, rough walls {:.4g} Pa (wall load {:.4g} Pa)\n",
             le.m.stress_tensor[1], walls.m.stress_tensor[1], walls.m.normal_stress);
}

// Table 4 open loop (--wall_speed): the rough-wall cell compacted, then sheared with the walls held
// at one relative speed U (the servo still holds the normal stress; no wall-speed controller),
// every 0.5 strain (target rate x time) a line: the bulk rate (least squares over the middle half
// of the gap, mass-weighted, as the cell's), the wall friction tau / p from the wall loads, the
// slip of each wall against the bulk profile extended to it, and the solid fraction; at the end
// the velocity and solid-fraction profile across the gap in 10 slabs over the last half.
void walls_open_loop(const Options& o) {
  const Cell c{.shear_rate = o.shear_rate, .walls = true};
  const json campaign = campaign_for(o, c);
  const dem::ShearCellSetup setup = setup_for(o, c, campaign);
  fmt::print("\nTable 4 open loop: rough walls at U = {:g} m/s ({:g} 1/s target, {:g} Pa)\n",
             o.wall_speed, o.shear_rate, o.normal_stress);
  const double cpu_start = process_cpu_seconds();
  dem::ShearCell cell(setup);
  cell.compact();
  dem::System& s = cell.system();
  const dem::GroupId bottom = 1, top = 2;
  s.group(bottom).velocity.x() = -0.5 * o.wall_speed;
  s.group(top).velocity.x() = 0.5 * o.wall_speed;
  const double d = setup.media_diameter, area = cell.wall_area();
  const auto plane = [&](dem::GroupId g) {
    double y = 0.0, n = 0.0;
    for (std::size_t p = 0; p < s.size(); ++p)
      if (s.particle_groups()[p] == g) y += s.positions()[p].y(), n += 1.0;
    return y / n;
  };
  constexpr int kSlabs = 10;
  std::array<double, kSlabs> slab_mv{}, slab_m{}, slab_volume{};
  double slab_samples = 0.0;
  const int windows = static_cast<int>(std::lround(o.open_loop_strain / 0.5));
  fmt::print(
      "  strain  bulk rate  bulk/nominal  tau/p(walls)  p_wall/target  slip bottom, top  solid\n");
  for (int w = 0; w < windows; ++w) {
    double sw = 0, swy = 0, swyy = 0, swv = 0, swyv = 0, tau = 0, load = 0, solid = 0, yb = 0,
           yt = 0;
    constexpr int kSamples = 20;
    for (int k = 0; k < kSamples; ++k) {
      // The wall loads every step (read once per sample they would be read in step with the
      // servo's interval, and read high).
      const double step_strain = setup.shear_rate * s.time_step();
      const auto steps = static_cast<int>(std::ceil(0.5 / kSamples / step_strain));
      for (int n = 0; n < steps; ++n) {
        cell.run_strain(0.5 * step_strain);  // one step
        const auto& fb = s.group_load(bottom).force;
        const auto& ft = s.group_load(top).force;
        tau += 0.5 * (fb.x() - ft.x()) / area / (kSamples * steps);
        load -= 0.5 * (fb.y() - ft.y()) / area / (kSamples * steps);
      }
      const double y0 = plane(bottom), y1 = plane(top), h = y1 - y0;
      yb += y0 / kSamples, yt += y1 / kSamples;
      double volume = 0.0;
      for (std::size_t p = 0; p < s.size(); ++p) {
        if (s.particle_groups()[p] != dem::kFreeParticle) continue;
        const double y = s.positions()[p].y() - y0, m = s.masses()[p], v = s.velocities()[p].x();
        const double r = s.radii()[p];
        if (2 * w >= windows) {
          const int b = std::clamp(static_cast<int>(y / h * kSlabs), 0, kSlabs - 1);
          slab_mv[b] += m * v, slab_m[b] += m;
          slab_volume[b] += 4.0 / 3.0 * std::numbers::pi * r * r * r / (area * h / kSlabs);
        }
        if (y < 0.25 * h || y >= 0.75 * h) continue;
        sw += m, swy += m * y, swyy += m * y * y, swv += m * v, swyv += m * y * v;
        volume += 4.0 / 3.0 * std::numbers::pi * r * r * r;
      }
      if (2 * w >= windows) slab_samples += 1.0;
      solid += volume / (area * 0.5 * h) / kSamples;
    }
    const double rate = (sw * swyv - swy * swv) / (sw * swyy - swy * swy);
    const double h = yt - yb, mid_v = (swv - rate * (swy - 0.5 * h * sw)) / sw;
    const double slip_bottom = (mid_v - 0.5 * rate * h) - (-0.5 * o.wall_speed);
    const double slip_top = 0.5 * o.wall_speed - (mid_v + 0.5 * rate * h);
    fmt::print(
        "  {:5.1f}  {:8.3f}   {:8.3f}      {:8.4f}      {:8.3f}       {:6.3f}, {:6.3f}    {:.4f}\n",
        0.5 * (w + 1), rate, rate * h / o.wall_speed, tau / load, load / setup.normal_stress,
        slip_bottom, slip_top, solid);
    std::fflush(stdout);
  }
  fmt::print("  profile over the last half (slab centre / gap, v_x / (U/2), solid fraction):\n");
  for (int b = 0; b < kSlabs; ++b)
    fmt::print("    {:.2f}  {:+.3f}  {:.3f}\n", (b + 0.5) / kSlabs,
               slab_mv[b] / slab_m[b] / (0.5 * o.wall_speed), slab_volume[b] / slab_samples);
  fmt::print("  {:.1f} CPU s, d {:g} m\n", process_cpu_seconds() - cpu_start, d);
}

void overlap_table(const Options& o) {
  fmt::print(
      "\nTable 5: overlaps, powder {:g} d at load {:g}, cell {} x {} x {} d, policy default ({:g} "
      "1/s, {:g} Pa; bound: p95 <= 0.03 of d_s)\n",
      o.overlap_ratio, o.overlap_load, o.overlap_size[0], o.overlap_size[1], o.overlap_size[2],
      o.shear_rate, o.normal_stress);
  run_cell(o, {.powder_load = o.overlap_load,
               .shear_rate = o.shear_rate,
               .powder_ratio = o.overlap_ratio,
               .size = o.overlap_size,
               .strain_factor = o.overlap_strain_factor});
}

// Components of a stress tensor in LAMMPS's order of its pressure vector: xx yy zz xy xz yz.
constexpr std::array<std::array<int, 2>, 6> kComponents{
    {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}}};

// The stress of contacts whose virial (sum of F b^T, System::contact_virial's) is `virial`, in a
// volume, compression positive, symmetrised, in kComponents' order.
std::array<double, 6> contact_stress(const Eigen::Matrix3d& virial, double volume) {
  std::array<double, 6> stress{};
  for (std::size_t k = 0; k < 6; ++k) {
    const auto [a, b] = kComponents[k];
    stress[k] = -0.5 * (virial(a, b) + virial(b, a)) / volume;
  }
  return stress;
}

// Stress tensor of an LE system now, compression positive (kComponents' order): the contacts'
// virial plus the kinetic part of the motion relative to the linear profile (zero at
// mid-height), over the box volume.
std::array<double, 6> stress_tensor(const dem::System& s, double shear_rate) {
  const dem::Domain& d = s.domain();
  const double y_mid = d.lo.y() + 0.5 * d.length().y(), volume = d.length().prod();
  std::array<double, 6> stress = contact_stress(s.contact_virial(), volume);
  for (std::size_t p = 0; p < s.size(); ++p) {
    const dem::Vec3 c =
        s.velocities()[p] - dem::Vec3(shear_rate * (s.positions()[p].y() - y_mid), 0.0, 0.0);
    for (std::size_t k = 0; k < 6; ++k) {
      const auto [a, b] = kComponents[k];
      stress[k] += s.masses()[p] * c[a] * c[b] / volume;
    }
  }
  return stress;
}

// A line of table 6's contacts file (millflow_contacts.txt; the LAMMPS side writes the same
// columns): the step, then per pair type, media-media, media-powder, powder-powder: its contacts,
// their mean overlap / smaller diameter and their stress (contact_stress).
std::string contacts_by_pair_type(std::uint64_t step, const dem::System& s,
                                  dem::MaterialId powder) {
  const std::vector<dem::CategoryContacts> sums = dem::contacts_by_category(s);
  const double volume = s.domain().length().prod();
  std::string line = fmt::format("{}", step);
  for (const std::uint32_t category :
       {s.pair_category(0, 0), s.pair_category(0, powder), s.pair_category(powder, powder)}) {
    const dem::CategoryContacts& c = sums[category];
    line +=
        fmt::format(" {} {:.8g}", c.contacts,
                    c.contacts > 0 ? c.overlap_fraction / static_cast<double>(c.contacts) : 0.0);
    for (const double v : contact_stress(c.virial, volume)) line += fmt::format(" {:.10g}", v);
  }
  return line + "\n";
}

// A particle like `a` of `cell` meeting one like `b` (their radii and materials) at the cell's
// time step over `refine`, `tangential` m/s across the line of centres (dem/pair_collision.hpp).
dem::Rebound pair_rebound(const dem::System& cell, std::size_t a, std::size_t b, double tangential,
                          double refine) {
  return dem::pair_rebound(cell.materials(), {.radius_a = cell.radii()[a],
                                              .radius_b = cell.radii()[b],
                                              .material_a = cell.particle_materials()[a],
                                              .material_b = cell.particle_materials()[b],
                                              .tangential_speed = tangential,
                                              .time_step = cell.time_step() / refine});
}

// System's default skin: 0.6 x the smallest radius.
double default_skin(const dem::System& system) {
  return 0.6 * *std::min_element(system.radii().begin(), system.radii().end());
}

// The tangential speeds of the oblique collisions: one where the contact sticks and its spring
// turns the contact points' motion back, one where it slides throughout (a sliding contact takes
// mu (1 + e) 7/2 of the normal speed off the tangential one: 2.5-3.4 m/s at this cell's friction
// 0.6-0.75 and restitution 0.2-0.3).
constexpr std::array kObliqueSpeeds{1.0, 5.0};

// Per pair of types, the contact parameters the cell's material table holds (exported for
// LAMMPS) and the pair's collisions at the cell's dt over `refine`: head-on, then oblique.
void add_and_check_pair_types(const dem::System& system, bench::LammpsParams& params,
                              double refine) {
  bench::add_pair_type_params(params, system);
  fmt::print("    exported per pair of types:");
  for (const auto& [name, value] : params.values) fmt::print(" {} {:.5g}", name, value);
  fmt::print("\n");
  const auto materials = system.particle_materials();
  const auto [ball, grain] = bench::first_of_kinds(system);
  const dem::MaterialId powder = materials[grain];
  const std::array<std::pair<const char*, std::array<std::size_t, 2>>, 3> pairs{
      {{"mm", {ball, ball}}, {"mp", {ball, grain}}, {"pp", {grain, grain}}}};
  const std::array<double, 3> table{system.materials().interaction(0, 0).restitution,
                                    system.materials().interaction(0, powder).restitution,
                                    system.materials().interaction(powder, powder).restitution};
  fmt::print(
      "    restitution of a head-on collision at 1 m/s at this dt / {:g} (material table's):",
      refine);
  for (std::size_t k = 0; k < pairs.size(); ++k)
    fmt::print(" {} {:.6f} ({:g})", pairs[k].first,
               pair_rebound(system, pairs[k].second[0], pairs[k].second[1], 0.0, refine).normal,
               table[k]);
  fmt::print("\n");
  for (const double tangential : kObliqueSpeeds) {
    fmt::print("    oblique, 1 m/s normal and {:g} m/s tangential (rebound normal, tangential):",
               tangential);
    for (const auto& [name, ab] : pairs) {
      const dem::Rebound r = pair_rebound(system, ab[0], ab[1], tangential, refine);
      fmt::print(" {} {:.6f} {:.6f}", name, r.normal, r.tangential);
    }
    fmt::print("\n");
  }
}

void lammps_table(const Options& o) {
  if (!o.lammps_dir) throw std::invalid_argument("table 6 needs --lammps_dir");
  if (o.lammps_load > 0.0 &&
      (o.lammps_contact_every <= 0 || o.lammps_contact_every % o.lammps_sample_every != 0))
    throw std::invalid_argument(
        "--lammps_contact_every must be a multiple of --lammps_sample_every");
  const std::filesystem::path& dir = *o.lammps_dir;
  std::filesystem::create_directories(dir);
  const bool with_powder = o.lammps_load > 0.0;
  const Cell c{.powder_load = o.lammps_load,
               .shear_rate = shear_rate_for(o, o.lammps_inertial_number)};
  fmt::print(
      "\nTable 6: {} {} for LAMMPS (I {:g}, {:.4g} 1/s, {:g} Pa, {:g} strains, files in {})\n",
      o.lammps_stress_control ? "stress-controlled" : "fixed-volume",
      with_powder
          ? fmt::format("cell with powder {:g} d at load {:g}", o.powder_ratio, o.lammps_load)
          : std::string("media cell"),
      o.lammps_inertial_number, c.shear_rate, o.normal_stress, o.lammps_strain, dir.string());
  const json campaign = campaign_for(o, c);
  const dem::ShearCellSetup setup = setup_for(o, c, campaign);
  dem::ShearCellRun run(setup, tasks::shear_cell_protocol(campaign));
  if (o.lammps_pairs_only) {
    if (!with_powder) throw std::invalid_argument("--lammps_pairs_only needs --lammps_load > 0");
    const dem::System& placed = run.cell().system();
    bench::LammpsParams params;
    add_and_check_pair_types(placed, params, o.lammps_pair_refine);
    params.set("dt", placed.time_step());
    params.set("skin", default_skin(placed));
    bench::write_lammps_params("cell_physics", "bench_cell_physics, pair types of a cell", params,
                               dir / "cell_physics.params");
    return;
  }
  tbb::task_arena arena(o.threads);
  arena.execute([&] {
    while (run.phase_name() != "measuring") run.advance(1000);
  });
  dem::System system = run.cell().system();
  const double length_y = system.domain().length().y();
  const double particle_volume = [&] {
    double volume = 0.0;
    for (const double r : system.radii()) volume += util::sphere_volume_of_radius(r);
    return volume;
  }();
  const double solid_fraction = particle_volume / system.domain().length().prod();
  // LAMMPS's temp/deform takes the streaming profile as zero at the bottom of the box; ours is
  // zero at mid-height. A uniform shift of every velocity (Galilean) puts LAMMPS's copy in its
  // frame without changing its dynamics.
  dem::System shifted = system;
  for (std::size_t p = 0; p < shifted.size(); ++p)
    shifted.set_velocity(p,
                         shifted.velocities()[p] + dem::Vec3(0.5 * c.shear_rate * length_y, 0, 0));
  // Under stress control the samples fall on every phase of the barostat's interval, as the
  // cells' own do (dem::sample_interval_across_control_phases), and the contact rows on samples.
  const std::uint64_t sample_every =
      o.lammps_stress_control ? dem::sample_interval_across_control_phases(
                                    static_cast<std::uint64_t>(o.lammps_sample_every),
                                    run.cell().stress_control().settings().interval_steps)
                              : static_cast<std::uint64_t>(o.lammps_sample_every);
  const std::uint64_t contact_every =
      (static_cast<std::uint64_t>(o.lammps_contact_every) + sample_every - 1) / sample_every *
      sample_every;
  const auto steps =
      static_cast<std::uint64_t>(std::ceil(o.lammps_strain / (c.shear_rate * system.time_step()) /
                                           static_cast<double>(sample_every)) *
                                 static_cast<double>(sample_every));
  const auto materials = system.particle_materials();
  const auto powder_count = static_cast<std::size_t>(
      std::count_if(materials.begin(), materials.end(), [](dem::MaterialId m) { return m != 0; }));
  const std::size_t grain = bench::first_of_kinds(system).grain;
  const dem::MaterialId powder = grain < system.size() ? materials[grain] : dem::MaterialId{0};
  if (with_powder && powder_count == 0)
    throw std::runtime_error("table 6: the cell with powder holds no powder");
  bench::LammpsParams params;
  if (with_powder) {
    add_and_check_pair_types(system, params, 1.0);
    params.set("contact_every", static_cast<double>(contact_every));
    params.set("media_count", static_cast<double>(system.size() - powder_count));
    params.set("powder_count", static_cast<double>(powder_count));
    params.set("volume", system.domain().length().prod());
    params.notes.push_back(
        "bench_cell_physics table 6 with powder: fixed volume; pair_style granular per pair of "
        "types, mass_velocity damping exact for each (one size per type)");
  } else {
    bench::add_contact_params(params, "", setup.media_media, 0.5 * system.masses()[0]);
    params.notes.push_back(
        "bench_cell_physics table 6: fixed volume; one pair type, so gran/hooke/history's "
        "gamma_n is exact");
  }
  params.set("dt", system.time_step());
  params.set("skin", default_skin(system));
  params.set("shear_rate", c.shear_rate);
  params.set("nsteps", static_cast<double>(steps));
  params.set("sample_every", static_cast<double>(sample_every));
  params.set("solid_fraction", solid_fraction);
  params.set("particle_volume", particle_volume);
  // Under stress control LAMMPS holds p_yy either with its Nose-Hoover barostat on y (nph/sphere:
  // LAMMPS has no first-order barostat for a triclinic box), of period the barostat's relaxation
  // time and a drag that damps the box's oscillation, another law than millflow's; or with
  // millflow's own law (dem/stress_control.hpp, LeesEdwardsBarostat) as a loop of runs that
  // stretches the box between them (bench/lammps/stretch_barostat.lmp), whose constants follow.
  // The interval is the cell's at its own dt (LAMMPS runs at it whatever --lammps_dt_refine).
  const dem::StressControlSettings& control = run.cell().stress_control().settings();
  params.set("stress_control", o.lammps_stress_control ? 1.0 : 0.0);
  params.set("target_stress", control.target_stress);
  params.set("relaxation_time", control.relaxation_time);
  params.set("barostat_drag", 1.0);
  params.set("barostat_interval", static_cast<double>(control.interval_steps));
  params.set("barostat_part_strain", control.part_strain);
  params.set("barostat_stretch_every", static_cast<double>(dem::kBarostatStretchEvery));
  params.set("barostat_bed_modulus", dem::kFlowingBedModulus);
  params.set("barostat_integral_times", dem::kBarostatIntegralTimes);
  params.set("barostat_max_dilation", dem::kBarostatMaxDilation);
  params.set("barostat_max_integral", dem::IntegralTerm::kMaxIntegralRate);
  bench::write_lammps_data(shifted, "cell_physics", dir / "cell_physics.data");
  bench::write_lammps_params("cell_physics",
                             with_powder ? "bench_cell_physics, media + powder LE cell"
                                         : "bench_cell_physics, media-only LE cell",
                             params, dir / "cell_physics.params");
  // Our side: the same state sheared on at fixed volume (the System alone: no barostat), or under
  // the cell's barostat (a copy of the cell, which carries its control's state).
  std::ofstream out(dir / "millflow_stress.txt");
  out << "# step pxx pyy pzz pxy pxz pyz (Pa, compression positive) solid_fraction\n";
  std::optional<dem::ShearCell> held;
  if (o.lammps_stress_control) held.emplace(run.cell());
  dem::System& sheared = held ? held->system() : system;
  std::ofstream contacts;
  if (with_powder) {
    contacts.open(dir / "millflow_contacts.txt");
    contacts << "# step, then per pair type (media-media, media-powder, powder-powder): contacts, "
                "mean overlap / smaller diameter, contact stress xx yy zz xy xz yz (Pa)\n";
  }
  // At a fraction of the cell's dt (the integrator's share of a difference), the same strain and
  // samples: the rows keep the cell's step numbers, which the reduction turns into strain.
  const auto refine = static_cast<std::uint64_t>(o.lammps_dt_refine);
  if (held)
    held->refine_time_step(o.lammps_dt_refine);
  else
    sheared.set_time_step(sheared.time_step() / static_cast<double>(refine));
  const double cpu_start = process_cpu_seconds();
  arena.execute([&] {
    for (std::uint64_t step = 0; step <= steps; step += sample_every) {
      if (step > 0 && held) held->advance(sample_every * refine);
      if (step > 0 && !held) system.step(sample_every * refine);
      const auto t = stress_tensor(sheared, c.shear_rate);
      out << fmt::format("{} {:.10g} {:.10g} {:.10g} {:.10g} {:.10g} {:.10g} {:.6f}\n", step, t[0],
                         t[1], t[2], t[3], t[4], t[5],
                         particle_volume / sheared.domain().length().prod());
      if (with_powder && step % contact_every == 0)
        contacts << contacts_by_pair_type(step, sheared, powder);
    }
  });
  if (!out) throw std::runtime_error("could not write millflow_stress.txt");
  if (with_powder && !contacts) throw std::runtime_error("could not write millflow_contacts.txt");
  const double cpu = process_cpu_seconds() - cpu_start;
  const double media_kappa =
      setup.media_media.normal_stiffness / (setup.normal_stress * setup.media_diameter);
  if (with_powder)
    fmt::print("  {} particles ({} balls, {} powder grains of {:.4g} m), ", system.size(),
               system.size() - powder_count, powder_count,
               2.0 * *std::min_element(system.radii().begin(), system.radii().end()));
  else
    fmt::print("  {} balls, ", system.size());
  fmt::print(
      "solid fraction {:.4f}, media k_n/(p d) {:.3g}, dt {:.4g} s, {} steps at {} in {:.1f} CPU "
      "s ({:.3g} particle-steps per CPU s)\n",
      solid_fraction, media_kappa, sheared.time_step(), steps * refine,
      o.lammps_stress_control ? "held normal stress" : "fixed volume", cpu,
      static_cast<double>(system.size() * steps * refine) / cpu);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"Shear-cell physics against the outside world (docs/cell_validation.md)"};
  app.add_option("--tables", o.tables,
                 "which tables: 1 stiffness, 2 mu(I), 3 dilute powder, 4 walls against LE, "
                 "5 overlaps, 6 LAMMPS fixed-volume cell")
      ->delimiter(',');
  app.add_option("--size", o.size, "cell size in ball diameters: x y z")->expected(3);
  app.add_option("--threads", o.threads, "threads per cell");
  app.add_option("--shear_rate", o.shear_rate, "site shear rate of tables 1, 3, 4 and 5, 1/s");
  app.add_option("--normal_stress", o.normal_stress, "site normal stress, Pa");
  app.add_option("--powder_ratio", o.powder_ratio, "powder diameter / ball diameter");
  app.add_option("--load", o.load, "powder load of table 1");
  app.add_option("--dilute_load", o.dilute_load, "powder load of table 3");
  app.add_option("--stiffer_factor", o.stiffer_factor, "table 1's stiffer cells, x the policy");
  app.add_option("--stiffness_factors", o.stiffness_factors,
                 "table 1 at each of these stiffnesses, x the policy's (in place of the default "
                 "and --stiffer_factor), each against the one before, and the sequence")
      ->delimiter(',');
  app.add_option("--stiffness_pairs", o.stiffness_pairs,
                 "table 1: the pairs its factors multiply: all, powder (media-powder and "
                 "powder-powder), media (media-media), media_powder, powder_powder")
      ->check(CLI::IsMember({"all", "powder", "media", "media_powder", "powder_powder"}));
  app.add_option("--media_kappa", o.media_kappa,
                 "raise every cell's media-media k_n to at least this k_n / (sigma_n d_m) after "
                 "the policy, before the factors (0: off)");
  app.add_option("--dissipation_probe_every", o.dissipation_probe_every,
                 "table 1: split each cell's measured dissipation by term (normal dashpot, "
                 "tangential dashpot, Coulomb sliding) and, from a one-step probe after every "
                 "this many steps, by contact age in collision times (0: off)");
  app.add_option("--inertial_numbers", o.inertial_numbers, "table 2's I")->delimiter(',');
  app.add_option("--overlap_ratio", o.overlap_ratio, "table 5's powder / ball diameter");
  app.add_option("--overlap_load", o.overlap_load, "table 5's powder load");
  app.add_option("--overlap_size", o.overlap_size, "table 5's cell size, ball diameters")
      ->expected(3);
  app.add_option("--overlap_strain_factor", o.overlap_strain_factor,
                 "table 5's strains, x the protocol's");
  app.add_option("--warmup_strain", o.warmup_strain, "/shear_cell/warmup_strain");
  app.add_option("--max_warmup_strain", o.max_warmup_strain, "/shear_cell/max_warmup_strain");
  app.add_option("--measure_strain", o.measure_strain, "/shear_cell/measure_strain");
  app.add_option("--max_strain", o.max_strain, "/shear_cell/convergence/max_strain");
  app.add_option("--standard_error", o.standard_error, "/shear_cell/convergence/standard_error");
  app.add_option("--seed", o.seed, "/dem/seed");
  app.add_option("--lammps_dir", o.lammps_dir, "table 6: where the LAMMPS files go");
  app.add_option("--lammps_inertial_number", o.lammps_inertial_number, "table 6's I");
  app.add_option("--lammps_strain", o.lammps_strain, "table 6's fixed-volume strain");
  app.add_option("--lammps_sample_every", o.lammps_sample_every, "table 6's sample interval");
  app.add_option("--lammps_load", o.lammps_load,
                 "table 6's powder load (powder of --powder_ratio d; 0: media only)");
  app.add_flag("--lammps_pairs_only", o.lammps_pairs_only,
               "table 6 with powder: only the pair types' collisions and their parameters");
  app.add_option("--lammps_pair_refine", o.lammps_pair_refine,
                 "with --lammps_pairs_only: the collisions at the cell's dt over this (> 0)")
      ->check(CLI::PositiveNumber);
  app.add_option("--steps_per_collision", o.steps_per_collision,
                 "every cell's /shear_cell/steps_per_collision (its time step; default: the "
                 "campaign's)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--lammps_stress_control", o.lammps_stress_control,
               "table 6: both codes shear on under their barostats (millflow's own, LAMMPS's "
               "nph/sphere on y), not at fixed volume");
  app.add_option("--lammps_dt_refine", o.lammps_dt_refine,
                 "table 6: millflow's run at the cell's dt over this")
      ->check(CLI::PositiveNumber);
  app.add_option("--lammps_contact_every", o.lammps_contact_every,
                 "table 6 with powder: contact stress by pair type every this many steps (a "
                 "multiple of --lammps_sample_every)");
  app.add_option("--wall_speed", o.wall_speed,
                 "table 4 open loop: hold the rough walls at this relative speed, m/s (no "
                 "wall-speed controller, no Lees-Edwards cell)");
  app.add_option("--open_loop_strain", o.open_loop_strain, "table 4 open loop: strain");
  app.add_option("--wall_kappa", o.wall_kappa,
                 "table 4: media-media (and wall) k_n / (p d) of both cells, in place of the "
                 "stiffness policy's");
  bool debug_log = false;
  app.add_flag("--debug_log", debug_log,
               "the cells' debug log on stderr (compaction, warm-up windows, wall speed)");
  CLI11_PARSE(app, argc, argv);
  for (const char* strain :
       {"--warmup_strain", "--max_warmup_strain", "--measure_strain", "--max_strain"})
    if (app.count(strain) > 0) o.wall_strains = false;
  if (app.count("--size") > 0) o.wall_size = false;
  spdlog::set_level(debug_log ? spdlog::level::debug : spdlog::level::warn);
  const std::set<int> tables(o.tables.begin(), o.tables.end());
  fmt::print(
      "bench_cell_physics: cell {} x {} x {} d, {} thread(s), strains warm-up {:g} (max "
      "{:g}), measure {:g} (max {:g}), standard error target {:g}\n",
      o.size[0], o.size[1], o.size[2], o.threads, o.warmup_strain, o.max_warmup_strain,
      o.measure_strain, o.max_strain, o.standard_error);
  try {
    if (tables.contains(1)) stiffness_table(o);
    if (tables.contains(2)) inertial_number_table(o);
    if (tables.contains(3)) dilute_table(o);
    if (tables.contains(4)) o.wall_speed > 0.0 ? walls_open_loop(o) : walls_table(o);
    if (tables.contains(5)) overlap_table(o);
    if (tables.contains(6)) lammps_table(o);
  } catch (const std::exception& e) {  // a flag the campaign refuses, a file not written
    fmt::print(stderr, "bench_cell_physics: {}\n", e.what());
    return 2;
  }
  return 0;
}
