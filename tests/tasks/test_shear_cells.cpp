// The shear_cell kind: planning per sweep point (a cell per site slot and load, an upscale per
// point), finding a slot's site, the translation of campaign parameters into a cell, and tiny
// cells run through the task function.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <set>

#include "dem/material.hpp"
#include "dem/skin_choice.hpp"
#include "engine/campaign.hpp"
#include "tasks/millflow.hpp"
#include "tasks/shear_cell.hpp"
#include "tests/common/scratch_dir.hpp"
#include "tests/tasks/golden.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

json tiny_cell_params(double powder_load) {
  return json::parse(R"({
    "materials": {"steel": {"density": 7800}, "clinker": {"density": 3150}},
    "interactions": [
      {"materials": ["steel", "steel"], "restitution": 0.5, "friction": 0.5, "stiffness": {"collision_time": 0.001}},
      {"materials": ["steel", "clinker"], "restitution": 0.4, "friction": 0.5, "stiffness": {"collision_time": 0.0008}},
      {"materials": ["clinker", "clinker"], "restitution": 0.3, "friction": 0.5, "stiffness": {"collision_time": 0.0006}}],
    "dem": {"seed": 3, "neighbor_skin_fraction": 0.3},
    "media": {"material": "steel", "diameter": 0.01},
    "shear_cell": {"boundary": "walls", "size_diameters": [4, 4, 4], "gravity": false,
                   "warmup_strain": 0.5, "max_warmup_strain": 0.5, "measure_strain": 1.0,
                   "convergence": {"standard_error": 0.03, "max_strain": 1.0},
                   "stiffness": {"policy": "overlap_bound", "mean_overlap_fraction": 0.01,
                                 "p95_overlap_fraction": 0.03},
                   "stress_control": {"gain": 0.5},
                   "checkpoint_interval_s": 60, "steps_per_collision": 20,
                   "powder": {"material": "clinker", "diameter_ratio": 0.5, "load": 0}},
    "slot": {"region": "toe", "index": 0}
  })")
      .patch(json::array(
          {{{"op", "replace"}, {"path", "/shear_cell/powder/load"}, {"value", powder_load}}}));
}

json tiny_site() {
  return {{"site_id", "toe-0"},         {"region", "toe"},          {"shear_rate_per_s", 20.0},
          {"normal_stress_pa", 2000.0}, {"shear_stress_pa", 900.0}, {"weight_m3", 0.001},
          {"dissipation_share", 0.2},   {"position_m", {0.1, -0.3}}};
}

engine::TaskInput sites_input() {
  return engine::TaskInput{
      .key = "sites-key", .kind = "sites", .result = {{"sites", {tiny_site()}}}, .artifacts = {}};
}

struct Direct {
  json params;
  std::vector<engine::TaskInput> inputs;
  std::string key = "tiny-cell";
  millflow::testing::ScratchDir dir{};

  engine::TaskOutcome run(engine::RunFunction function) const {
    engine::TaskContext context{.key = key,
                                .params = params,
                                .inputs = inputs,
                                .work_dir = dir.path() / "work",
                                .threads = 2,
                                .stop = {},
                                .progress = [](double, std::string_view) {},
                                .log = [](std::string_view) {}};
    engine::TaskOutcome outcome;
    tbb::task_arena arena(2);
    arena.execute([&] { outcome = function(context); });
    return outcome;
  }
};

// campaigns/quick.json with its shear cells switched on or off, and without its stiff cells
// (/shear_cell/stiffness/sensitivity) unless asked.
std::vector<engine::TaskSpec> quick_plan(bool shear_cells, bool stiffness_sensitivity = false) {
  engine::Registry registry;
  register_millflow(registry);
  auto campaign = engine::load_campaign_file(registry, MILLFLOW_SOURCE_DIR "/campaigns/quick.json");
  campaign.document["shear_cell"]["enabled"] = shear_cells;
  if (!stiffness_sensitivity) campaign.document["shear_cell"]["stiffness"].erase("sensitivity");
  return engine::plan_campaign(registry, campaign);
}

TEST(ShearCellsPlan, StiffnessSensitivityAddsStiffCellsAtLoadedPointsAndRekeysNoOtherCell) {
  const auto plain = quick_plan(true);
  const auto with = quick_plan(true, true);
  std::map<std::string, const engine::TaskSpec*> by_key;
  for (const auto& task : with) by_key[task.key] = &task;
  // Without the setting no task has a trace of it; with it every macro, average, sites and
  // default cell keeps its key (so its cached result), only the upscales and the report gain
  // inputs.
  for (const auto& task : plain) {
    EXPECT_FALSE(task.params.contains("stiffness_factor"));
    if (task.kind == "shear_cell") {
      EXPECT_FALSE(task.params.at("shear_cell").at("stiffness").contains("sensitivity"));
    }
    if (task.kind != "upscale" && task.kind != "report") {
      EXPECT_TRUE(by_key.count(task.key)) << task.kind << " " << task.key;
    }
  }
  // quick.json: factor 4 at the first site of the toe and the bulk, at the 2 x 2 x 2 points with
  // powder (without powder the stiff cell would be the default one, its own reference).
  std::set<std::string> stiff;
  for (const auto& task : with) {
    if (!task.params.contains("stiffness_factor")) continue;
    stiff.insert(task.key);
    EXPECT_EQ(task.kind, "shear_cell");
    EXPECT_EQ(task.params.at("stiffness_factor"), 4.0);
    EXPECT_EQ(task.params.at("slot").at("index"), 0);
    EXPECT_TRUE(task.params.at("slot").at("region") == "toe" ||
                task.params.at("slot").at("region") == "bulk");
    EXPECT_NE(task.params.at("shear_cell").at("powder").at("load"), 0.0);
  }
  EXPECT_EQ(stiff.size(), 4u * 2 * 2);
  EXPECT_EQ(with.size(), plain.size() + stiff.size());
  for (const auto& task : with) {
    if (task.kind != "upscale") continue;
    const std::size_t stiff_inputs = std::count_if(task.upstream.begin(), task.upstream.end(),
                                                   [&](const auto& k) { return stiff.count(k); });
    EXPECT_EQ(stiff_inputs, task.params.at("powder_load") == 0.0 ? 0u : 2u);
  }
}

TEST(ShearCellsPlan, DisabledShearCellsStopTheDagAtTheSites) {
  for (const auto& task : quick_plan(false)) {
    EXPECT_TRUE(task.kind == "macro" || task.kind == "average" || task.kind == "sites")
        << task.kind;
  }
}

TEST(ShearCellsPlan, MacroOnlyCampaignNeedsNoPowder) {
  engine::Registry registry;
  register_millflow(registry);
  const auto campaign = engine::load_campaign_file(
      registry, MILLFLOW_SOURCE_DIR "/tests/tasks/good_campaigns/macro_only.json");
  std::vector<std::string> kinds;
  for (const auto& task : engine::plan_campaign(registry, campaign)) kinds.push_back(task.kind);
  EXPECT_EQ(kinds, (std::vector<std::string>{"macro", "average", "sites"}));
}

TEST(ShearCellsPlan, EverySlotAndLoadHasACellBelowSharedSitesAndEveryPointAnUpscaleAndOneReport) {
  const auto tasks = quick_plan(true);
  std::map<std::string, int> per_kind;
  std::map<std::string, const engine::TaskSpec*> by_key;
  for (const auto& task : tasks) {
    ++per_kind[task.kind];
    by_key[task.key] = &task;
  }
  // 2 fills x 2 speeds; 5 regions x 2 sites per region; loads 0, 0.5, 1.
  EXPECT_EQ(per_kind["macro"], 4);
  EXPECT_EQ(per_kind["average"], 4);
  EXPECT_EQ(per_kind["sites"], 4);
  EXPECT_EQ(per_kind["shear_cell"], 4 * 10 * 3);
  EXPECT_EQ(per_kind["upscale"], 4 * 3);
  ASSERT_EQ(per_kind["report"], 1);

  for (const auto& task : tasks) {
    if (task.kind == "shear_cell") {
      ASSERT_EQ(task.upstream.size(), 1u);
      EXPECT_EQ(by_key[task.upstream[0]]->kind, "sites");
      EXPECT_EQ(task.params.at("materials").size(), 2u);  // steel and clinker
      EXPECT_EQ(task.params.at("interactions").size(), 3u);
      EXPECT_TRUE(task.params.at("slot").contains("region"));
      EXPECT_FALSE(task.params.contains("macro"));  // a macro setting must not re-key the cells
      // nor the macro runs' time step (the seed and the neighbour skin are shared)
      EXPECT_EQ(task.params.at("dem"), json({{"seed", 1}, {"neighbor_skin_fraction", 0.3}}));
    }
    if (task.kind == "report") {
      // Every upscale, and each fill and speed's macro, average and sites once (its charge shape,
      // spectra and maps).
      std::map<std::string, int> upstream_kinds;
      for (const auto& key : task.upstream) ++upstream_kinds[by_key.at(key)->kind];
      EXPECT_EQ(upstream_kinds, (std::map<std::string, int>{
                                    {"macro", 4}, {"average", 4}, {"sites", 4}, {"upscale", 12}}));
    }
    if (task.kind != "upscale") continue;
    // Its macro, average and sites, its 10 cells, and the 10 without powder unless it has none.
    const double load = task.params.at("powder_load");
    std::map<std::string, int> upstream_kinds;
    std::set<double> cell_loads;
    for (const auto& key : task.upstream) {
      const engine::TaskSpec& up = *by_key.at(key);
      ++upstream_kinds[up.kind];
      if (up.kind == "shear_cell")
        cell_loads.insert(up.params.at("shear_cell").at("powder").at("load").get<double>());
    }
    EXPECT_EQ(upstream_kinds["macro"], 1);
    EXPECT_EQ(upstream_kinds["average"], 1);
    EXPECT_EQ(upstream_kinds["sites"], 1);
    EXPECT_EQ(upstream_kinds["shear_cell"], load == 0.0 ? 10 : 20);
    const std::set<double> expected =
        load == 0.0 ? std::set<double>{0.0} : std::set<double>{0.0, load};
    EXPECT_EQ(cell_loads, expected);
  }
}

json site(const std::string& id, double shear_rate, double normal_stress) {
  return {{"site_id", id},
          {"region", "toe"},
          {"shear_rate_per_s", shear_rate},
          {"normal_stress_pa", normal_stress},
          {"weight_m3", 0.002},
          {"dissipation_share", 0.1},
          {"shear_stress_pa", 800.0},
          {"pressure_pa", 5.0},
          {"position_m", {0.1, -0.2}}};
}

TEST(ShearCellSlot, FindsItsSiteOrSaysWhyThereIsNone) {
  const json sites = {
      {"sites", {site("toe-0", 4.0, 100.0), site("toe-1", 0.0, 100.0), site("toe-2", 3.0, -1.0)}}};
  const SlotSite found = find_slot_site(sites, {{"region", "toe"}, {"index", 0}});
  EXPECT_TRUE(found.skipped.empty());
  EXPECT_EQ(found.site, sites["sites"][0]);
  EXPECT_EQ(find_slot_site(sites, {{"region", "toe"}, {"index", 1}}).skipped,
            "shear_rate_per_s = 0 is not positive");
  EXPECT_EQ(find_slot_site(sites, {{"region", "toe"}, {"index", 2}}).skipped,
            "normal_stress_pa = -1 is not positive");
  EXPECT_EQ(find_slot_site(sites, {{"region", "bulk"}, {"index", 0}}).skipped,
            "the sites task chose no site bulk-0 (region bulk has fewer cells or none)");
}

TEST(ShearCellSlot, AnEmptySlotFinishesAtOnceAndSaysWhy) {
  json params = tiny_cell_params(0.5);
  params["slot"] = {{"region", "bulk"}, {"index", 3}};
  const auto outcome = Direct{.params = params, .inputs = {sites_input()}}.run(run_shear_cell);
  EXPECT_EQ(outcome.result.at("skipped"),
            "the sites task chose no site bulk-3 (region bulk has fewer cells or none)");
  EXPECT_EQ(outcome.result.at("powder_load"), 0.5);
  EXPECT_FALSE(outcome.result.contains("shear_stress_pa"));
  EXPECT_FALSE(outcome.result.contains("stiffness_factor"));
  params["stiffness_factor"] = 4.0;  // a stiff cell's slot says so even when empty
  const auto stiff = Direct{.params = params, .inputs = {sites_input()}}.run(run_shear_cell);
  EXPECT_EQ(stiff.result.at("stiffness_factor"), 4.0);
}

TEST(ShearCellSetup, CollisionTimesHoldForEachPairsReferenceParticles) {
  const dem::ShearCellSetup setup = shear_cell_setup(tiny_cell_params(0.3), tiny_site(), "key");
  EXPECT_DOUBLE_EQ(setup.media_diameter, 0.01);
  EXPECT_DOUBLE_EQ(setup.powder.density, 3150.0);
  EXPECT_DOUBLE_EQ(setup.shear_rate, 20.0);
  EXPECT_DOUBLE_EQ(setup.normal_stress, 2000.0);
  EXPECT_DOUBLE_EQ(setup.powder_load, 0.3);
  EXPECT_EQ(setup.boundary, dem::ShearCellSetup::Boundary::RoughWalls);
  const double pi = 3.14159265358979323846;
  const double ball = 7800.0 * pi * std::pow(0.01, 3) / 6.0,
               grain = 3150.0 * pi * std::pow(0.005, 3) / 6.0;
  auto duration = [](const dem::InteractionSpec& spec, double m_a, double m_b) {
    return dem::collision_duration(spec.normal_stiffness, m_a * m_b / (m_a + m_b),
                                   dem::damping_ratio_for_restitution(spec.restitution));
  };
  EXPECT_NEAR(duration(setup.media_media, ball, ball), 1e-3, 1e-9);
  EXPECT_NEAR(duration(setup.media_powder, ball, grain), 8e-4, 1e-9);
  EXPECT_NEAR(duration(setup.powder_powder, grain, grain), 6e-4, 1e-9);
  EXPECT_NE(setup.seed, shear_cell_setup(tiny_cell_params(0.3), tiny_site(), "other key").seed);
  json finer = tiny_cell_params(0.3);
  finer["shear_cell"]["steps_per_collision"] = 80;
  EXPECT_EQ(shear_cell_setup(finer, tiny_site(), "key").steps_per_collision, 80);
  // The campaign's neighbour skin reaches the cell's system.
  json wider = tiny_cell_params(0.3);
  wider["dem"]["neighbor_skin_fraction"] = 0.5;
  const dem::ShearCellSetup wide_setup = shear_cell_setup(wider, tiny_site(), "key");
  EXPECT_EQ(wide_setup.neighbor_skin_fraction, std::optional(0.5));
  const dem::ShearCell cell(wide_setup);
  const auto radii = cell.system().radii();
  EXPECT_DOUBLE_EQ(cell.system().neighbor_skin(),
                   0.5 * 2.0 * *std::min_element(radii.begin(), radii.end()));
  // "auto" leaves the skin to the cell (chosen by trial after its first warm-up window).
  json chosen = tiny_cell_params(0.3);
  chosen["dem"]["neighbor_skin_fraction"] = "auto";
  EXPECT_EQ(shear_cell_setup(chosen, tiny_site(), "key").neighbor_skin_fraction, std::nullopt);
}

TEST(ShearCell, TinyMediaCellGivesFiniteStressesAndNoPowderDissipation) {
  const Direct direct{.params = tiny_cell_params(0.0), .inputs = {sites_input()}};
  const auto outcome = direct.run(run_shear_cell);
  ASSERT_FALSE(outcome.interrupted);
  const json& r = outcome.result;
  EXPECT_EQ(r.at("powder_count"), 0);
  EXPECT_GT(r.at("media_count").get<int>(), 0);
  const double tau = r.at("shear_stress_pa"), p = r.at("normal_stress_pa");
  EXPECT_TRUE(std::isfinite(tau) && std::isfinite(p));
  EXPECT_GT(p, 0.0);
  EXPECT_NEAR(r.at("friction").get<double>(), tau / p, 1e-12 * std::abs(tau / p));
  EXPECT_GT(r.at("power_density_w_m3").get<double>(), 0.0);
  EXPECT_EQ(r.at("powder_dissipation_w_m3").get<double>(), 0.0);
  EXPECT_GT(r.at("dissipation_w_m3").at("total").get<double>(), 0.0);
  EXPECT_EQ(r.at("site"), tiny_site());
  EXPECT_EQ(r.at("powder_load"), 0.0);
  // The ParaView snapshot: one point per free particle.
  ASSERT_EQ(outcome.artifacts.size(), 1u);
  EXPECT_EQ(outcome.artifacts[0].name, "cell.vtp");
  std::ifstream snapshot(outcome.artifacts[0].file);
  const std::string text((std::istreambuf_iterator<char>(snapshot)),
                         std::istreambuf_iterator<char>());
  EXPECT_NE(text.find(fmt::format("NumberOfPoints=\"{}\"", r.at("media_count").get<int>())),
            std::string::npos);
}

TEST(ShearCell, PowderInTheCellDissipates) {
  const auto outcome =
      Direct{.params = tiny_cell_params(0.1), .inputs = {sites_input()}}.run(run_shear_cell);
  const json& r = outcome.result;
  EXPECT_GT(r.at("powder_count").get<int>(), 0);
  EXPECT_GT(r.at("powder_dissipation_w_m3").get<double>(), 0.0);
  EXPECT_TRUE(std::isfinite(r.at("friction").get<double>()));
  // The stresses as others define them: p = trace / 3, friction against it beside tau / p_yy.
  const json& stresses = r.at("stresses");
  const double p = (stresses.at("xx").get<double>() + stresses.at("yy").get<double>() +
                    stresses.at("zz").get<double>()) /
                   3.0;
  EXPECT_NEAR(stresses.at("mean_pressure_pa").get<double>(), p, 1e-9 * p);
  EXPECT_EQ(stresses.at("p_yy_pa"), r.at("normal_stress_pa"));
  EXPECT_NEAR(r.at("friction_mean_pressure").get<double>(),
              r.at("shear_stress_pa").get<double>() / p, 1e-9);
  EXPECT_TRUE(r.contains("inertial_number_measured_rate"));
  // Standard errors, flags and overlaps for the upscaling and the report.
  for (const char* key : {"friction", "friction_mean_pressure", "shear_stress_pa",
                          "normal_stress_pa", "power_density_w_m3", "powder_dissipation_w_m3"})
    EXPECT_GT(r.at("standard_errors").at(key).get<double>(), 0.0) << key;
  EXPECT_TRUE(r.at("standard_errors").at("dissipation_w_m3").contains("total"));
  EXPECT_TRUE(r.at("converged").is_boolean());
  EXPECT_TRUE(r.at("steady").is_boolean());
  EXPECT_TRUE(r.contains("stationary_strain"));
  for (const char* pair : {"media-media", "media-powder"}) {
    const json& o = r.at("overlap").at(pair);
    EXPECT_LE(o.at("mean_fraction").get<double>(), o.at("p95_fraction").get<double>()) << pair;
    EXPECT_LE(o.at("p95_fraction").get<double>(), o.at("max_fraction").get<double>()) << pair;
  }
  EXPECT_GE(r.at("overlap_p95_fraction").get<double>(),
            r.at("overlap").at("media-media").at("p95_fraction").get<double>());
  EXPECT_EQ(r.at("overlap_ok").get<bool>(), r.at("overlap_p95_fraction").get<double>() <= 0.03);
  // The policy's static bound for the powder pairs at the site's 2 kPa: S sigma d_m^2 / (f d_s)
  // = 2 x 2000 x 1e-4 / (0.01 x 0.005) = 8000 N/m; each pair takes the largest of the bounds and
  // the stiffness given.
  for (const char* pair : {"media-powder", "powder-powder"}) {
    const json& k = r.at("stiffness").at(pair);
    EXPECT_NEAR(k.at("static_bound_n_m").get<double>(), 8000.0, 1e-6) << pair;
    EXPECT_EQ(k.at("k_n_n_m").get<double>(),
              std::max({k.at("given_n_m").get<double>(), k.at("static_bound_n_m").get<double>(),
                        k.at("impact_bound_n_m").get<double>()}))
        << pair;
    EXPECT_NE(k.at("governing").get<std::string>(), "given") << pair;
  }
  EXPECT_GT(r.at("stiffness").at("powder-powder").at("k_n_n_m").get<double>(),
            r.at("stiffness").at("powder-powder").at("given_n_m").get<double>());
}

TEST(ShearCellSetup, CampaignStiffnessPolicyKeepsTheGivenStiffness) {
  json params = tiny_cell_params(0.3);
  dem::ShearCellSetup setup = shear_cell_setup(params, tiny_site(), "key");
  const double given = setup.powder_powder.normal_stiffness;
  params["shear_cell"]["stiffness"]["policy"] = "campaign";
  const auto kept = apply_stiffness_policy(params, setup);
  EXPECT_EQ(setup.powder_powder.normal_stiffness, given);
  EXPECT_EQ(kept.at(2).chosen, given);
  EXPECT_NEAR(kept.at(2).kappa, given / (2000.0 * 0.005), 1e-9 * given);
  params["shear_cell"]["stiffness"]["policy"] = "overlap_bound";
  const auto raised = apply_stiffness_policy(params, setup);
  EXPECT_GT(setup.powder_powder.normal_stiffness, given);
  EXPECT_EQ(raised.at(2).chosen, setup.powder_powder.normal_stiffness);
}

TEST(ShearCellSetup, MediaRigidityRaisesOnlyTheBallsAndIsOffWhenAbsent) {
  json params = tiny_cell_params(0.3);
  dem::ShearCellSetup setup = shear_cell_setup(params, tiny_site(), "key");
  EXPECT_EQ(setup.overlap_bound.media_rigidity, 0.0);
  dem::ShearCellSetup plain = setup;
  const auto without = apply_stiffness_policy(params, plain);

  params["shear_cell"]["stiffness"]["media_rigidity"] = 1e6;
  setup = shear_cell_setup(params, tiny_site(), "key");
  EXPECT_EQ(setup.overlap_bound.media_rigidity, 1e6);
  const auto with = apply_stiffness_policy(params, setup);
  // 1e6 x 2000 Pa x 0.01 m, above what the collision time of 1 ms gives the balls.
  EXPECT_DOUBLE_EQ(with.at(0).rigidity_bound, 2e7);
  EXPECT_EQ(with.at(0).governing, "rigidity");
  EXPECT_DOUBLE_EQ(setup.media_media.normal_stiffness, 2e7);
  EXPECT_EQ(setup.media_powder.normal_stiffness, plain.media_powder.normal_stiffness);
  EXPECT_EQ(setup.powder_powder.normal_stiffness, plain.powder_powder.normal_stiffness);
  EXPECT_LT(without.at(0).chosen, 2e7);
}

TEST(ShearCellSetup, StiffnessFactorMultipliesOnlyThePowderPairsAfterThePolicy) {
  json params = tiny_cell_params(0.3);
  dem::ShearCellSetup plain = shear_cell_setup(params, tiny_site(), "key");
  const auto policy = apply_stiffness_policy(params, plain);
  EXPECT_FALSE(stiffness_factor(params));
  params["stiffness_factor"] = 4.0;
  dem::ShearCellSetup setup = shear_cell_setup(params, tiny_site(), "key");
  const auto stiff = apply_stiffness_policy(params, setup);
  EXPECT_EQ(setup.media_media.normal_stiffness, plain.media_media.normal_stiffness);
  EXPECT_DOUBLE_EQ(setup.media_powder.normal_stiffness, 4.0 * plain.media_powder.normal_stiffness);
  EXPECT_DOUBLE_EQ(setup.powder_powder.normal_stiffness,
                   4.0 * plain.powder_powder.normal_stiffness);
  // What the result stores and the log shows is the stiffened k_n, beside the policy's bounds.
  EXPECT_EQ(stiff.at(0).chosen, policy.at(0).chosen);
  for (std::size_t pair : {1u, 2u}) {
    EXPECT_DOUBLE_EQ(stiff.at(pair).chosen, 4.0 * policy.at(pair).chosen);
    EXPECT_DOUBLE_EQ(stiff.at(pair).kappa, 4.0 * policy.at(pair).kappa);
    EXPECT_EQ(stiff.at(pair).static_bound, policy.at(pair).static_bound);
  }
  EXPECT_NE(stiffness_log(stiff, setup, 4.0).find("the powder pairs' k_n 4 x the policy's"),
            std::string::npos);
}

// One attempt of a task in a work directory kept across attempts: stopped when it reports
// progress for the `stop_at`-th time (never when 0, before its first step when -1), counting
// only the reports of a phase whose name starts with `phase` when one is given; its log lines
// kept.
struct Attempt {
  engine::TaskOutcome outcome;
  std::vector<std::string> log;
};

Attempt attempt(const json& params, const std::filesystem::path& work_dir, int stop_at,
                std::string_view phase = {}) {
  const std::vector<engine::TaskInput> inputs = {sites_input()};
  std::stop_source stop;
  if (stop_at == -1) stop.request_stop();
  int reports = 0;
  Attempt result;
  engine::TaskContext context{.key = "tiny-cell",
                              .params = params,
                              .inputs = inputs,
                              .work_dir = work_dir,
                              .threads = 2,
                              .stop = stop.get_token(),
                              .progress =
                                  [&](double, std::string_view name) {
                                    if (name.starts_with(phase) && ++reports == stop_at)
                                      stop.request_stop();
                                  },
                              .log = [&](std::string_view line) { result.log.emplace_back(line); }};
  tbb::task_arena arena(2);
  arena.execute([&] { result.outcome = run_shear_cell(context); });
  return result;
}

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream stream(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
}

// The tiny powder cell's results (walls, load 0.1, seed 3, key "tiny-cell") pin the kind's
// version: tests/tasks/golden/shear_cell.json.
TEST(ShearCell, Golden) {
  const millflow::testing::ScratchDir dir;
  const json r = attempt(tiny_cell_params(0.1), dir.path() / "work", 0).outcome.result;
  json values;
  for (const char* pointer :
       {"/media_count", "/powder_count", "/steps", "/bulk_shear_rate_per_s", "/gap_m",
        "/shear_stress_pa", "/normal_stress_pa", "/power_density_w_m3", "/dissipation_w_m3/total",
        "/powder_dissipation_w_m3", "/collisions/media/count", "/collisions/powder/count",
        "/energy/balance_error", "/media_solid_fraction", "/stresses/mean_pressure_pa",
        "/standard_errors/friction", "/overlap_p95_fraction", "/stiffness/powder-powder/k_n_n_m"}) {
    values[pointer] = r.at(json::json_pointer(pointer));
  }
  millflow::testing::check_golden("shear_cell", kShearCellVersion, values);
}

TEST(ShearCell, StopsBeforeTheFirstStepWhenAskedAndKeepsACheckpoint) {
  const millflow::testing::ScratchDir dir;
  const Attempt stopped = attempt(tiny_cell_params(0.0), dir.path() / "work", -1);
  EXPECT_TRUE(stopped.outcome.interrupted);
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "work" / "cell.ckpt"));
}

// Stopped five times (twice while it compacts, in the warm-up's first and second windows and in
// the measurement: the tiny cell reports progress every 100 steps), each attempt continuing from
// the last one's checkpoint: the same result bytes and snapshot as one attempt.
TEST(ShearCell, AnInterruptedCellContinuesFromItsCheckpointToTheSameResult) {
  const json params = tiny_cell_params(0.1);
  const millflow::testing::ScratchDir once, interrupted;
  const Attempt reference = attempt(params, once.path() / "work", 0);
  ASSERT_FALSE(reference.outcome.interrupted);
  // The log says once how compaction ended (under load: no warning).
  EXPECT_EQ(std::ranges::count_if(reference.log,
                                  [](const std::string& line) {
                                    return line.starts_with("shear cell: compacted in ");
                                  }),
            1);
  const std::filesystem::path work = interrupted.path() / "work";
  std::vector<std::string> stops;
  for (const auto& [stop_at, phase] : {std::pair{1, "compacting"},
                                       {2, "compacting"},
                                       {1, "warm-up window 1 "},
                                       {2, "warm-up window 2 "},
                                       {2, "measuring"}}) {
    const Attempt stopped = attempt(params, work, stop_at, phase);
    ASSERT_TRUE(stopped.outcome.interrupted) << "stop at report " << stop_at << " of " << phase;
    stops.push_back(stopped.log.back());
  }
  EXPECT_NE(stops[0].find("(compacting)"), std::string::npos) << stops[0];
  EXPECT_NE(stops[1].find("(compacting)"), std::string::npos) << stops[1];
  EXPECT_NE(stops[2].find("(warm-up window 1 (at most 4))"), std::string::npos) << stops[2];
  EXPECT_NE(stops[3].find("(warm-up window 2 (at most 4))"), std::string::npos) << stops[3];
  EXPECT_NE(stops[4].find("(measuring)"), std::string::npos) << stops[4];
  const Attempt last = attempt(params, work, 0);
  ASSERT_FALSE(last.outcome.interrupted);
  EXPECT_NE(last.log.front().find("shear cell: continuing from the checkpoint at step"),
            std::string::npos)
      << last.log.front();
  EXPECT_EQ(last.outcome.result.dump(), reference.outcome.result.dump());
  ASSERT_EQ(last.outcome.artifacts.size(), 1u);
  EXPECT_EQ(file_bytes(last.outcome.artifacts[0].file),
            file_bytes(reference.outcome.artifacts[0].file));
  EXPECT_FALSE(std::filesystem::exists(work / "cell.ckpt"))
      << "a finished cell leaves no checkpoint";
}

// An "auto" cell reports the skin it chose, one of the candidates, and otherwise the same result
// bytes as at the campaign's 0.3 (no result depends on the skin), which it reports too.
TEST(ShearCell, AnAutoSkinCellReportsItsChoiceAndOtherwiseTheSameResult) {
  const json fixed_params = tiny_cell_params(0.1);
  json auto_params = fixed_params;
  auto_params["dem"]["neighbor_skin_fraction"] = "auto";
  const millflow::testing::ScratchDir fixed_dir, auto_dir;
  json fixed = attempt(fixed_params, fixed_dir.path() / "work", 0).outcome.result;
  json chosen = attempt(auto_params, auto_dir.path() / "work", 0).outcome.result;
  EXPECT_DOUBLE_EQ(fixed.at("neighbor_skin_fraction").get<double>(), 0.3);
  const double skin = chosen.at("neighbor_skin_fraction").get<double>();
  EXPECT_TRUE(std::any_of(std::begin(dem::kSkinFractionCandidates),
                          std::end(dem::kSkinFractionCandidates),
                          [&](double f) { return std::abs(f - skin) < 1e-12; }))
      << skin;
  // Stopped in the first warm-up window (before the choice, at its end) and in the second (after
  // it) and continued from its checkpoint, it reports the same skin: chosen by the continued run,
  // or the one the checkpoint saved. The log names the window it continues in.
  for (const char* window : {"warm-up window 1 ", "warm-up window 2 "}) {
    const millflow::testing::ScratchDir stopped_dir;
    ASSERT_TRUE(attempt(auto_params, stopped_dir.path() / "work", 1, window).outcome.interrupted);
    const Attempt resumed = attempt(auto_params, stopped_dir.path() / "work", 0);
    ASSERT_FALSE(resumed.log.empty());
    EXPECT_NE(resumed.log.front().find(window), std::string::npos) << resumed.log.front();
    EXPECT_EQ(resumed.outcome.result.at("neighbor_skin_fraction"), skin) << window;
  }
  fixed.erase("neighbor_skin_fraction");
  chosen.erase("neighbor_skin_fraction");
  EXPECT_EQ(chosen.dump(), fixed.dump());
}

TEST(ShearCell, AnUnusableCheckpointIsLoggedAndTheCellStartsAgainFromScratch) {
  const json params = tiny_cell_params(0.0);
  const millflow::testing::ScratchDir once, broken;
  const Attempt reference = attempt(params, once.path() / "work", 0);
  const std::filesystem::path work = broken.path() / "work";
  ASSERT_TRUE(attempt(params, work, 4).outcome.interrupted);
  const std::string saved = file_bytes(work / "cell.ckpt");
  for (const std::string& damage : {std::string("truncated"), std::string("checksum mismatch")}) {
    std::string bytes = saved;
    if (damage == "truncated") bytes.resize(bytes.size() - 100);
    if (damage == "checksum mismatch") bytes[bytes.size() / 3] ^= 0x01;
    std::ofstream(work / "cell.ckpt", std::ios::binary | std::ios::trunc) << bytes;
    const Attempt again = attempt(params, work, 0);
    ASSERT_FALSE(again.log.empty());
    EXPECT_NE(again.log.front().find("shear cell: the checkpoint " + (work / "cell.ckpt").string() +
                                     " cannot be used ("),
              std::string::npos)
        << again.log.front();
    EXPECT_NE(again.log.front().find(damage), std::string::npos) << again.log.front();
    EXPECT_NE(again.log.front().find("); starting again from scratch"), std::string::npos)
        << again.log.front();
    EXPECT_EQ(again.outcome.result.dump(), reference.outcome.result.dump()) << damage;
  }
}

}  // namespace
}  // namespace millflow::tasks
