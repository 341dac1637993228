// Shear-cell physics against the outside world (issue 12, "Check it against the outside world";
// the measured tables are in docs/shear_cells.md). Not a timing benchmark: it runs whole cells
// (compaction, warm-up to stationarity, measurement to convergence) through the campaign's code
// path (tasks::shear_cell_setup, tasks::apply_stiffness_policy, tasks::shear_cell_protocol,
// dem::ShearCellRun) and prints three tables:
//
//   1 stiffness  a media-only cell and a cell with powder (--powder_ratio d at --load) at the
//                policy's default stiffness and at --stiffer_factor x it: friction (tau / p_yy),
//                friction_mean_pressure (tau / p), the powder's share of the dissipation and the
//                cushioning (media-media dissipation with powder / without), each with its
//                standard error, and the difference in units of the combined standard error.
//   2 mu(I)      the media-only cell at inertial numbers --inertial_numbers (the shear rate set
//                from I at the site's normal stress), against Jop, Forterre & Pouliquen (Nature
//                441, 2006): mu(I) = mu_s + (mu_2 - mu_s) / (1 + I_0 / I) with their glass
//                beads' mu_2 - mu_s = 0.26 and I_0 = 0.279 held, mu_s fitted (weighted by the
//                friction's standard error), and the residuals in standard errors.
//   3 dilute     the cell at powder load --dilute_load against the media-only one.
//
// The scene is campaigns/cement_ball_mill.json's cell (50 mm steel balls, clinker powder, steel
// 7800 and clinker 3150 kg/m^3, Lees-Edwards, stiffness policy "overlap_bound") at a site of
// --shear_rate and --normal_stress; --size sets the cell (in ball diameters), the strains and the
// convergence target scale the run up. Standard errors are the cells' batch means; a ratio's is
// propagated from its two parts as if independent (the dissipation terms of one cell are
// positively correlated, so the share's error is overstated).
//
//   bench_cell_physics [--tables 1,2,3] [--size 5 6 5] [--threads 1] ...  (--help lists all)
#include <sys/resource.h>
#include <tbb/task_arena.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "dem/shear_cell.hpp"
#include "dem/stiffness_policy.hpp"
#include "tasks/campaign.hpp"
#include "tasks/shear_cell.hpp"

namespace {

using namespace millflow;
using nlohmann::json;

// Jop, Forterre & Pouliquen 2006, glass beads: mu_2 - mu_s and I_0 (their mu_s = 0.38 and
// mu_2 = 0.64; mu_s is fitted here).
constexpr double kJfpFrictionRise = 0.64 - 0.38;
constexpr double kJfpInertialNumber = 0.279;

struct Options {
  std::vector<int> tables{1, 2, 3};
  std::vector<double> size{5, 6, 5};
  int threads = 1;
  double shear_rate = 10.0;     // 1/s, tables 1 and 3
  double normal_stress = 2e4;   // Pa
  double powder_ratio = 0.25;   // powder / ball diameter
  double load = 1.0;            // table 1's powder load
  double dilute_load = 0.01;    // table 3's
  double stiffer_factor = 4.0;  // table 1's second stiffness, x the policy's
  std::vector<double> inertial_numbers{0.01, 0.03, 0.1, 0.3};
  double warmup_strain = 1.0, max_warmup_strain = 3.0;
  double measure_strain = 2.0, max_strain = 4.0;
  double standard_error = 0.03;
  std::uint64_t seed = 1;
};

struct Cell {
  double powder_load = 0.0;
  double shear_rate = 0.0;
  double stiffness_factor = 1.0;
};

// What a finished cell reports.
struct CellResult {
  dem::ShearCellMeasurements m;
  std::size_t particles = 0;
  double media_kappa = 0.0;  // k_n / (p d) of media-media contacts
  double cpu_seconds = 0.0;
};

double process_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

json campaign_for(const Options& o, const Cell& c) {
  json campaign = tasks::load_campaign(std::filesystem::path(MILLFLOW_SOURCE_DIR) / "campaigns" /
                                       "cement_ball_mill.json");
  campaign.erase("sweep");
  campaign["dem"]["seed"] = o.seed;
  json& cell = campaign["shear_cell"];
  cell["size_diameters"] = o.size;
  cell["powder"]["diameter_ratio"] = o.powder_ratio;
  cell["powder"]["load"] = c.powder_load;
  cell["warmup_strain"] = o.warmup_strain;
  cell["max_warmup_strain"] = o.max_warmup_strain;
  cell["measure_strain"] = o.measure_strain;
  cell["convergence"] = {{"standard_error", o.standard_error}, {"max_strain", o.max_strain}};
  return tasks::validate_campaign(campaign);
}

CellResult run_cell(const Options& o, const Cell& c) {
  const json campaign = campaign_for(o, c);
  const json site{{"shear_rate_per_s", c.shear_rate}, {"normal_stress_pa", o.normal_stress}};
  dem::ShearCellSetup setup = tasks::shear_cell_setup(campaign, site, "bench_cell_physics");
  tasks::apply_stiffness_policy(campaign, setup);
  for (dem::InteractionSpec* pair : {&setup.media_media, &setup.media_powder, &setup.powder_powder})
    pair->normal_stiffness *= c.stiffness_factor;
  CellResult result;
  result.media_kappa =
      setup.media_media.normal_stiffness / (setup.normal_stress * setup.media_diameter);
  const double cpu_start = process_cpu_seconds();
  dem::ShearCellRun run(setup, tasks::shear_cell_protocol(campaign));
  tbb::task_arena arena(o.threads);
  arena.execute([&] {
    while (!run.advance(100000)) {
    }
  });
  result.cpu_seconds = process_cpu_seconds() - cpu_start;
  result.m = run.measurements();
  result.particles = run.cell().system().size();
  const auto& m = result.m;
  fmt::print(
      "  cell load {:g}, {:g} 1/s, stiffness x{:g} (media k_n/(p d) {:.3g}): {} particles, "
      "{} steps, {:.1f} CPU s; I {:.3g}, stationary strain {}, measured strain {:.2f}, steady {}, "
      "converged {}, overlap p95 {:.3g} (ok {}), energy balance {:.2g}\n",
      c.powder_load, c.shear_rate, c.stiffness_factor, result.media_kappa, result.particles,
      run.cell().system().step_count(), result.cpu_seconds, m.inertial_number,
      m.stationary ? fmt::format("{:.2f}", m.stationary_strain) : std::string("none"), m.strain,
      m.steady, m.converged,
      [&] {
        double worst = 0.0;
        for (const auto& t : m.overlaps) worst = std::max(worst, t.p95_fraction);
        return worst;
      }(),
      m.overlap_ok, m.energy_balance_error);
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

void print_row(const std::string& name, Value a, Value b) {
  fmt::print("  {:<24} {:>9.4f} +- {:<8.4f} {:>9.4f} +- {:<8.4f} {:>+8.1f}\n", name, a.mean,
             a.error, b.mean, b.error, separation(a, b));
}

void stiffness_table(const Options& o) {
  fmt::print("\nTable 1: stiffness sensitivity ({:g} 1/s, {:g} Pa, powder {:g} d at load {:g})\n",
             o.shear_rate, o.normal_stress, o.powder_ratio, o.load);
  CellResult media[2], powder[2];
  const double factors[2] = {1.0, o.stiffer_factor};
  for (int i = 0; i < 2; ++i) {
    media[i] = run_cell(o, {.shear_rate = o.shear_rate, .stiffness_factor = factors[i]});
    powder[i] = run_cell(
        o, {.powder_load = o.load, .shear_rate = o.shear_rate, .stiffness_factor = factors[i]});
  }
  fmt::print("  {:<24} {:>21} {:>21} {:>8}\n", "quantity", "policy default",
             fmt::format("x{:g}", o.stiffer_factor), "diff/se");
  print_row("friction media-only", friction(media[0]), friction(media[1]));
  print_row("friction powder", friction(powder[0]), friction(powder[1]));
  print_row("friction_mean_p media", friction_mean_pressure(media[0]),
            friction_mean_pressure(media[1]));
  print_row("friction_mean_p powder", friction_mean_pressure(powder[0]),
            friction_mean_pressure(powder[1]));
  print_row("powder dissipation share", powder_share(powder[0]), powder_share(powder[1]));
  print_row("cushioning", ratio(media_dissipation(powder[0]), media_dissipation(media[0])),
            ratio(media_dissipation(powder[1]), media_dissipation(media[1])));
}

void inertial_number_table(const Options& o) {
  const json campaign = campaign_for(o, {});
  const double diameter = campaign["media"]["diameter"].get<double>();
  const double density = campaign["materials"]["steel"]["density"].get<double>();
  fmt::print("\nTable 2: mu(I), media only, Lees-Edwards, {:g} Pa\n", o.normal_stress);
  std::vector<CellResult> cells;
  for (const double inertial : o.inertial_numbers) {
    const double rate = inertial * std::sqrt(o.normal_stress / density) / diameter;
    cells.push_back(run_cell(o, {.shear_rate = rate}));
  }
  // Weighted least squares of mu_s alone: mean of mu - rise / (1 + I_0 / I), weights 1 / se^2.
  auto rise = [](double inertial) {
    return kJfpFrictionRise / (1.0 + kJfpInertialNumber / inertial);
  };
  double sum_w = 0.0, sum_wx = 0.0;
  for (const CellResult& r : cells) {
    const double w = 1.0 / std::pow(r.m.friction_error.standard_error, 2);
    sum_w += w;
    sum_wx += w * (r.m.friction - rise(r.m.inertial_number));
  }
  const double mu_s = sum_wx / sum_w, mu_s_error = 1.0 / std::sqrt(sum_w);
  double chi2 = 0.0;
  fmt::print("  {:>8} {:>8} {:>21} {:>21} {:>8} {:>9} {:>8}\n", "I target", "I", "tau/p_yy",
             "tau/p", "JFP fit", "residual", "res/se");
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const CellResult& r = cells[i];
    const double model = mu_s + rise(r.m.inertial_number);
    const double residual = r.m.friction - model;
    const double pull = residual / r.m.friction_error.standard_error;
    chi2 += pull * pull;
    fmt::print(
        "  {:>8.3g} {:>8.3g} {:>9.4f} +- {:<8.4f} {:>9.4f} +- {:<8.4f} {:>8.4f} {:>+9.4f} "
        "{:>+8.1f}\n",
        o.inertial_numbers[i], r.m.inertial_number, r.m.friction, r.m.friction_error.standard_error,
        r.m.friction_mean_pressure, r.m.friction_mean_pressure_error.standard_error, model,
        residual, pull);
  }
  fmt::print("  fitted mu_s = {:.4f} +- {:.4f} (JFP glass: 0.38), chi^2 = {:.1f} over {} dof\n",
             mu_s, mu_s_error, chi2, cells.size() - 1);
}

void dilute_table(const Options& o) {
  fmt::print(
      "\nTable 3: dilute powder ({:g} d at load {:g}) against media only, {:g} 1/s, {:g} Pa\n",
      o.powder_ratio, o.dilute_load, o.shear_rate, o.normal_stress);
  const CellResult media = run_cell(o, {.shear_rate = o.shear_rate});
  const CellResult dilute = run_cell(o, {.powder_load = o.dilute_load, .shear_rate = o.shear_rate});
  fmt::print("  {:<24} {:>21} {:>21} {:>8}\n", "quantity", "media only",
             fmt::format("load {:g}", o.dilute_load), "diff/se");
  print_row("friction", friction(media), friction(dilute));
  print_row("friction_mean_p", friction_mean_pressure(media), friction_mean_pressure(dilute));
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"Shear-cell physics against the outside world (docs/shear_cells.md)"};
  app.add_option("--tables", o.tables, "which tables: 1 stiffness, 2 mu(I), 3 dilute powder")
      ->delimiter(',');
  app.add_option("--size", o.size, "cell size in ball diameters: x y z")->expected(3);
  app.add_option("--threads", o.threads, "threads per cell");
  app.add_option("--shear_rate", o.shear_rate, "site shear rate of tables 1 and 3, 1/s");
  app.add_option("--normal_stress", o.normal_stress, "site normal stress, Pa");
  app.add_option("--powder_ratio", o.powder_ratio, "powder diameter / ball diameter");
  app.add_option("--load", o.load, "powder load of table 1");
  app.add_option("--dilute_load", o.dilute_load, "powder load of table 3");
  app.add_option("--stiffer_factor", o.stiffer_factor, "table 1's stiffer cells, x the policy");
  app.add_option("--inertial_numbers", o.inertial_numbers, "table 2's I")->delimiter(',');
  app.add_option("--warmup_strain", o.warmup_strain, "/shear_cell/warmup_strain");
  app.add_option("--max_warmup_strain", o.max_warmup_strain, "/shear_cell/max_warmup_strain");
  app.add_option("--measure_strain", o.measure_strain, "/shear_cell/measure_strain");
  app.add_option("--max_strain", o.max_strain, "/shear_cell/convergence/max_strain");
  app.add_option("--standard_error", o.standard_error, "/shear_cell/convergence/standard_error");
  app.add_option("--seed", o.seed, "/dem/seed");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);
  const std::set<int> tables(o.tables.begin(), o.tables.end());
  fmt::print(
      "bench_cell_physics: cell {} x {} x {} d, {} thread(s), strains warm-up {:g} (max "
      "{:g}), measure {:g} (max {:g}), standard error target {:g}\n",
      o.size[0], o.size[1], o.size[2], o.threads, o.warmup_strain, o.max_warmup_strain,
      o.measure_strain, o.max_strain, o.standard_error);
  if (tables.contains(1)) stiffness_table(o);
  if (tables.contains(2)) inertial_number_table(o);
  if (tables.contains(3)) dilute_table(o);
  return 0;
}
