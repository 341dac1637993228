// The average and sites kinds through their run functions: a real small mill (mass conservation,
// artifacts, the flow physics of a slowly turning mill), golden regressions on fixed synthetic
// input, and the `sites` SQL view.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>

#include "dem/rng.hpp"
#include "engine/store.hpp"
#include "method/fields_file.hpp"
#include "method/macro_measure.hpp"
#include "tasks/average.hpp"
#include "tasks/macro.hpp"
#include "tasks/sites.hpp"
#include "tests/tasks/golden.hpp"
#include "tests/tasks/mill_frames.hpp"

namespace millflow::tasks {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Scratch {
  Scratch()
      : path(fs::temp_directory_path() / ("millflow_analysis_" + std::to_string(::getpid()))) {
    fs::create_directories(path);
  }
  ~Scratch() { fs::remove_all(path); }
  fs::path path;
};

engine::TaskOutcome run(engine::RunFunction function, const json& params,
                        const std::vector<engine::TaskInput>& inputs, const fs::path& work_dir) {
  fs::create_directories(work_dir);
  engine::TaskContext context{.key = "test",
                              .params = params,
                              .inputs = inputs,
                              .work_dir = work_dir,
                              .threads = 1,
                              .attempt = 1,
                              .stop = {},
                              .progress = [](double, std::string_view) {},
                              .log = [](std::string_view) {}};
  return function(context);
}

engine::TaskInput as_input(const std::string& kind, const engine::TaskOutcome& outcome) {
  engine::TaskInput input{.key = kind, .kind = kind, .result = outcome.result, .artifacts = {}};
  for (const auto& artifact : outcome.artifacts) input.artifacts[artifact.name] = artifact.file;
  return input;
}

engine::TaskInput macro_input(const std::vector<fs::path>& segments, const json& result) {
  engine::TaskInput input{.key = "macro", .kind = "macro", .result = result, .artifacts = {}};
  for (std::size_t s = 0; s < segments.size(); ++s)
    input.artifacts[fmt::format("flow/segment_{:04d}.mfs", s)] = segments[s];
  return input;
}

const json kAverageParams = {
    {"average", {{"grid_cells", {20, 20}}, {"kernel_width_diameters", 1.5}}}};
const json kSitesParams = {
    {"sites",
     {{"per_region", 2},
      {"regions", method::region_names()},
      {"weight_by", "solid_volume"},
      {"rules", json(method::RegionRules{})},
      {"alternatives", {{{"name", "strict"}, {"rules", {{"en_masse_max_slip", 0.3}}}}}}}}};

// The macro run's result with the toe and shoulder its liner contacts show in `segments`.
engine::TaskInput macro_with_charge(const std::vector<fs::path>& segments, const json& sample) {
  method::ChargeShape shape;
  for (const auto& segment : segments) {
    for (const auto& frame : dem::read_flow_segment(segment)) shape.add_frame(frame, 0);
  }
  const auto angles = shape.angles();
  auto result = sample.get<method::MacroResult>();
  result.charge.toe_angle_deg = angles ? std::optional(angles->toe_deg) : std::nullopt;
  result.charge.shoulder_angle_deg = angles ? std::optional(angles->shoulder_deg) : std::nullopt;
  return {.key = "macro", .kind = "macro", .result = result, .artifacts = {}};
}

json read_json(const fs::path& file) {
  std::ifstream in(file);
  return json::parse(in);
}

TEST(AnalysisTasks, SlowMillBulkTurnsWithTheShellAndTheSurfaceShears) {
  const auto& sample = testing::small_mill_sample();
  Scratch scratch;
  const auto average =
      run(run_average, kAverageParams, {macro_input(sample.segments, sample.macro_result)},
          scratch.path / "average");
  EXPECT_LT(std::abs(average.result.at("mass_conservation").at("relative_error").get<double>()),
            0.01);
  ASSERT_EQ(average.artifacts.size(), 2u);
  for (const auto& artifact : average.artifacts)
    EXPECT_GT(fs::file_size(artifact.file), 1000u) << artifact.name;

  const engine::TaskInput macro = macro_with_charge(sample.segments, sample.macro_result);
  const auto sites =
      run(run_sites, kSitesParams, {as_input("average", average), macro}, scratch.path / "sites");
  double weights = 0.0, solid = 0.0;
  for (const auto& site : sites.result.at("sites")) {
    weights += site.at("weight_m3").get<double>();
    solid += site.at("solid_volume_m3").get<double>();
  }
  EXPECT_NEAR(weights, sites.result.at("charge_volume_m3").get<double>(), 1e-12);
  EXPECT_NEAR(solid, sites.result.at("charge_solid_volume_m3").get<double>(), 1e-12);
  // The charge's solid volume is the balls' volume the average conserves, less what the kernel
  // spreads into cells below the charge threshold (0.3% here).
  EXPECT_NEAR(solid,
              average.result.at("mass_conservation").at("integrated_volume_m3").get<double>(),
              1e-2 * solid);
  ASSERT_EQ(sites.result.at("rule_sets").size(), 2u);

  // The toe holds the impact zone, which lies where the macro run's liner contacts end: within
  // 30 degrees of its toe on this mill.
  const json& toe = sites.result.at("toe");
  ASSERT_TRUE(toe.is_object());
  const double macro_toe = macro.result.at("charge").at("toe_angle_deg").get<double>();
  const double impact = toe.at("impact_angle_deg").get<double>();
  std::cout << "macro toe " << macro_toe << " deg, impact zone " << impact << " deg, toe radius "
            << toe.at("radius_m") << " m over " << toe.at("impact_cells") << " impact cells\n";
  EXPECT_LT(std::abs(std::remainder(impact - macro_toe, 360.0)), 30.0);

  // The physics, from the fields: bulk cells move with the shell, the sheared surface layer and
  // the toe shear faster and dissipate more than the bulk.
  const json fields = read_json(average.artifacts[1].file);
  const method::FlowMap map = method::flow_map_from_document(fields);
  const method::SiteSelection selection = method::select_sites(
      map, method::RegionRules{},
      {.toe_deg = macro_toe,
       .shoulder_deg = macro.result.at("charge").at("shoulder_angle_deg").get<double>()},
      method::region_names(), 2);
  const auto& velocity = fields.at("arrays").at("velocity_m_s").at("values");
  const double omega = map.angular_velocity;
  double slip = 0.0, speed = 0.0, spin = 0.0, solid_bulk = 0.0;
  for (std::size_t c = 0; c < map.grid.size(); ++c) {
    if (selection.region_of_cell[c] != 5) continue;  // bulk
    const double x = map.grid.x_of(c), y = map.grid.y_of(c), nu = map.solid_fraction[c];
    slip += nu * std::hypot(velocity[3 * c].get<double>() + omega * y,
                            velocity[3 * c + 1].get<double>() - omega * x);
    speed += nu * omega * std::hypot(x, y);
    spin += nu * (x * velocity[3 * c + 1].get<double>() - y * velocity[3 * c].get<double>()) /
            (x * x + y * y);
    solid_bulk += nu;
  }
  auto region = [&](int r) { return selection.regions[static_cast<std::size_t>(r)]; };
  const auto bulk = region(5), cascading = region(4), toe_region = region(2);
  std::cout << "bulk: angular velocity about the axis " << spin / solid_bulk << " rad/s (shell "
            << omega << "), slip / shell-rotation speed " << slip / speed << "\n";
  for (const auto& r : selection.regions) {
    std::cout << r.name << ": " << r.cells << " cells, shear " << r.mean_shear_rate
              << " 1/s, dissipation " << (r.volume_m3 > 0 ? r.dissipation_w / r.volume_m3 : 0.0)
              << " W/m^3, share " << r.dissipation_share << "\n";
  }
  ASSERT_GT(bulk.cells, 5u);
  ASSERT_GT(cascading.cells, 0u);
  // A weak bound: this bed is only ~8 balls deep, so the cells the region rules leave as bulk lie
  // within a few balls of the cascading layer (the balls in them turn at 0.8 omega) and the
  // 1.5-diameter kernel smears the cascade in further: measured here 0.72 omega (slip 0.28).
  // bench/bench_slow_mill_flow.cpp shows the claim on a 0.5 m mill, a bed 20 balls deep.
  EXPECT_GT(spin / solid_bulk, 0.5 * omega);
  EXPECT_LT(spin / solid_bulk, 1.1 * omega);
  EXPECT_GT(cascading.mean_shear_rate, 2.0 * bulk.mean_shear_rate);
  const double surface_power = (cascading.dissipation_w + toe_region.dissipation_w) /
                               (cascading.volume_m3 + toe_region.volume_m3);
  EXPECT_GT(surface_power, bulk.dissipation_w / bulk.volume_m3);
}

// Two segments of two frames: 150 balls in the lower half of a 0.1 m mill, random velocities,
// chains of contacts and collisions (seed 11).
std::vector<fs::path> synthetic_segments(const fs::path& dir) {
  dem::Rng rng(11);
  std::vector<fs::path> files;
  for (int s = 0; s < 2; ++s) {
    std::vector<dem::FlowFrame> frames(2);
    for (auto& f : frames) {
      for (int p = 0; p < 150; ++p) {
        const double r = 0.09 * std::sqrt(rng.uniform()), a = -std::numbers::pi * rng.uniform();
        f.position.push_back(
            {static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a)), 0.0f});
        f.velocity.push_back(
            {static_cast<float>(rng.uniform(-1, 1)), static_cast<float>(rng.uniform(-1, 1)), 0.0f});
        f.angular_velocity.push_back({0.0f, 0.0f, 0.0f});
        f.radius.push_back(0.005f);
        f.material.push_back(0);
        if (p == 0) continue;
        const auto& x0 = f.position[static_cast<std::size_t>(p - 1)];
        const auto& x1 = f.position[static_cast<std::size_t>(p)];
        const dem::Float3 branch{x1[0] - x0[0], x1[1] - x0[1], 0.0f};
        const auto push = static_cast<float>(-10.0 * rng.uniform());
        f.contact_a.push_back(static_cast<std::uint32_t>(p - 1));
        f.contact_b.push_back(static_cast<std::uint32_t>(p));
        f.contact_with_wall.push_back(0);
        f.contact_point.push_back(x0);
        f.contact_force.push_back({push * branch[0], push * branch[1], 0.0f});
        f.contact_branch.push_back(branch);
        f.event_time.push_back(0.0);
        f.event_point.push_back(x1);
        f.event_impact_energy.push_back(0.01f);
        f.event_dissipated.push_back(static_cast<float>(0.01 * rng.uniform()));
        f.event_category.push_back(static_cast<std::uint32_t>(p % 2));
        f.event_with_wall.push_back(static_cast<std::uint8_t>(p % 2));
      }
    }
    files.push_back(dir / fmt::format("segment_{:04d}.mfs", s));
    dem::write_flow_segment(files.back(), frames);
  }
  return files;
}

const method::MacroResult kSyntheticMacro = [] {
  method::MacroResult r;
  r.ball_mass_kg = 150 * 7800.0 * 4.0 / 3.0 * std::numbers::pi * 1.25e-7;
  r.media_diameter_m = 0.01;
  r.angular_velocity_rad_s = 4.0;
  r.mill.radius_m = 0.1;
  r.mill.length_m = 0.04;
  r.sample_interval_s = 0.01;
  r.frame_count = 4;
  r.categories = {"steel-steel", "steel-wall:shell"};
  return r;
}();

TEST(AnalysisTasks, AverageGolden) {
  Scratch scratch;
  const auto average = run(run_average, kAverageParams,
                           {macro_input(synthetic_segments(scratch.path), kSyntheticMacro)},
                           scratch.path / "average");
  const json& r = average.result;
  EXPECT_NEAR(r.at("media_density_kg_m3").get<double>(), 7800.0, 1e-3);
  millflow::testing::check_golden(
      "average", kAverageVersion,
      {{"integrated_volume_m3", r["mass_conservation"]["integrated_volume_m3"]},
       {"max_pressure_pa", r["fields"]["pressure_pa"]["max"]},
       {"max_shear_rate_per_s", r["fields"]["shear_rate_per_s"]["max"]},
       {"mean_granular_temperature_m2_s2",
        r["fields"]["granular_temperature_m2_s2"]["mean_over_charge"]},
       {"max_normal_stress_pa", r["fields"]["normal_stress_pa"]["max"]},
       {"max_dissipation_w_m3", r["fields"]["dissipation_w_m3"]["max"]},
       {"collisions_per_s", r["mill_wide"]["total"]["collisions_per_s"]},
       {"dissipation_w", r["mill_wide"]["total"]["dissipation_w"]}});
}

TEST(AnalysisTasks, SitesGolden) {
  Scratch scratch;
  const auto average = run(run_average, kAverageParams,
                           {macro_input(synthetic_segments(scratch.path), kSyntheticMacro)},
                           scratch.path / "average");
  method::MacroResult macro = kSyntheticMacro;
  macro.charge.toe_angle_deg = 200.0;
  macro.charge.shoulder_angle_deg = -20.0;
  macro.fill = 0.3;
  macro.speed_fraction = 0.7;
  const auto sites = run(run_sites, kSitesParams,
                         {as_input("average", average),
                          {.key = "macro", .kind = "macro", .result = macro, .artifacts = {}}},
                         scratch.path / "sites");
  json values = {{"charge_volume_m3", sites.result["charge_volume_m3"]},
                 {"charge_solid_volume_m3", sites.result["charge_solid_volume_m3"]},
                 {"toe_radius_m", sites.result["toe"]["radius_m"]},
                 {"site_count", sites.result["sites"].size()},
                 {"toe_angle_deg", sites.result["toe_angle_deg"]},
                 {"shoulder_angle_deg", sites.result["shoulder_angle_deg"]}};
  for (const auto& region : sites.result["regions"]) {
    values[region["name"].get<std::string>() + "_volume_m3"] = region["volume_m3"];
  }
  for (const auto& site : sites.result["sites"]) {
    values[site["site_id"].get<std::string>() + "_shear_rate_per_s"] = site["shear_rate_per_s"];
    values[site["site_id"].get<std::string>() + "_pressure_pa"] = site["pressure_pa"];
  }
  millflow::testing::check_golden("sites", kSitesVersion, values);
}

TEST(AnalysisTasks, SitesViewJoinsTheMacroRunsFillAndSpeed) {
  Scratch scratch;
  engine::SystemClock clock;
  engine::Store store(scratch.path / "view.db", {macro_lineage_view(), sites_view()}, clock);
  const json macro_params = {{"macro", {{"fill", 0.35}, {"speed_fraction", 0.7}}}};
  const json result = {{"sites",
                        {{{"site_id", "toe-0"},
                          {"region", "toe"},
                          {"position_m", {0.1, -0.2}},
                          {"weight_m3", 0.5},
                          {"shear_rate_per_s", 30.0}}}}};
  store.connection().exec(fmt::format(R"sql(
INSERT INTO campaigns (id, name, format, document, submitted_at) VALUES (1, 'c', 'millflow_campaign', '{{}}', 0);
INSERT INTO tasks (key, kind, kind_version, params, key_text, status, created_at) VALUES
  ('m', 'macro', '1', '{}', '', 'done', 0), ('a', 'average', '1', '{{}}', '', 'done', 0),
  ('s', 'sites', '1', '{{}}', '', 'done', 0);
INSERT INTO campaign_tasks VALUES (1, 'm'), (1, 'a'), (1, 's');
INSERT INTO edges VALUES ('a', 0, 'm'), ('s', 0, 'a');
INSERT INTO results (task_key, result, committed_at) VALUES ('s', '{}', 0);
)sql",
                                      macro_params.dump(), result.dump()));
  auto rows = store.connection().prepare(
      "SELECT campaign, fill, speed_fraction, site_id, region, weight_m3, "
      "shear_rate_per_s, x_m, y_m FROM sites");
  ASSERT_TRUE(rows.step());
  EXPECT_EQ(rows.text(0), "c");
  EXPECT_EQ(rows.real(1), 0.35);
  EXPECT_EQ(rows.real(2), 0.7);
  EXPECT_EQ(rows.text(3), "toe-0");
  EXPECT_EQ(rows.text(4), "toe");
  EXPECT_EQ(rows.real(5), 0.5);
  EXPECT_EQ(rows.real(6), 30.0);
  EXPECT_EQ(rows.real(7), 0.1);
  EXPECT_EQ(rows.real(8), -0.2);
  EXPECT_FALSE(rows.step());
}

}  // namespace
}  // namespace millflow::tasks
