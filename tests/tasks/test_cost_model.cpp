// The cost model's inputs (tasks/cost_model.hpp) against what the runs really use: the balls and
// time step of a real mill set-up, the particles and time step of real shear cells (built by the
// cells' own code at a site), and the per-kind estimate of a plan.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "dem/mill_setup.hpp"
#include "dem/shear_cell.hpp"
#include "engine/campaign.hpp"
#include "tasks/campaign.hpp"
#include "tasks/cost_model.hpp"
#include "tasks/kinds.hpp"
#include "tasks/macro_setup.hpp"
#include "tasks/millflow.hpp"
#include "tasks/shear_cell.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace millflow;

const fs::path source_dir = MILLFLOW_SOURCE_DIR;

json first_point(const fs::path& file) {
  return tasks::expand(tasks::load_campaign(source_dir / file)).front().document;
}

// The shear_cell parameters of a point's first slot, with the cell's block changed by `edit`.
json cell_params(json point, const std::function<void(json&)>& edit) {
  edit(point["shear_cell"]);
  json params = tasks::shear_cells_params(point);
  params["slot"] = {{"region", "bulk"}, {"index", 0}};
  return params;
}

// The particles and time step a real cell of these parameters has at `site`.
void expect_cell_inputs_match(const json& params, const json& site) {
  const tasks::ShearCellSize size = tasks::shear_cell_size(params, site);
  dem::ShearCellSetup setup = tasks::shear_cell_setup(params, site, "cell");
  tasks::apply_stiffness_policy(params, setup);
  const dem::ShearCell cell(setup);
  EXPECT_EQ(size.media, cell.media_count());
  EXPECT_EQ(size.powder, cell.powder_count());
  EXPECT_EQ(size.wall_balls, cell.wall_ball_count());
  EXPECT_EQ(size.powder_load, cell.setup().powder_load);
  EXPECT_EQ(size.powder_diameter_ratio, cell.setup().powder_diameter_ratio);
  EXPECT_DOUBLE_EQ(size.time_step_s, cell.system().time_step());
  EXPECT_GT(size.compaction_steps, 0.0);
  EXPECT_NEAR(size.compaction_steps, static_cast<double>(cell.expected_compaction_steps()), 0.5);
  EXPECT_GT(size.shear_steps_at_caps, size.shear_steps);
}

TEST(CostModel, MacroBallsAndTimeStepAreTheMillSetUpsOwn) {
  for (const char* file : {"campaigns/quick.json", "tests/tasks/good_campaigns/minimal.json"}) {
    const json params = tasks::macro_params(first_point(file));
    const tasks::MacroRunSize size = tasks::macro_run_size(params);
    const method::MacroSettings settings = tasks::macro_settings(params, "macro");
    dem::System mill = dem::build_mill(settings.mill);
    mill.set_time_step_from_collisions(settings.steps_per_collision);
    EXPECT_EQ(size.balls, mill.size()) << file;
    EXPECT_DOUBLE_EQ(size.time_step_s, mill.time_step()) << file;
    // Settling, then the revolutions at omega.
    const double omega =
        settings.mill.speed_fraction *
        dem::critical_speed(2 * settings.mill.shell.radius, dem::mean_ball_diameter(settings.mill));
    const double seconds =
        settings.settle_time +
        (settings.warmup_revolutions + settings.measure_revolutions) * 2 * std::numbers::pi / omega;
    EXPECT_NEAR(size.steps * size.time_step_s, seconds, 1e-9 * seconds) << file;
  }
}

TEST(CostModel, ShearCellParticlesAndTimeStepAreTheCellsOwn) {
  const json site = {{"shear_rate_per_s", 5.0}, {"normal_stress_pa", 2.5e4}};
  // The cement campaign's cell (powder 0.125 d, the stiffness policy raising the powder's
  // contacts) made small, with and without powder, Lees-Edwards and walls.
  const json cement = first_point("campaigns/cement_ball_mill.json");
  for (const double load : {0.0, 0.5, 1.5}) {
    for (const char* boundary : {"lees_edwards", "walls"}) {
      SCOPED_TRACE(fmt::format("load {}, {}", load, boundary));
      expect_cell_inputs_match(cell_params(cement,
                                           [&](json& cell) {
                                             cell["size_diameters"] = {3, 3, 3};
                                             cell["boundary"] = boundary;
                                             cell["powder"]["load"] = load;
                                           }),
                               site);
    }
  }
  // quick.json's cell as it is, at load 1, its stiffness kept by the campaign policy and raised.
  const json quick = first_point("campaigns/quick.json");
  for (const char* policy : {"campaign", "overlap_bound"}) {
    SCOPED_TRACE(policy);
    expect_cell_inputs_match(cell_params(quick,
                                         [&](json& cell) {
                                           cell["powder"]["load"] = 1.0;
                                           cell["stiffness"]["policy"] = policy;
                                         }),
                             site);
  }
}

// A stiff cell's powder pairs collide for half as long at 4x their k_n: in quick.json, whose
// pairs all have one collision time, the powder's then sets half the time step.
TEST(CostModel, AStiffCellPaysForItsShorterContacts) {
  const json plain = cell_params(first_point("campaigns/quick.json"),
                                 [](json& cell) { cell["powder"]["load"] = 1.0; });
  json stiff = plain;
  stiff["stiffness_factor"] = 4.0;
  const json site = {{"shear_rate_per_s", 4.0}, {"normal_stress_pa", 2e3}};
  EXPECT_NEAR(tasks::shear_cell_size(stiff, site).time_step_s,
              0.5 * tasks::shear_cell_size(plain, site).time_step_s, 1e-12);
}

// The throughputs are the benches' at the loads, powder sizes and ball counts they were measured
// at, and the cost per particle-step lies between them elsewhere.
TEST(CostModel, ThroughputsAreTheMeasuredOnesAtTheirScenes) {
  using namespace tasks;
  const PowderFamily& fine = kPowderFamilies.front();
  const PowderFamily& coarse = kPowderFamilies.back();
  EXPECT_EQ(cell_throughput(0.0, fine.diameter_ratio), kMediaCellThroughput);
  // Each family's cells (bench_cells' cement_load05 ... cement_load15_d05).
  for (const PowderFamily& family : kPowderFamilies) {
    for (std::size_t k = 0; k < kPowderLoads.size(); ++k) {
      EXPECT_DOUBLE_EQ(cell_throughput(kPowderLoads[k], family.diameter_ratio),
                       family.throughput[k])
          << family.diameter_ratio << " at " << kPowderLoads[k];
    }
  }
  // Between two loads, linear in the load; outside them, the nearer figure.
  EXPECT_DOUBLE_EQ(1.0 / cell_throughput(0.75, fine.diameter_ratio),
                   0.5 / fine.throughput[0] + 0.5 / fine.throughput[1]);
  EXPECT_DOUBLE_EQ(1.0 / cell_throughput(1.25, coarse.diameter_ratio),
                   0.5 / coarse.throughput[1] + 0.5 / coarse.throughput[2]);
  EXPECT_DOUBLE_EQ(cell_throughput(0.2, fine.diameter_ratio), fine.throughput[0]);
  EXPECT_DOUBLE_EQ(cell_throughput(2.0, coarse.diameter_ratio), coarse.throughput[2]);
  // Between two sizes, linear in log(d_p / d); outside them, the nearer family.
  const PowderFamily& middle = kPowderFamilies[1];
  EXPECT_DOUBLE_EQ(
      1.0 / cell_throughput(1.0, std::sqrt(middle.diameter_ratio * coarse.diameter_ratio)),
      0.5 / middle.throughput[1] + 0.5 / coarse.throughput[1]);
  EXPECT_DOUBLE_EQ(cell_throughput(1.5, 0.05), fine.throughput[2]);
  EXPECT_DOUBLE_EQ(cell_throughput(0.5, 0.9), coarse.throughput[0]);
  EXPECT_DOUBLE_EQ(macro_throughput(415.0), kMacroThroughput);
  EXPECT_DOUBLE_EQ(macro_throughput(kLargeMillBalls), kLargeMillThroughput);
  const double balls = 8454.0;  // the cement campaign's smallest charge
  EXPECT_LT(macro_throughput(balls), kMacroThroughput);
  EXPECT_GT(macro_throughput(balls), kLargeMillThroughput);
}

// The fine and the coarse families are the example campaigns' own powders.
TEST(CostModel, PowderFamiliesAreTheCampaignsPowders) {
  const auto ratio = [](const char* file) {
    return first_point(file)["shear_cell"]["powder"]["diameter_ratio"].get<double>();
  };
  EXPECT_EQ(ratio("campaigns/cement_ball_mill.json"),
            tasks::kPowderFamilies.front().diameter_ratio);
  EXPECT_EQ(ratio("campaigns/paper_demo.json"), tasks::kPowderFamilies.front().diameter_ratio);
  EXPECT_EQ(ratio("campaigns/quick.json"), tasks::kPowderFamilies.back().diameter_ratio);
}

TEST(CostModel, ShearStepsAreTheStrainsOverTheStrainPerStep) {
  const json params = cell_params(first_point("campaigns/quick.json"), [](json& cell) {
    cell["warmup_strain"] = 2.0;
    cell["max_warmup_strain"] = 6.0;
    cell["measure_strain"] = 3.0;
    cell["convergence"]["max_strain"] = 5.0;
  });
  const json site = {{"shear_rate_per_s", 4.0}, {"normal_stress_pa", 1e4}};
  const tasks::ShearCellSize size = tasks::shear_cell_size(params, site);
  EXPECT_NEAR(size.shear_steps * 4.0 * size.time_step_s, 5.0, 1e-12);
  EXPECT_NEAR(size.shear_steps_at_caps * 4.0 * size.time_step_s, 11.0, 1e-12);
  // Half the shear rate, twice the steps (the stiffness is the campaign's at these sites).
  const json slower = {{"shear_rate_per_s", 2.0}, {"normal_stress_pa", 1e4}};
  EXPECT_NEAR(tasks::shear_cell_size(params, slower).shear_steps, 2.0 * size.shear_steps,
              1e-9 * size.shear_steps);
}

TEST(CostModel, EstimateOfAPlanCountsEveryTaskAndPricesMacroRunsAndCells) {
  engine::Registry registry;
  tasks::register_millflow(registry);
  const auto campaign = engine::load_campaign_file(registry, source_dir / "campaigns/quick.json");
  const auto planned = engine::plan_campaign(registry, campaign);
  const auto by_kind = tasks::estimate_plan(planned);
  ASSERT_EQ(by_kind.at("macro").tasks, 4);
  EXPECT_EQ(by_kind.at("macro").estimated, 4);
  // 120 cells, and 16 stiff ones (/shear_cell/stiffness/sensitivity) at the points with powder.
  EXPECT_EQ(by_kind.at("shear_cell").tasks, 136);
  EXPECT_EQ(by_kind.at("shear_cell").estimated, 136);
  EXPECT_EQ(by_kind.at("average").estimated, 0);
  // Cells at load 0 have balls only; at load 1 the powder: the particle range spans both.
  const json point = first_point("campaigns/quick.json");
  const json media_only = cell_params(point, [](json& cell) { cell["powder"]["load"] = 0.0; });
  const json site = tasks::typical_site(tasks::macro_params(point), "bulk");
  EXPECT_EQ(by_kind.at("shear_cell").particles_min,
            static_cast<double>(tasks::shear_cell_size(media_only, site).media));
  EXPECT_GT(by_kind.at("shear_cell").particles_max, by_kind.at("shear_cell").particles_min);
  double macro_seconds = 0.0;
  for (const auto& spec : planned) {
    if (spec.kind == "macro") macro_seconds += tasks::macro_cost(spec.params).core_seconds;
  }
  EXPECT_DOUBLE_EQ(by_kind.at("macro").core_seconds, macro_seconds);
  EXPECT_GE(by_kind.at("shear_cell").core_seconds_at_caps, by_kind.at("shear_cell").core_seconds);
  // Each kind that has a cost model gives the engine one (the ETA).
  EXPECT_TRUE(registry.kinds.get("macro").cost);
  EXPECT_TRUE(registry.kinds.get("shear_cell").cost);
  EXPECT_FALSE(registry.kinds.get("average").cost);
}

// quick.json's plan, one of its toe cells and a site for that cell's slot (7 1/s, 3 kPa): what a
// stored sites result would hold.
struct PlanWithASite {
  std::vector<engine::TaskSpec> planned;
  std::size_t cell = 0;  // index into planned
  json site;
};
PlanWithASite quick_plan_with_a_toe_site() {
  engine::Registry registry;
  tasks::register_millflow(registry);
  const auto campaign = engine::load_campaign_file(registry, source_dir / "campaigns/quick.json");
  PlanWithASite plan;
  plan.planned = engine::plan_campaign(registry, campaign);
  for (std::size_t k = 0; k < plan.planned.size(); ++k) {
    const engine::TaskSpec& spec = plan.planned[k];
    if (spec.kind == "shear_cell" && spec.params.at("slot").at("region") == "toe") plan.cell = k;
  }
  plan.site = {{"site_id", tasks::slot_site_id(plan.planned[plan.cell].params.at("slot"))},
               {"shear_rate_per_s", 7.0},
               {"normal_stress_pa", 3e3}};
  return plan;
}

// A lookup over a plan's tasks, each with the stored result `result_of` gives it (or null).
engine::TaskLookup lookup_in(const std::vector<engine::TaskSpec>& planned,
                             const std::function<const json*(const engine::TaskSpec&)>& result_of) {
  return [&planned, result_of](const std::string& key) {
    for (const auto& spec : planned)
      if (spec.key == key) return engine::KnownTask{&spec, result_of(spec)};
    return engine::KnownTask{};
  };
}

TEST(CostModel, ACellOnceItsSiteIsKnownCostsThatSitesAndAnEmptySlotNothing) {
  const PlanWithASite plan = quick_plan_with_a_toe_site();
  const auto& planned = plan.planned;
  const engine::TaskSpec* cell = &planned[plan.cell];
  ASSERT_EQ(cell->kind, "shear_cell");
  const json& site = plan.site;
  json sites_result = {{"sites", json::array({site})}};
  const engine::TaskLookup lookup = lookup_in(planned, [&](const engine::TaskSpec& spec) {
    return spec.kind == "sites" ? &sites_result : nullptr;
  });
  const auto known = tasks::task_cost(*cell, lookup);
  ASSERT_TRUE(known);
  EXPECT_DOUBLE_EQ(known->core_seconds, tasks::shear_cell_cost(cell->params, site).core_seconds);
  sites_result["sites"] = json::array();
  const auto empty = tasks::task_cost(*cell, lookup);
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->core_seconds, 0.0);
}

// With a sites task's result (the dry run of a campaign whose sites ran), its cells are priced at
// their own sites, a slot without a site at nothing and outside the particle and step ranges; the
// cells of the other sweep points stay at their regions' typical sites.
TEST(CostModel, AnEstimateWithStoredSitesPricesEachCellAtItsOwnSite) {
  const PlanWithASite plan = quick_plan_with_a_toe_site();
  const auto& planned = plan.planned;
  ASSERT_EQ(planned[plan.cell].kind, "shear_cell");
  const std::string sites_key = planned[plan.cell].upstream.at(0);
  const json& site = plan.site;
  const json sites_result = {{"sites", json::array({site})}};
  const auto stored = [&](const std::string& key) -> const json* {
    return key == sites_key ? &sites_result : nullptr;
  };
  const auto by_kind = tasks::estimate_plan(planned, {}, stored);
  // What each cell costs as the ETA prices it, with the same stored result.
  const engine::TaskLookup lookup =
      lookup_in(planned, [&](const engine::TaskSpec& spec) { return stored(spec.key); });
  double seconds = 0.0;
  // The sites task's cells, and of them those of the one stored site (its slot at every load,
  // and the stiff ones of it).
  int sized = 0, below_the_sites = 0, at_the_site = 0;
  for (const auto& spec : planned) {
    if (spec.kind != "shear_cell") continue;
    const auto cost = tasks::task_cost(spec, lookup);
    ASSERT_TRUE(cost);
    seconds += cost->core_seconds;
    sized += cost->particles > 0.0;
    if (spec.upstream.at(0) != sites_key) continue;
    ++below_the_sites;
    if (tasks::slot_site_id(spec.params.at("slot")) == site.at("site_id")) {
      ++at_the_site;
      EXPECT_DOUBLE_EQ(cost->core_seconds, tasks::shear_cell_cost(spec.params, site).core_seconds);
    }
  }
  const tasks::KindEstimate& cells = by_kind.at("shear_cell");
  EXPECT_EQ(cells.estimated, 136);
  EXPECT_EQ(cells.sized, sized);
  EXPECT_GT(below_the_sites, at_the_site);
  EXPECT_GE(at_the_site, 1);
  EXPECT_EQ(sized, 136 - below_the_sites + at_the_site);
  EXPECT_DOUBLE_EQ(cells.core_seconds, seconds);
  EXPECT_GT(cells.particles_min, 0.0);
  EXPECT_NE(cells.core_seconds, tasks::estimate_plan(planned).at("shear_cell").core_seconds);
}

// A campaign's fields are bounded, but nothing bounds what a cell's site asks of it: an estimate
// far beyond reach still reads as a number.
TEST(CostModel, AnEstimateBeyondReachPrintsAPowerOfTenNotARunOfDigits) {
  tasks::KindEstimate cell;
  cell.tasks = cell.estimated = 1;
  cell.particles_min = cell.particles_max = 1000.0;
  cell.steps_min = cell.steps_max = 1e20;
  cell.core_seconds = 3.6e6;           // 1000 core-hours: whole hours
  cell.core_seconds_at_caps = 3.6e50;  // 1e47 core-hours
  const std::string text = tasks::format_estimate({{"shear_cell", cell}});
  EXPECT_NE(text.find("1000 - 1e+47"), std::string::npos) << text;
  EXPECT_EQ(text.find("00000000"), std::string::npos) << text;
}

}  // namespace
