// The macro task: parameter translation, a tiny run through the task function with all its
// artifacts, interruption and resumption with the same result, and the macro_results view.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <sstream>

#include <fmt/format.h>

#include "dem/flow_sample.hpp"
#include "engine/sqlite.hpp"
#include "engine/store.hpp"
#include "engine/validation.hpp"
#include "report/report_inputs.hpp"
#include "tasks/macro_setup.hpp"
#include "tests/tasks/macro_fixtures.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;
using testing::DirectRun;
using testing::ScratchDir;
using testing::tiny_macro_params;

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

double ball_mass(double diameter) {
  return 7800.0 * std::numbers::pi * std::pow(diameter, 3) / 6.0;
}

TEST(MacroParams, CollisionTimeGivesThatContactDurationForTheReferencePairs) {
  const method::MacroSettings settings = macro_settings(tiny_macro_params(), "key");
  const double m = ball_mass(0.012);
  const double zeta = dem::damping_ratio_for_restitution(0.5);
  // Two balls: m_eff = m / 2; a ball on the liner (a wall): m_eff = m.
  EXPECT_NEAR(dem::collision_duration(settings.mill.ball_ball.normal_stiffness, m / 2, zeta), 1e-3,
              1e-12);
  EXPECT_NEAR(dem::collision_duration(settings.mill.ball_liner.normal_stiffness, m, zeta), 1e-3,
              1e-12);
  // Independently: t_c = pi / (omega_0 sqrt(1 - zeta^2)) => k = m_eff (pi / (t_c sqrt(1 -
  // zeta^2)))^2.
  const double expected =
      (m / 2) * std::pow(std::numbers::pi / (1e-3 * std::sqrt(1 - zeta * zeta)), 2);
  EXPECT_NEAR(settings.mill.ball_ball.normal_stiffness, expected, 1e-9 * expected);
  EXPECT_DOUBLE_EQ(settings.mill.ball_ball.tangential_stiffness_ratio, 0.2857142857);
  EXPECT_EQ(settings.mill.shell.lifter_count, 4);
  EXPECT_FALSE(settings.mill.shell.end_walls);
}

TEST(MacroParams, NormalStiffnessAndSizeDistributionAndEndWalls) {
  json params = tiny_macro_params();
  params["interactions"][0]["stiffness"] = {{"normal", 2.5e5}};
  params["media"] = {
      {"material", "steel"},
      {"size_distribution",
       {{{"diameter", 0.016}, {"mass_fraction", 3}}, {{"diameter", 0.008}, {"mass_fraction", 1}}}}};
  params["mill"]["axial_ends"] = "walls";
  const method::MacroSettings settings = macro_settings(params, "key");
  EXPECT_EQ(settings.mill.ball_ball.normal_stiffness, 2.5e5);
  EXPECT_EQ(settings.mill.ball_liner.normal_stiffness, 2.5e5);
  EXPECT_NEAR(dem::mean_ball_diameter(settings.mill), 0.75 * 0.016 + 0.25 * 0.008, 1e-15);
  EXPECT_TRUE(settings.mill.shell.end_walls);
}

TEST(MacroParams, SeedDependsOnTheKeyAndTheDemSeed) {
  EXPECT_EQ(macro_seed(1, "abc"), macro_seed(1, "abc"));
  EXPECT_NE(macro_seed(1, "abc"), macro_seed(1, "abd"));
  EXPECT_NE(macro_seed(1, "abc"), macro_seed(2, "abc"));
}

TEST(MacroParams, MissingValuesAndPairsAreNamed) {
  json params = tiny_macro_params();
  params["macro"].erase("fill");
  try {
    macro_settings(params, "key");
    FAIL() << "no error";
  } catch (const engine::InvalidInput& e) {
    EXPECT_EQ(e.errors().at(0).path, "/macro/fill");
  }
  params = tiny_macro_params();
  params["mill"]["liner_material"] = "rubber";
  params["materials"]["rubber"] = {{"density", 1200}};
  try {
    macro_settings(params, "key");
    FAIL() << "no error";
  } catch (const engine::InvalidInput& e) {
    EXPECT_NE(e.errors().at(0).problem.find("\"steel\" and \"rubber\""), std::string::npos)
        << e.what();
  }
}

// The shear_cell kind reads its media through the same functions: a value missing there is
// missing from the shear cell's parameters, not from a macro task's.
TEST(MacroParams, AMissingValueIsNamedAsMissingFromTheKindThatReadsIt) {
  json params = tiny_macro_params();
  params.erase("media");
  try {
    media_diameter(params);
    FAIL() << "no error";
  } catch (const engine::InvalidInput& e) {
    EXPECT_EQ(e.errors().at(0).problem, "is missing from the macro task's parameters");
  }
  params["shear_cell"] = json::object();
  try {
    media_diameter(params);
    FAIL() << "no error";
  } catch (const engine::InvalidInput& e) {
    EXPECT_EQ(e.errors().at(0).path, "/media");
    EXPECT_EQ(e.errors().at(0).problem, "is missing from the shear_cell task's parameters");
    EXPECT_EQ(e.errors().at(0).fix,
              "plan shear_cell tasks from a validated campaign (tasks::shear_cells_params)");
  }
}

TEST(MacroParams, CorrelationsMatchTheFactsSheet) {
  // docs/method.md, reference points: Bond ~8 kW/t at D = 1 m, ~13 kW/t at D = 5 m; Hogg-Fuerstenau
  // ~6.4 kW/t at D = 1 m (J = 0.3, phi_c = 0.75).
  EXPECT_NEAR(method::bond_kw_per_tonne(1.0, 0.3, 0.75), 8.0, 0.3);
  EXPECT_NEAR(method::bond_kw_per_tonne(5.0, 0.3, 0.75), 13.0, 0.5);
  EXPECT_NEAR(method::hogg_fuerstenau_kw_per_tonne(1.0, 0.3, 0.75), 6.4, 0.1);
}

class MacroRunTest : public ::testing::Test {
 protected:
  // The tiny run with 1.5 revolutions of warm-up: after the fixture's default 0.5 the charge is
  // still gaining energy, and the torque arm falls 6-12% short of the shell's power (over 4 seeds,
  // with the cubic and the close-packed start alike); after 1.5 it agrees within 2.6%. Frames
  // every 5 ms (about 160 in the measured revolution): the frame means sample an instantaneous
  // torque, and the 41 frames of the default 20 ms gave 0.71-1.18 of the every-step power over
  // seeds 1-8 (0.94-1.04 with 164; 0.87-1.11 with 41 before the sliding spring was reset with its
  // dashpot, whose abrupt tangential forces at the shell make the instantaneous torque noisier).
  static json params() {
    json params = tiny_macro_params();
    params["macro"]["warmup_revolutions"] = 1.5;
    params["macro"]["sample_interval"] = 0.005;
    return params;
  }
  static void SetUpTestSuite() {
    scratch_ = new ScratchDir("macro_run");
    outcome_ = new engine::TaskOutcome(DirectRun{params(), scratch_->path() / "whole"}.run());
  }
  static void TearDownTestSuite() {
    delete outcome_;
    delete scratch_;
  }
  static const json& result() { return outcome_->result; }

  static ScratchDir* scratch_;
  static engine::TaskOutcome* outcome_;
};
ScratchDir* MacroRunTest::scratch_ = nullptr;
engine::TaskOutcome* MacroRunTest::outcome_ = nullptr;

TEST_F(MacroRunTest, ReportsTheChargeAndTheDerivedValues) {
  ASSERT_FALSE(outcome_->interrupted);
  const json& r = result();
  const double area = std::numbers::pi * 0.01;  // lifters take ~1.5% of it
  const double expected_balls =
      0.3 * area * 0.036 * 0.6 / (std::numbers::pi * std::pow(0.012, 3) / 6);
  EXPECT_NEAR(r["n_balls"].get<double>(), expected_balls, 0.03 * expected_balls);
  EXPECT_NEAR(r["ball_mass_kg"].get<double>(), r["n_balls"].get<double>() * ball_mass(0.012), 1e-9);
  EXPECT_NEAR(r["dt_s"].get<double>(), 1e-3 / 20,
              1e-9);  // the ball-ball pair is the shortest: t_c = 1 ms
  const double omega_c = std::sqrt(9.81 / (0.1 - 0.006));
  EXPECT_NEAR(r["critical_speed_rad_s"].get<double>(), omega_c, 1e-9);
  EXPECT_NEAR(r["angular_velocity_rad_s"].get<double>(), 0.75 * omega_c, 1e-9);
  EXPECT_EQ(r["mill"]["lifter_count"], 4);
  EXPECT_EQ(r["mill"]["axial_ends"], "periodic");
  EXPECT_NEAR(r["measure_revolutions"].get<double>(), 1.0, 0.02);
  EXPECT_NEAR(r["contacts"]["ball_liner"]["collision_time_s"].get<double>(), 1e-3, 1e-12);
}

TEST_F(MacroRunTest, PowerIsPositiveAndAgreesWithTheTorqueArmAndTheDissipation) {
  const json& power = result()["power"];
  const double p = power["mean_kw"].get<double>();
  EXPECT_GT(p, 0.0);
  // Over one revolution the charge's kinetic and potential energy barely change: the shell's work
  // goes into dissipation, and the torque that holds the centre of mass off-centre is the torque
  // the shell supplies. Tolerances: 10% (a single, short revolution of ~220 balls).
  EXPECT_NEAR(power["torque_arm_kw"].get<double>(), p, 0.10 * p);
  EXPECT_NEAR(power["dissipation_kw"].get<double>(), p, 0.10 * p);
  EXPECT_NEAR(power["kw_per_m"].get<double>(), p / 0.036, 1e-9 * p / 0.036);
  EXPECT_NEAR(power["kw_per_t_balls"].get<double>(),
              p / (result()["ball_mass_kg"].get<double>() / 1000), 1e-9);
  EXPECT_GT(power["std_kw"].get<double>(), 0.0);
}

TEST_F(MacroRunTest, FrameMeansAgreeWithTheEveryStepPowerAndTheTorqueArm) {
  const json& r = result();
  const json& means = r["frame_means"];
  EXPECT_EQ(means["frames"], r["frame_count"]);
  const double omega = r["angular_velocity_rad_s"].get<double>();
  const double power_w = r["power"]["mean_w"].get<double>();
  const json& torque = means["drive_torque_n_m"];
  // Both the liner and the lifters carry the charge; without end walls they take no torque.
  EXPECT_GT(torque["liner"].get<double>(), 0.0);
  EXPECT_GT(torque["lifters"].get<double>(), 0.0);
  EXPECT_EQ(torque["end_walls"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(torque["total"].get<double>(),
                   torque["liner"].get<double>() + torque["lifters"].get<double>());
  EXPECT_DOUBLE_EQ(means["drive_power_w"].get<double>(), torque["total"].get<double>() * omega);
  // Sampled at the ~160 flow frames of one revolution, not every step: within 15% of the power.
  EXPECT_NEAR(means["drive_power_w"].get<double>(), power_w, 0.15 * power_w);
  // The centre of mass held right of the axis (mill turning counter-clockwise) is the torque
  // arm: M g x_com omega within 10% of the torque-arm power of the blocks.
  const double x_com = means["centre_of_mass_m"]["x"].get<double>();
  EXPECT_GT(x_com, 0.0);
  EXPECT_LT(means["centre_of_mass_m"]["y"].get<double>(), 0.0);  // below the axis
  EXPECT_NEAR(r["ball_mass_kg"].get<double>() * 9.81 * x_com * omega,
              1000 * r["power"]["torque_arm_kw"].get<double>(),
              0.10 * 1000 * r["power"]["torque_arm_kw"].get<double>());
  // A tumbling charge: the balls' spin energy is a fraction of their translational energy
  // (a ball rolling without slip holds 2/7 of its energy in spin, 2/5 of the translational).
  const double translational = means["kinetic_energy_j"]["translational"].get<double>();
  const double rotational = means["kinetic_energy_j"]["rotational"].get<double>();
  EXPECT_GT(rotational, 0.0);
  EXPECT_LT(rotational, 0.4 * translational * 1.05);
  // The charge moves at most as fast as the shell: sum m v^2 / 2 < M (omega R)^2 / 2.
  EXPECT_LT(translational, 0.5 * r["ball_mass_kg"].get<double>() * std::pow(omega * 0.1, 2));
}

TEST_F(MacroRunTest, ChargeIsLiftedOnTheRisingSide) {
  const json& charge = result()["charge"];
  ASSERT_TRUE(charge["toe_angle_deg"].is_number());
  const double toe = charge["toe_angle_deg"], shoulder = charge["shoulder_angle_deg"];
  EXPECT_GT(toe, 180.0);  // lower left
  EXPECT_LT(toe, 270.0);
  EXPECT_GT(shoulder, -30.0);  // right, above the bed's static surface
  EXPECT_LT(shoulder, 90.0);
}

TEST_F(MacroRunTest, CountsCollisionsOfBothKinds) {
  const json& r = result();
  for (const char* kind : {"ball_ball", "ball_liner"}) {
    const json& c = r["collisions"][kind];
    EXPECT_GT(c["count"].get<double>(), 100) << kind;
    double counted = 0;
    for (const json& n : r["spectra"][kind]["impact_energy"]["counts"]) counted += n.get<double>();
    counted += r["spectra"][kind]["impact_energy"]["underflow"].get<double>();
    counted += r["spectra"][kind]["impact_energy"]["overflow"].get<double>();
    EXPECT_EQ(counted, c["count"].get<double>()) << kind;
  }
  EXPECT_EQ(r["spectra"]["bin_edges_j"].size(),
            r["spectra"]["ball_ball"]["impact_energy"]["counts"].size() + 1);
  EXPECT_EQ(r["collisions"]["ball_ball"]["category"], "steel-steel");
  EXPECT_EQ(r["collisions"]["ball_liner"]["category"], "steel-wall:shell");
}

// The report reads the macro kind's own result (its charge shape and spectra figures): the
// contract between the two kinds.
TEST_F(MacroRunTest, TheReportReadsTheChargeAndTheSpectra) {
  const json& r = result();
  const report::MacroRun run = report::read_macro("tiny-macro", r);
  EXPECT_EQ(run.toe_angle_deg, r["charge"]["toe_angle_deg"].get<double>());
  ASSERT_EQ(run.spectra.size(), 4u);  // ball_ball, ball_liner x impact, dissipated
  EXPECT_EQ(run.spectra[0].label, "ball_ball impact");
  const double duration = r["measure_end_s"].get<double>() - r["measure_start_s"].get<double>();
  const json& counts = r["spectra"]["ball_liner"]["dissipated_energy"]["counts"];
  ASSERT_EQ(run.spectra[3].rate_per_s.size(), counts.size());
  for (std::size_t k = 0; k < counts.size(); ++k)
    EXPECT_DOUBLE_EQ(run.spectra[3].rate_per_s[k] * duration, counts[k].get<double>()) << k;
}

TEST_F(MacroRunTest, FlowSegmentsHoldEveryFrameInOrder) {
  const json& r = result();
  std::map<std::string, std::filesystem::path> files;
  for (const auto& a : outcome_->artifacts) files[a.name] = a.file;
  const std::uint64_t segments = r["segment_count"];
  ASSERT_GT(segments, 1u);
  std::size_t frames = 0, events = 0, contacts = 0;
  double last_time = r["measure_start_s"];
  const double interval = r["sample_interval_s"];
  for (std::uint64_t k = 0; k < segments; ++k) {
    const auto name = fmt::format("flow/segment_{:04d}.mfs", k);
    ASSERT_TRUE(files.count(name)) << name;
    for (const dem::FlowFrame& frame : dem::read_flow_segment(files[name])) {
      EXPECT_NEAR(frame.time - last_time, interval, 1e-9);
      last_time = frame.time;
      EXPECT_EQ(frame.position.size(), r["n_balls"].get<std::size_t>());
      // Contacts in force: at least a quarter of the balls' count in every frame and half of it
      // on average (measured in this mill over 4 seeds: 0.38-0.59 per ball in the sparsest frame,
      // 0.67-0.79 on average, with either initial placement).
      EXPECT_GT(frame.contact_a.size(), frame.position.size() / 4);
      contacts += frame.contact_a.size();
      events += frame.event_time.size();
      ++frames;
    }
  }
  EXPECT_EQ(frames, r["frame_count"].get<std::size_t>());
  EXPECT_GT(contacts, frames * r["n_balls"].get<std::size_t>() / 2);
  EXPECT_NEAR(last_time, r["measure_end_s"].get<double>(), 1e-12);
  EXPECT_EQ(events, r["collisions"]["ball_ball"]["count"].get<std::size_t>() +
                        r["collisions"]["ball_liner"]["count"].get<std::size_t>());
  EXPECT_EQ(r["categories"].size(), 6u);  // 2 materials: 4 pair categories + 2 wall categories
}

TEST_F(MacroRunTest, WritesPowerCsvAndVtkFiles) {
  std::map<std::string, std::filesystem::path> files;
  for (const auto& a : outcome_->artifacts) files[a.name] = a.file;
  for (const char* name : {"power.csv", "vtk/particles.pvd", "vtk/particles_0000.vtp",
                           "vtk/mill.pvd", "vtk/mill_0000.vtp"}) {
    ASSERT_TRUE(files.count(name)) << name;
    ASSERT_TRUE(std::filesystem::exists(files[name])) << name;
  }
  const std::string csv = read_file(files["power.csv"]);
  const auto lines = std::count(csv.begin(), csv.end(), '\n');
  EXPECT_NEAR(static_cast<double>(lines - 1), 200.0, 2.0);  // ~200 points per revolution
  const std::string pvd = read_file(files["vtk/particles.pvd"]);
  std::size_t vtp = 0;
  std::size_t outlines = 0;
  for (const auto& [name, path] : files) {
    vtp += name.starts_with("vtk/particles_") ? 1 : 0;
    outlines += name.starts_with("vtk/mill_") ? 1 : 0;
  }
  EXPECT_EQ(static_cast<std::size_t>(std::count(pvd.begin(), pvd.end(), '\n')),
            vtp + 5);        // 5 lines of header and footer
  EXPECT_EQ(outlines, vtp);  // the shell and lifters beside every particle frame
  ASSERT_TRUE(files.count("collision_spectra.csv"));
  const std::string spectra = read_file(files["collision_spectra.csv"]);
  EXPECT_EQ(spectra.substr(0, spectra.find('\n')),
            "energy_low_j,energy_high_j,ball_ball_impact_energy_count,"
            "ball_ball_dissipated_energy_count,ball_liner_impact_energy_count,"
            "ball_liner_dissipated_energy_count");
  EXPECT_EQ(static_cast<std::size_t>(std::count(spectra.begin(), spectra.end(), '\n')),
            result()["spectra"]["bin_edges_j"].size());  // the header and a row per bin
  const std::string particles = read_file(files["vtk/particles_0000.vtp"]);
  EXPECT_NE(particles.find(fmt::format("NumberOfPoints=\"{}\"", result()["n_balls"].get<int>())),
            std::string::npos);
}

// An interval longer than any run writes the first frame only. 1e15 s is past the 2^63 steps an
// integer holds at this dt: the count wrapped, and the run wrote a frame every step.
TEST(MacroRunVtk, AnIntervalLongerThanTheRunWritesTheFirstFrameOnly) {
  ScratchDir scratch("macro_vtk_interval");
  json params = tiny_macro_params();
  params["macro"]["measure_revolutions"] = 0.25;
  for (const double interval : {1e15, 1e308}) {
    params["macro"]["vtk_interval"] = interval;
    const auto outcome = DirectRun{params, scratch.path() / fmt::format("{}", interval)}.run();
    ASSERT_FALSE(outcome.interrupted);
    std::vector<std::string> frames;
    for (const auto& a : outcome.artifacts) {
      if (a.name.ends_with(".vtp")) frames.push_back(a.name);
    }
    EXPECT_EQ(frames, (std::vector<std::string>{"vtk/particles_0000.vtp", "vtk/mill_0000.vtp"}))
        << interval;
  }
}

// Runs until `fraction` of the run is done and asks it to stop there: true when it stopped.
bool stopped_at(const DirectRun& run, double fraction) {
  std::stop_source stop;
  return run
      .run(stop.get_token(),
           [&](double done, std::string_view) {
             if (done >= fraction) stop.request_stop();
           })
      .interrupted;
}

TEST_F(MacroRunTest, InterruptedTwiceAndResumedGivesTheSameResultAndFiles) {
  const auto dir = scratch_->path() / "interrupted";
  const DirectRun run{params(), dir};
  // Stop once in the warm-up and once in the measurement (with frames waiting for a segment).
  for (const double stop_at : {0.25, 0.8}) {
    ASSERT_TRUE(stopped_at(run, stop_at)) << stop_at;
    EXPECT_TRUE(std::filesystem::exists(dir / "state.bin"));
  }
  const auto resumed = run.run();
  ASSERT_FALSE(resumed.interrupted);
  EXPECT_EQ(resumed.result.dump(), result().dump());
  ASSERT_EQ(resumed.artifacts.size(), outcome_->artifacts.size());
  for (std::size_t k = 0; k < resumed.artifacts.size(); ++k) {
    EXPECT_EQ(resumed.artifacts[k].name, outcome_->artifacts[k].name);
    EXPECT_EQ(read_file(resumed.artifacts[k].file), read_file(outcome_->artifacts[k].file))
        << resumed.artifacts[k].name;
  }
  // The last checkpoint stays until the runtime removes the work directory after the commit.
  EXPECT_TRUE(std::filesystem::exists(dir / "state.bin"));
}

// An attempt killed after its run finished, while its artifacts were stored, used to start again
// from scratch (finish() had removed the checkpoint): it continues from the last checkpoint.
TEST_F(MacroRunTest, ARunKilledAfterItFinishedContinuesFromItsLastCheckpoint) {
  const auto dir = scratch_->path() / "finished";
  std::vector<std::string> log;
  const DirectRun run{params(), dir, "tiny-macro", 2, &log};
  ASSERT_TRUE(stopped_at(run, 0.8));
  ASSERT_FALSE(run.run().interrupted);
  const auto again = run.run();  // as the next attempt after a kill before the commit
  ASSERT_FALSE(again.interrupted);
  EXPECT_EQ(again.result.dump(), result().dump());
  EXPECT_EQ(std::count_if(log.begin(), log.end(),
                          [](const std::string& line) {
                            return line.starts_with("macro: continuing from the checkpoint");
                          }),
            2);
}

// "auto" chooses the skin by trial at the end of the warm-up, logs it, and moves no result bit.
TEST_F(MacroRunTest, AnAutoSkinLogsItsChoiceAndGivesTheSameResult) {
  json chosen = params();
  chosen["dem"]["neighbor_skin_fraction"] = "auto";
  std::vector<std::string> log;
  const auto outcome =
      DirectRun{.params = chosen, .work_dir = scratch_->path() / "auto", .log_lines = &log}.run();
  ASSERT_FALSE(outcome.interrupted);
  EXPECT_EQ(outcome.result.dump(), result().dump());
  EXPECT_EQ(std::count_if(log.begin(), log.end(),
                          [](const std::string& line) {
                            return line.find("macro: neighbour skin \"auto\" chose") !=
                                   std::string::npos;
                          }),
            1);
}

void flip_byte(const std::filesystem::path& file, std::streamoff at) {
  std::fstream bytes(file, std::ios::in | std::ios::out | std::ios::binary);
  bytes.seekg(at);
  const char byte = static_cast<char>(bytes.get());
  bytes.seekp(at);
  bytes.put(static_cast<char>(byte ^ 0xff));
}

// A damaged checkpoint used to fail every resume the same way until the work directory was
// deleted by hand. It is logged and the run starts again, to the same result.
TEST_F(MacroRunTest, ADamagedCheckpointIsLoggedAndTheRunStartsAgainToTheSameResult) {
  const std::vector<std::pair<std::string, std::function<void(const std::filesystem::path&)>>>
      damages = {
          {"flipped state",
           [](const std::filesystem::path& dir) { flip_byte(dir / "state.bin", 30); }},
          {"truncated state",
           [](const std::filesystem::path& dir) {
             std::filesystem::resize_file(dir / "state.bin", 40);
           }},
          {"deleted DEM checkpoint",
           [](const std::filesystem::path& dir) {
             for (const auto& entry : std::filesystem::directory_iterator(dir)) {
               if (entry.path().filename().string().starts_with("checkpoint_"))
                 std::filesystem::remove(entry.path());
             }
           }},
          // The measured output before the checkpoint: a resume used to fail at the run's end.
          {"flipped flow segment",
           [](const std::filesystem::path& dir) {
             const auto segment = dir / "flow" / "segment_0000.mfs";
             ASSERT_TRUE(std::filesystem::exists(segment));
             flip_byte(segment, 40);
           }},
          {"deleted VTK file",
           [](const std::filesystem::path& dir) {
             const auto vtk = dir / "vtk" / "particles_0000.vtp";
             ASSERT_TRUE(std::filesystem::exists(vtk));
             std::filesystem::remove(vtk);
           }},
          // Present but not the bytes written: stored as an artifact, it had been "verified"
          // against its own damaged bytes.
          {"truncated VTK file",
           [](const std::filesystem::path& dir) {
             const auto vtk = dir / "vtk" / "particles_0000.vtp";
             ASSERT_TRUE(std::filesystem::exists(vtk));
             std::filesystem::resize_file(vtk, 10);
           }},
          {"flipped VTK outline",
           [](const std::filesystem::path& dir) {
             const auto vtk = dir / "vtk" / "mill_0001.vtp";
             ASSERT_TRUE(std::filesystem::exists(vtk));
             flip_byte(vtk, 200);
           }},
      };
  for (const auto& [name, damage] : damages) {
    const auto dir = scratch_->path() / ("damaged " + name);
    std::vector<std::string> log;
    const DirectRun run{params(), dir, "tiny-macro", 2, &log};
    ASSERT_TRUE(stopped_at(run, 0.8)) << name;
    damage(dir);
    const auto resumed = run.run();
    ASSERT_FALSE(resumed.interrupted) << name;
    EXPECT_EQ(resumed.result.dump(), result().dump()) << name;
    EXPECT_EQ(std::count_if(log.begin(), log.end(),
                            [](const std::string& line) {
                              return line.find("cannot be used") != std::string::npos &&
                                     line.ends_with("starting again from scratch");
                            }),
              1)
        << name;
  }
}

TEST(MacroResultsView, OneRowPerMacroTaskWithItsNumbers) {
  ScratchDir scratch("macro_view");
  const auto db = scratch.path() / "test.db";
  engine::SystemClock clock;
  engine::Store store(db, {macro_results_view()}, clock);
  const json params = tiny_macro_params(0.35, 0.8);
  const auto spec = engine::make_task_spec("macro", kMacroVersion, params, {});
  const auto other = engine::make_task_spec("average", "1", json::object(), {spec.key});
  const auto campaign =
      store.register_campaign("c1", "millflow_campaign", json::object(), {spec, other});
  const json result = {{"power",
                        {{"mean_kw", 1.5},
                         {"kw_per_m", 2.5},
                         {"kw_per_t_balls", 9.0},
                         {"std_kw", 0.1},
                         {"torque_arm_kw", 1.4}}},
                       {"charge", {{"toe_angle_deg", 220.0}, {"shoulder_angle_deg", 40.0}}},
                       {"n_balls", 123},
                       {"ball_mass_kg", 4.5},
                       {"dt_s", 5e-5}};
  store.mark_running(spec.key);
  store.commit_done(campaign, spec.key, result, {}, {}, 1.0);

  auto read = engine::open_read_only(db);
  auto rows = read.prepare(
      "SELECT campaign, task_key, fill, speed_fraction, power_kw, power_kw_per_m, "
      "power_kw_per_t_balls, power_std_kw, "
      "torque_arm_power_kw, toe_angle_deg, shoulder_angle_deg, n_balls, ball_mass_kg, "
      "mill_diameter_m, dt_s, status "
      "FROM macro_results");
  ASSERT_TRUE(rows.step());
  EXPECT_EQ(rows.text(0), "c1");
  EXPECT_EQ(rows.text(1), spec.key);
  EXPECT_EQ(rows.real(2), 0.35);
  EXPECT_EQ(rows.real(3), 0.8);
  EXPECT_EQ(rows.real(4), 1.5);
  EXPECT_EQ(rows.real(5), 2.5);
  EXPECT_EQ(rows.real(6), 9.0);
  EXPECT_EQ(rows.real(7), 0.1);
  EXPECT_EQ(rows.real(8), 1.4);
  EXPECT_EQ(rows.real(9), 220.0);
  EXPECT_EQ(rows.real(10), 40.0);
  EXPECT_EQ(rows.integer(11), 123);
  EXPECT_EQ(rows.real(12), 4.5);
  EXPECT_EQ(rows.real(13), 0.2);
  EXPECT_EQ(rows.real(14), 5e-5);
  EXPECT_EQ(rows.text(15), "done");
  EXPECT_FALSE(rows.step());  // the average task is not a macro row
}

}  // namespace
}  // namespace millflow::tasks
