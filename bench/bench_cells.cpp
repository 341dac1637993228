// Dense shear cells as a campaign runs them (issue 17): the cost that dominates a campaign.
//
//   le_media_2000   Lees-Edwards cell of ~2000 steel balls of 10 mm (media solid fraction 0.58 at
//                   placement), no powder; steel-steel contacts of 0.1 ms (k_n / (p d) ~ 1e4)
//   cement_load05   the cement campaign's cell (campaigns/cement_ball_mill.json: 50 mm balls,
//                   clinker powder of 0.125 d, 6 x 8 x 6 d, Lees-Edwards) at powder load 0.5
//   cement_load10   the same at powder load 1 (the powder just filling the media's voids)
//   cement_load15   the same at powder load 1.5
//   cement_load00   the same without powder (the campaign's load-0 cells)
//   cement_load05_d025 ... cement_load15_d05
//                   the same with a coarser powder, 0.25 d or 0.5 d (quick.json's size), at each
//                   load: with the three above, the grid of the cost model (tasks/cost_model.hpp)
// All at a site of shear rate 2 1/s (a few per second is what the cement mill's sites see) and
// normal stress 100 kPa (the lower part of its charge); at 20 kPa, and at 10 1/s, compaction
// stops in a hot dilute state that the barostat takes strains to close. Every scene is built by the
// cell's own code path (tasks::shear_cell_setup from the campaign file, dem::ShearCellRun), with
// the file's contacts unless --cells_stiffness=policy (a campaign's cell runs the policy's):
// placement in insertion order, compaction by the barostat, a warm-up of --cells_warmup_strain, and
// then the measurement phase, which is what is timed (the cell's per-step measurement included).
// The prepared state is regenerated deterministically, or read from --cells_cache (a ShearCellRun
// checkpoint per scene; a checkpoint of another setup is refused and regenerated).
// cement_load10 and cement_load15 (and their coarser twins) are prepared in stages: soft powder
// contacts (soft_phase), then the real ones with the soft overlaps let out by a stretch of the box
// (dem::ShearCell::relieve_normal_stress), then windows of the measurement phase until a steady
// test passes (stiffen_until_steady); the cache file says "_steady" only then ("_NOTSTEADY"
// otherwise, never read back). At the policy's stiffness their soft phase is the scene's steady
// state at the file's contacts ("_fromgiven"), which is prepared first when not in the cache.
//
// Counters: pts_per_cpu_s (particle-steps per CPU-second of the process, every thread),
// pts_per_s (wall), contacts_per_particle (pair and wall contacts in force), pairs_per_particle
// (candidate pairs), screened_per_particle_step (the candidate pairs the screening looked at per
// particle-step: those asleep it skips, System::pairs_screened), rebuilds_per_kstep (neighbour
// list builds per 1,000 timed steps), layouts_per_kstep (the contact store laid out in pair order
// again between builds, per 1,000 timed steps: System::compact_contacts), strain_per_step (shear
// rate x time step), bytes_per_particle (System::memory_bytes() / particles) and its parts
// (System::MemoryUse): bytes_particles, bytes_pairs (candidate pairs), bytes_contacts (pair and
// wall contacts), bytes_queues (the step's queues of starting and finishing contacts),
// bytes_events (collision events not yet taken).
//
// Extra flags (before Google Benchmark's own):
//   --cells_steps=N           steps per timed iteration (default: per scene)
//   --cells_shear_rate=R      the site's shear rate, 1/s (default 2)
//   --cells_normal_stress=P   the site's normal stress, Pa (default 1e5)
//   --cells_warmup_strain=S   shear strain run after compaction, before timing (default 1 for
//                             the media cell, 0.05 for the cement cells)
//   --cells_lammps_dir=D      write each scene's state and parameters for LAMMPS into D
//                             (bench/run_cell_comparison.sh)
//   --cells_cache=DIR         where the prepared states are kept (default: none)
//   --cells_stiffness=K       given (default): the contacts of the campaign file, as the scenes'
//                             figures so far were measured; policy: those raised by the cell's
//                             stiffness policy at the site (tasks::apply_stiffness_policy), as a
//                             campaign's cell runs (at 100 kPa the fine powder's k_n 128 times
//                             the given, its time step 11 times shorter); a staged scene is
//                             prepared from its steady state at the given contacts
//   --cells_skin_fraction=F   time with a neighbour skin of F x the smallest diameter (default:
//                             the prepared state's); F = auto: the skin an "auto" cell picks
//                             (dem::adopt_skin_by_trials: 100 steps of a copy at each of 0.1,
//                             0.15, 0.2 and 0.3 x the smallest diameter)
#include <tbb/task_arena.h>

#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "bench/lammps_export.hpp"
#include "bench/process_measures.hpp"
#include "dem/shear_cell.hpp"
#include "dem/skin_choice.hpp"
#include "dem/stationarity.hpp"
#include "method/sites.hpp"
#include "tasks/campaign.hpp"
#include "tasks/shear_cell.hpp"
#include "util/sphere.hpp"

namespace {

using namespace millflow;
using bench::contacts_per_particle;
using bench::process_cpu_seconds;
using bench::state_hash;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

constexpr double kHugeMeasureStrain = 1e3;  // the measurement never ends while timed

struct Options {
  std::optional<std::size_t> steps;
  double shear_rate = 2.0;     // 1/s
  double normal_stress = 1e5;  // Pa
  std::optional<double> warmup_strain;
  std::optional<double> skin_fraction;
  bool skin_auto = false;
  std::optional<std::filesystem::path> cache;
  std::optional<std::filesystem::path> lammps_dir;
  bool stiffness_policy = false;
};
Options g_options;

struct CellCase {
  std::string name;
  double powder_load = 0.0;
  double powder_diameter_ratio = 0.0;   // d_p / d; 0: the campaign's (kCampaignPowderRatio)
  bool media_only_small_balls = false;  // le_media_2000
  std::size_t default_steps = 0;
  double warmup_strain = 0.05;  // the media cell, cheap, runs to a denser state
  // Preparation with soft powder contacts (cement_load10 and 15; soft_phase, stiffen_until_steady):
  // the powder's contacts (media-powder, powder-powder) at t_c x powder_softening (k_n /
  // softening^2, a power of two so that stiffening back is exact) through placement, compaction
  // and the protocol's warm-up, then at each of stiffening_stages for stage_strain, then the real
  // contacts until steady; after each stiffening the soft overlaps are let out by stretching the
  // box (dem::ShearCell::relieve_normal_stress) before the barostat goes on. The media-media
  // contacts, which set the barostat's speed limit and relaxation time, keep their real stiffness
  // throughout; their t_c is 2.5 x the powder's, so the time step gains 2.5 at most (5 us ->
  // 12.5 us at t_c x 4). 1: the plain preparation.
  double powder_softening = 1.0;
  std::vector<double> stiffening_stages = {};
  double stage_strain = 0.02;
  // The steady test's windows (see steady_test) and the most strain of real contacts. A cell
  // whose shear stress wanders more slowly than 5 windows can follow needs longer ones.
  double steady_window_strain = 0.01;
  double max_real_strain = 0.3;
};

// The campaign's powder, d_p / d; the coarser scenes' steps scale with its particle volume.
constexpr double kCampaignPowderRatio = 0.125;

const std::vector<CellCase>& cases() {
  static const std::vector<CellCase> all = [] {
    std::vector<CellCase> scenes{
        {.name = "le_media_2000",
         .media_only_small_balls = true,
         .default_steps = 400,
         .warmup_strain = 1.0},
        {.name = "cement_load05", .powder_load = 0.5, .default_steps = 40},
        // Its shear stress wanders with a period of about 0.1 strain (docs/benchmarks.md).
        {.name = "cement_load10",
         .powder_load = 1.0,
         .default_steps = 20,
         .powder_softening = 4.0,
         .steady_window_strain = 0.03,
         .max_real_strain = 0.6},
        {.name = "cement_load15", .powder_load = 1.5, .default_steps = 20, .powder_softening = 4.0},
        // The cement cell without powder: its balls at the cement site (a dense bed).
        {.name = "cement_load00", .default_steps = 2000},
    };
    // The cement cells again with coarser powders, 0.25 d and 0.5 d (quick.json's size), each
    // prepared as the fine powder's scene at its load: the cost model's grid
    // (tasks/cost_model.hpp). Named by the ratio's digits: cement_load10_d025.
    std::vector<CellCase> fine;
    std::copy_if(scenes.begin(), scenes.end(), std::back_inserter(fine),
                 [](const CellCase& c) { return c.powder_load > 0.0; });
    for (const double ratio : {0.25, 0.5}) {
      for (const CellCase& c : fine) {
        CellCase coarser = c;
        std::string digits = fmt::format("{}", ratio);
        std::erase(digits, '.');
        coarser.name += "_d" + digits;
        coarser.powder_diameter_ratio = ratio;
        coarser.default_steps *=
            static_cast<std::size_t>(std::lround(std::pow(ratio / kCampaignPowderRatio, 3)));
        scenes.push_back(std::move(coarser));
      }
    }
    return scenes;
  }();
  return all;
}

// The cell setup the campaign's own code derives, at a fixed site.
dem::ShearCellSetup setup_of(const CellCase& c, bool stiffness_policy) {
  json campaign = tasks::load_campaign(std::filesystem::path(MILLFLOW_SOURCE_DIR) / "campaigns" /
                                       "cement_ball_mill.json");
  campaign.erase("sweep");
  json& cell = campaign["shear_cell"];
  cell["powder"]["load"] = c.powder_load;
  if (c.powder_diameter_ratio > 0.0) cell["powder"]["diameter_ratio"] = c.powder_diameter_ratio;
  if (c.media_only_small_balls) {
    // 2000 balls of 10 mm at phi = 0.58: a cube of (2000 pi / 6 / 0.58)^(1/3) = 12.18 d.
    campaign["media"]["diameter"] = 0.01;
    cell["size_diameters"] = {12.18, 12.18, 12.18};
    for (json& interaction : campaign["interactions"]) {
      if (interaction["materials"] == json{"steel", "steel"})
        interaction["stiffness"] = {{"collision_time", 1e-4}};
    }
  }
  campaign = tasks::validate_campaign(campaign);
  const json site = method::CellDrive{.shear_rate = g_options.shear_rate,
                                      .normal_stress = g_options.normal_stress};
  dem::ShearCellSetup setup = tasks::shear_cell_setup(campaign, site, "bench_cells/" + c.name);
  if (stiffness_policy) tasks::apply_stiffness_policy(campaign, setup);
  if (c.media_only_small_balls) setup.media_solid_fraction = 0.58;
  return setup;
}

double warmup_strain(const CellCase& c) {
  return g_options.warmup_strain.value_or(c.warmup_strain);
}

dem::ShearCellProtocol protocol(const CellCase& c) {
  return {.warmup_strain = warmup_strain(c),
          .warmup_windows = 1,
          .measure_strain = kHugeMeasureStrain,
          .measure = {}};
}

// Placement, compaction and the protocol's warm-up, on 2 threads: the run ends in its
// measurement phase.
void run_to_measurement(dem::ShearCellRun& run) {
  tbb::task_arena arena(2);
  arena.execute([&] {
    while (run.phase_name() != "measuring") run.advance(1000);
  });
}

// --- The staged preparation (cement_load10, cement_load15) -------------------------------------
// A soft run goes on at the next stiffness through dem::ShearCellRun::with_interactions (the
// same state, every contact's dashpot and the time step worked out again from the new contacts).

// The setup with the powder's contacts at t_c x softening.
dem::ShearCellSetup softened(dem::ShearCellSetup setup, double softening) {
  const double k = 1.0 / (softening * softening);
  setup.media_powder.normal_stiffness *= k;
  setup.powder_powder.normal_stiffness *= k;
  return setup;
}

// One window of the run in its measurement phase: the means over its control intervals.
struct Chunk {
  double normal_stress = 0.0;   // Pa
  double shear_stress = 0.0;    // Pa
  double solid_fraction = 0.0;  // particle volume / box volume
  double contacts = 0.0;        // contacts in force per particle
};

double particle_volume(const dem::System& system) {
  double volume = 0.0;
  for (const double r : system.radii()) volume += util::sphere_volume_of_radius(r);
  return volume;
}

// `strain` more of the run in its measurement phase (the timed protocol), sampled once per
// control interval.
Chunk run_chunk(dem::ShearCellRun& run, double strain) {
  const dem::ShearCell& cell = run.cell();
  const dem::System& system = cell.system();
  const double solid = particle_volume(system);
  const auto interval = static_cast<std::uint64_t>(cell.setup().steps_per_collision);
  const auto steps = static_cast<std::uint64_t>(
      std::ceil(strain / (cell.setup().shear_rate * system.time_step())));
  Chunk chunk;
  double samples = 0.0;
  for (std::uint64_t done = 0; done < steps; done += interval) {
    run.advance(interval);
    chunk.normal_stress += cell.normal_stress_now();
    chunk.shear_stress += cell.shear_stress_now();
    chunk.solid_fraction += solid / system.domain().length().prod();
    chunk.contacts += contacts_per_particle(system);
    samples += 1.0;
  }
  chunk.normal_stress /= samples;
  chunk.shear_stress /= samples;
  chunk.solid_fraction /= samples;
  chunk.contacts /= samples;
  return chunk;
}

// The real contacts' test of a steady state, over the last kSteadyWindows windows of the scene's
// steady_window_strain: the cell's own stationarity test (dem::test_stationarity: no drift of
// shear stress or solid fraction beyond the windows' scatter, the normal stress carried in every
// window) with the normal stress's mean within kSteadyTolerance of the target (the cell's test
// allows 10%, or its scatter), and no drift of the contacts per particle beyond the windows'
// scatter or kContactsDrift of their mean. At most the scene's max_real_strain of real contacts,
// the relief's hold included.
//
// The relief after the last stiffening holds the stress on target for kReliefHoldStrain before the
// barostat goes on, and hands over with the barostat's integral term at 0: the real contacts'
// network re-forms under shear for about 0.1 strain (contacts per particle 2.07 -> 2.25, shear
// stress 13 -> 37 kPa); handed over at once, the bed's stress fell to 84 kPa while the barostat
// (time constant 0.2 strain) lagged, its integral term wound up on the dip, and it overshot to
// 113 kPa, still 10% high at strain 0.3 (the first run, docs/benchmarks.md).
constexpr double kReliefHoldStrain = 0.1;
constexpr std::size_t kSteadyWindows = 5;
constexpr double kSteadyTolerance = 0.05;
constexpr double kContactsDrift = 0.02;

struct SteadyVerdict {
  bool steady = false;
  std::string why;
};

SteadyVerdict steady_test(std::span<const Chunk> chunks, double target) {
  if (chunks.size() < kSteadyWindows) return {false, "too few windows"};
  const auto last = chunks.last(kSteadyWindows);
  std::vector<dem::WindowMeans> windows;
  std::vector<double> contacts, normal;
  for (const Chunk& c : last) {
    windows.push_back({.shear_stress = c.shear_stress,
                       .normal_stress = c.normal_stress,
                       .solid_fraction = c.solid_fraction,
                       .bulk_shear_rate = 0.0});
    contacts.push_back(c.contacts);
    normal.push_back(c.normal_stress);
  }
  const dem::StationarityCriterion criterion{.tolerance = kSteadyTolerance};
  const dem::StationarityVerdict verdict = dem::test_stationarity(windows, target, 0.0, criterion);
  const dem::SeriesFit contacts_fit = dem::fit_series(contacts);
  const dem::SeriesFit normal_fit = dem::fit_series(normal);
  const bool contacts_ok =
      std::abs(contacts_fit.drift) <=
      std::max(criterion.z * contacts_fit.drift_error, kContactsDrift * contacts_fit.mean);
  const bool normal_ok = std::abs(normal_fit.mean / target - 1.0) <= kSteadyTolerance;
  SteadyVerdict out;
  out.steady = verdict.stationary() && contacts_ok && normal_ok;
  out.why = fmt::format(
      "over the last {} windows: shear stress {}, solid fraction {}, normal stress {} (mean {:.4g} "
      "Pa, {}), contacts {} (drift {:.3g} of {:.4g})",
      kSteadyWindows, verdict.shear_stress ? "steady" : "drifts",
      verdict.solid_fraction ? "steady" : "drifts", verdict.normal_stress ? "on" : "off",
      normal_fit.mean, normal_ok ? "within 5%" : "off by more than 5%",
      contacts_ok ? "steady" : "drift", contacts_fit.drift, contacts_fit.mean);
  return out;
}

struct Prepared {
  std::unique_ptr<dem::ShearCellRun> run;
  std::string how;
  bool steady = true;
};

// Logs a line of a scene's preparation with the CPU-seconds it has taken so far.
class PreparationLog {
 public:
  explicit PreparationLog(const CellCase& c) : name_(c.name), cpu0_(process_cpu_seconds()) {}
  void operator()(const std::string& line) const {
    fmt::print(stderr, "bench_cells: {}: [{:.0f} CPU-s] {}\n", name_, cpu_seconds(), line);
  }
  double cpu_seconds() const { return process_cpu_seconds() - cpu0_; }

 private:
  std::string name_;
  double cpu0_;
};

// The soft phase of the staged preparation: placement, compaction and the protocol's warm-up at
// the powder's contacts softened by the scene's powder_softening. The costly part (about 18
// CPU-minutes for cement_load15), kept in `soft_file` so that a preparation stopped later
// resumes from it.
Prepared soft_phase(const CellCase& c, const dem::ShearCellSetup& setup,
                    const std::filesystem::path& soft_file, const PreparationLog& log) {
  const dem::ShearCellProtocol proto = protocol(c);
  const dem::ShearCellSetup soft = softened(setup, c.powder_softening);
  Prepared out;
  out.how = fmt::format("powder contacts at t_c x {}: ", c.powder_softening);
  if (std::filesystem::exists(soft_file)) {
    try {
      out.run =
          std::make_unique<dem::ShearCellRun>(dem::ShearCellRun::resume(soft, proto, soft_file));
      out.how += fmt::format("compaction and warm-up to step {} (from {})",
                             out.run->cell().system().step_count(), soft_file.filename().string());
      return out;
    } catch (const std::exception& e) {
      log(fmt::format("soft phase again ({})", e.what()));
    }
  }
  out.run = std::make_unique<dem::ShearCellRun>(soft, proto);
  run_to_measurement(*out.run);
  out.how += fmt::format("compaction and warm-up to step {} ({:.0f} CPU-s)",
                         out.run->cell().system().step_count(), log.cpu_seconds());
  out.run->save(soft_file);
  return out;
}

// Takes the soft run of `start` through `stages` of powder softening (1: the real contacts of
// `setup`), each one's overlaps let out by a stretch of the box, then windows of the measurement
// phase until the steady test passes or the scene's max_real_strain. Returns the run in its
// measurement phase at the real contacts, how it got there and whether it passed the test.
Prepared stiffen_until_steady(const CellCase& c, const dem::ShearCellSetup& setup, Prepared start,
                              std::span<const double> stages, const PreparationLog& log) {
  Prepared out = std::move(start);
  std::unique_ptr<dem::ShearCellRun>& run = out.run;
  std::string& how = out.how;
  log(fmt::format("{}; {:.4g} Pa, {:.3f} contacts per particle", how,
                  run->cell().normal_stress_now(), contacts_per_particle(run->cell().system())));
  tbb::task_arena arena(2);
  for (const double softening : stages) {
    const dem::ShearCellSetup next = softening == 1.0 ? setup : softened(setup, softening);
    run = std::make_unique<dem::ShearCellRun>(run->with_interactions(next));
    dem::StressRelief law;
    if (softening == 1.0) {
      law.hold_steps = static_cast<std::uint64_t>(
          std::ceil(kReliefHoldStrain / (next.shear_rate * run->cell().system().time_step())));
      law.max_steps += law.hold_steps;
    }
    dem::StressReliefResult relief;
    arena.execute([&] { relief = run->cell().relieve_normal_stress(law); });
    how += fmt::format(
        "; t_c x {}: {:.4g} Pa at once, relieved {}in {} steps{} by a stretch of {:.4g} to {:.4g} "
        "Pa",
        softening, relief.first_stress, relief.relieved ? "" : "(NOT: its step cap) ", relief.steps,
        law.hold_steps > 0 ? fmt::format(" (held on target for {} of them, strain {})",
                                         law.hold_steps, kReliefHoldStrain)
                           : "",
        relief.strain, relief.normal_stress);
    log(how);
    if (softening == 1.0) break;
    Chunk chunk;
    arena.execute([&] { chunk = run_chunk(*run, c.stage_strain); });
    how += fmt::format("; then strain {}: {:.4g} Pa, {:.3f} contacts per particle", c.stage_strain,
                       chunk.normal_stress, chunk.contacts);
    log(how);
  }
  double strain = kReliefHoldStrain;
  std::vector<Chunk> chunks;
  SteadyVerdict verdict;
  while (!verdict.steady && strain < c.max_real_strain - 1e-9) {
    Chunk chunk;
    arena.execute([&] { chunk = run_chunk(*run, c.steady_window_strain); });
    chunks.push_back(chunk);
    strain += c.steady_window_strain;
    verdict = steady_test(chunks, setup.normal_stress);
    log(fmt::format(
        "real contacts, strain {:.2f}: {:.4g} Pa, shear {:.4g} Pa, solid fraction {:.4f}, {:.4f} "
        "contacts per particle{}",
        strain, chunk.normal_stress, chunk.shear_stress, chunk.solid_fraction, chunk.contacts,
        chunks.size() >= kSteadyWindows ? "; " + verdict.why : ""));
  }
  out.steady = verdict.steady;
  const Chunk& last = chunks.back();
  how += fmt::format(
      "; real contacts for strain {:.2f} ({}): last window {:.4g} Pa, solid fraction {:.4f}, "
      "{:.4f} contacts per particle ({}); step {}, {:.0f} CPU-s in all",
      strain, verdict.steady ? "steady" : "NOT steady (the cap)", last.normal_stress,
      last.solid_fraction, last.contacts, verdict.why, run->cell().system().step_count(),
      log.cpu_seconds());
  return out;
}

// The scene's run in its measurement phase at the file's contacts or (stiffness_policy) the
// policy's, built once per process (and cached on disk). A staged scene at the policy's contacts
// starts from its state at the file's (prepared first, or read from the cache): the policy's
// contacts are stiffer (at 100 kPa the fine powder's 128 times), so that state is its soft phase,
// compacted and sheared already; preparing it from placement instead takes about 11 times the
// steps (the fine powder's time step 0.44 us against 5 us).
const dem::ShearCellRun& prepared(const CellCase& c, bool stiffness_policy) {
  static std::map<std::pair<std::string, bool>, std::unique_ptr<dem::ShearCellRun>> runs;
  auto& slot = runs[{c.name, stiffness_policy}];
  if (slot) return *slot;
  const dem::ShearCellSetup setup = setup_of(c, stiffness_policy);
  const bool staged = c.powder_softening != 1.0;
  // The staged preparation's recipe is in the name (its notes: the .txt beside), and a state is
  // kept under it only once it passed the steady test ("_steady"); one that did not is kept as
  // "_NOTSTEADY" for a look, never read back.
  std::string base = fmt::format("{}_rate{}_p{}_warm{}", c.name, g_options.shear_rate,
                                 g_options.normal_stress, warmup_strain(c));
  if (stiffness_policy) base += "_policy";
  std::string recipe;
  if (staged) {
    base += stiffness_policy ? "_fromgiven" : fmt::format("_powdersoft{}", c.powder_softening);
    for (const double s : c.stiffening_stages) recipe += fmt::format("x{}", s);
    recipe += fmt::format("_relieved_held{}", kReliefHoldStrain);
    if (c.steady_window_strain != CellCase{}.steady_window_strain)
      recipe += fmt::format("_windows{}", c.steady_window_strain);
  }
  std::optional<std::filesystem::path> file;
  if (g_options.cache) {
    std::filesystem::create_directories(*g_options.cache);
    file = *g_options.cache / (base + recipe + (staged ? "_steady" : "") + ".ckpt");
    if (std::filesystem::exists(*file)) {
      try {
        slot = std::make_unique<dem::ShearCellRun>(
            dem::ShearCellRun::resume(setup, protocol(c), *file));
        return *slot;
      } catch (const std::exception& e) {
        fmt::print(stderr, "bench_cells: {}: regenerating ({})\n", c.name, e.what());
      }
    }
  }
  const auto start = Clock::now();
  std::string how;
  bool steady = true;
  if (staged) {
    const PreparationLog log(c);
    Prepared soft;
    std::vector<double> stages;
    if (stiffness_policy) {
      soft.run = std::make_unique<dem::ShearCellRun>(prepared(c, false));
      soft.how = fmt::format("from the state at the file's contacts (step {})",
                             soft.run->cell().system().step_count());
    } else {
      // The soft phase depends on the softening only, not on what follows it.
      const std::filesystem::path soft_file =
          g_options.cache ? *g_options.cache / (base + ".soft.ckpt")
                          : std::filesystem::temp_directory_path() /
                                fmt::format("bench_cells_{}.soft.ckpt", base);
      soft = soft_phase(c, setup, soft_file, log);
      stages = c.stiffening_stages;
    }
    stages.push_back(1.0);
    Prepared p = stiffen_until_steady(c, setup, std::move(soft), stages, log);
    slot = std::move(p.run);
    how = std::move(p.how);
    steady = p.steady;
  } else {
    slot = std::make_unique<dem::ShearCellRun>(setup, protocol(c));
    run_to_measurement(*slot);
  }
  fmt::print(stderr, "bench_cells: {}: {} particles prepared in {:.1f} s (step {})\n", c.name,
             slot->cell().system().size(),
             std::chrono::duration<double>(Clock::now() - start).count(),
             slot->cell().system().step_count());
  if (!how.empty()) fmt::print(stderr, "bench_cells: {}: prepared: {}\n", c.name, how);
  if (!steady) {
    fmt::print(stderr, "bench_cells: {}: NOT steady: timed anyway, kept as _NOTSTEADY\n", c.name);
    if (file) file = *g_options.cache / (base + recipe + "_NOTSTEADY.ckpt");
  }
  if (file) {
    slot->save(*file);
    if (!how.empty()) {
      std::ofstream notes(file->string() + ".txt");
      notes << how << "\n";
    }
  }
  return *slot;
}

// A scene's state and parameters for LAMMPS: the media cell for bench/lammps/in.shear (one pair
// type), a media + powder cell for bench/lammps/in.cell_mixture (per pair of types, each type of
// one size, so the damping matches exactly).
void export_for_lammps(const CellCase& c, const dem::ShearCellRun& run) {
  const dem::System& system = run.cell().system();
  const dem::ShearCellSetup& setup = run.cell().setup();
  bench::LammpsParams params;
  if (c.media_only_small_balls) {
    const std::size_t ball = bench::first_of_kinds(system).ball;  // type 1: the media
    if (ball == system.size()) return;
    bench::add_contact_params(params, "", setup.media_media, 0.5 * system.masses()[ball]);
  } else if (!bench::add_pair_type_params(params, system)) {
    return;  // no powder: nothing for in.cell_mixture
  }
  params.set("dt", system.time_step());
  params.set("skin", 0.6 * *std::min_element(system.radii().begin(), system.radii().end()));
  params.set("shear_rate", setup.shear_rate);
  params.notes.push_back(
      "LAMMPS runs a fixed box: millflow's barostat and measurement are not "
      "part of it");
  std::filesystem::create_directories(*g_options.lammps_dir);
  bench::write_lammps_data(system, c.name, *g_options.lammps_dir / (c.name + ".data"));
  bench::write_lammps_params(c.name, "bench_cells, measurement phase", params,
                             *g_options.lammps_dir / (c.name + ".params"));
}

void run_cell(benchmark::State& state, const CellCase& c, int threads) {
  spdlog::set_level(spdlog::level::warn);
  dem::ShearCellRun run = prepared(c, g_options.stiffness_policy);  // each times its own copy
  if (g_options.lammps_dir) export_for_lammps(c, run);
  if (g_options.skin_auto) {
    // What an "auto" cell does (its trials step copies): the timed run starts from the prepared
    // state, at the chosen skin.
    dem::System& system = run.cell().system();
    spdlog::set_level(spdlog::level::info);  // the choice's log line
    const dem::SkinChoice choice = dem::adopt_skin_by_trials(system);
    spdlog::set_level(spdlog::level::warn);
    fmt::print(stderr, "SKIN {} chosen {:.4g} x smallest diameter\n", c.name,
               choice.skin_fraction());
  } else if (g_options.skin_fraction) {
    dem::System& system = run.cell().system();
    system.set_neighbor_skin(*g_options.skin_fraction * dem::smallest_diameter(system));
  }
  const std::size_t steps = g_options.steps.value_or(c.default_steps);
  const std::size_t particles = run.cell().system().size();
  tbb::task_arena arena(threads);
  const std::uint64_t screened_before = run.cell().system().pairs_screened();
  const std::uint64_t rebuilds_before = run.cell().system().neighbor_rebuild_count();
  const std::uint64_t layouts_before = run.cell().system().contact_compaction_count();
  double wall = 0.0, cpu = 0.0;
  std::size_t total_steps = 0;
  for (auto _ : state) {
    const double cpu_start = process_cpu_seconds();
    const auto start = Clock::now();
    arena.execute([&] { run.advance(steps); });
    wall += std::chrono::duration<double>(Clock::now() - start).count();
    cpu += process_cpu_seconds() - cpu_start;
    total_steps += steps;
  }
  const dem::System& system = run.cell().system();
  const double particle_steps = static_cast<double>(particles * total_steps);
  // For bench/run_cell_comparison.sh: RESULT scene threads particles steps wall-s cpu-s, and a
  // hash of the final positions and velocities (two builds that keep the bits print the same).
  fmt::print(stderr, "RESULT {} {} {} {} {:.6g} {:.6g} state {:016x}\n", c.name, threads, particles,
             total_steps, wall, cpu, state_hash(system));
  state.counters["particles"] = static_cast<double>(particles);
  state.counters["pts_per_s"] = particle_steps / wall;
  state.counters["pts_per_cpu_s"] = particle_steps / cpu;
  state.counters["contacts_per_particle"] = contacts_per_particle(system);
  state.counters["pairs_per_particle"] =
      static_cast<double>(system.candidate_pairs().size()) / static_cast<double>(particles);
  state.counters["screened_per_particle_step"] =
      static_cast<double>(system.pairs_screened() - screened_before) / particle_steps;
  const auto per_kstep = [&](std::uint64_t count) {
    return 1e3 * static_cast<double>(count) / static_cast<double>(total_steps);
  };
  state.counters["rebuilds_per_kstep"] =
      per_kstep(system.neighbor_rebuild_count() - rebuilds_before);
  state.counters["layouts_per_kstep"] =
      per_kstep(system.contact_compaction_count() - layouts_before);
  state.counters["strain_per_step"] = run.cell().setup().shear_rate * system.time_step();
  // The bytes per particle, and by what they grow with (System::MemoryUse).
  const dem::System::MemoryUse memory = system.memory_use();
  const auto per_particle = [&](std::size_t bytes) {
    return static_cast<double>(bytes) / static_cast<double>(particles);
  };
  state.counters["bytes_per_particle"] = per_particle(memory.total());
  state.counters["bytes_particles"] = per_particle(memory.particles);
  state.counters["bytes_pairs"] = per_particle(memory.candidate_pairs);
  state.counters["bytes_contacts"] = per_particle(memory.contacts + memory.wall_contacts);
  state.counters["bytes_queues"] = per_particle(memory.step_queues);
  state.counters["bytes_events"] = per_particle(memory.collision_events);
}

// Strips "--name=value" for our flags out of argv; returns the value of each one given.
std::optional<std::string> take_flag(int& argc, char** argv, std::string_view name) {
  const std::string prefix = fmt::format("--{}=", name);
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg(argv[i]);
    if (!arg.starts_with(prefix)) continue;
    std::string value(arg.substr(prefix.size()));
    for (int k = i; k + 1 < argc; ++k) argv[k] = argv[k + 1];
    --argc;
    return value;
  }
  return std::nullopt;
}

}  // namespace

int main(int argc, char** argv) {
  if (auto v = take_flag(argc, argv, "cells_steps")) g_options.steps = std::stoul(*v);
  if (auto v = take_flag(argc, argv, "cells_shear_rate")) g_options.shear_rate = std::stod(*v);
  if (auto v = take_flag(argc, argv, "cells_normal_stress"))
    g_options.normal_stress = std::stod(*v);
  if (auto v = take_flag(argc, argv, "cells_warmup_strain"))
    g_options.warmup_strain = std::stod(*v);
  if (auto v = take_flag(argc, argv, "cells_cache")) g_options.cache = *v;
  if (auto v = take_flag(argc, argv, "cells_lammps_dir")) g_options.lammps_dir = *v;
  if (auto v = take_flag(argc, argv, "cells_stiffness")) {
    if (*v != "given" && *v != "policy") {
      fmt::print(stderr, "--cells_stiffness={}: expected given or policy\n", *v);
      return 2;
    }
    g_options.stiffness_policy = *v == "policy";
  }
  if (auto v = take_flag(argc, argv, "cells_skin_fraction")) {
    if (*v == "auto") {
      g_options.skin_auto = true;
    } else {
      g_options.skin_fraction = std::stod(*v);
    }
  }
  for (const CellCase& c : cases()) {
    for (const int threads : {1, 2}) {
      benchmark::RegisterBenchmark(
          fmt::format("{}/threads:{}", c.name, threads).c_str(),
          [&c, threads](benchmark::State& state) { run_cell(state, c, threads); })
          ->Unit(benchmark::kSecond)
          ->UseRealTime();
    }
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
