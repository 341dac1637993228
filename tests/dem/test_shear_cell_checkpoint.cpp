// Shear cell checkpoints: a run stopped at several points of its compaction, warm-up and
// measurement and continued from its checkpoint file gives the same bits as a run that never
// stopped, with both boundaries; truncated, altered and foreign files are refused with a message
// that says so.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "dem/binary_io.hpp"
#include "dem/checkpoint.hpp"
#include "dem/shear_cell.hpp"
#include "tests/common/scratch_dir.hpp"
#include "tests/dem/same_bits.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

using testing::same_bits;

using testing::small_shear_cell;

ShearCellSetup tiny_cell(ShearCellSetup::Boundary boundary) {
  ShearCellSetup setup = small_shear_cell(0.1, 0.2, 0.5);
  setup.boundary = boundary;
  setup.size_diameters = Vec3(4, 5, 4);
  return setup;
}

ShearCellProtocol tiny_protocol() {
  // Measured past 0.3 strain by blocks, up to 0.4, unless converged (it is not, so short).
  return {.warmup_strain = 0.2,
          .warmup_windows = 2,
          .max_warmup_strain = 0.2,
          .measure_strain = 0.3,
          .measure = {.samples = 20, .max_strain = 0.4}};
}

void expect_same_histogram(const LogHistogram& a, const LogHistogram& b, const std::string& what) {
  ASSERT_EQ(a.bin_count(), b.bin_count()) << what;
  for (std::size_t k = 0; k < a.bin_count(); ++k)
    EXPECT_TRUE(same_bits(a.count(k), b.count(k))) << what << " bin " << k;
  EXPECT_TRUE(same_bits(a.underflow(), b.underflow())) << what;
  EXPECT_TRUE(same_bits(a.overflow(), b.overflow())) << what;
}

// Every measured number bit for bit (the window's wall time aside), and the particles' state.
void expect_same_bits(const ShearCellRun& a, const ShearCellRun& b) {
  const ShearCellMeasurements& x = a.measurements();
  const ShearCellMeasurements& y = b.measurements();
  EXPECT_EQ(x.steps, y.steps);
  const std::vector<std::pair<const char*, std::pair<double, double>>> values = {
      {"bulk shear rate", {x.bulk_shear_rate, y.bulk_shear_rate}},
      {"wall speed", {x.wall_speed, y.wall_speed}},
      {"gap", {x.gap, y.gap}},
      {"shear stress", {x.shear_stress, y.shear_stress}},
      {"normal stress", {x.normal_stress, y.normal_stress}},
      {"media solid fraction", {x.media_solid_fraction, y.media_solid_fraction}},
      {"powder solid fraction", {x.powder_solid_fraction, y.powder_solid_fraction}},
      {"power density", {x.power_density, y.power_density}},
      {"dissipation", {x.dissipation_density_total, y.dissipation_density_total}},
      {"work in", {x.work_in, y.work_in}},
      {"kinetic change", {x.kinetic_change, y.kinetic_change}},
      {"elastic change", {x.elastic_change, y.elastic_change}},
      {"dissipated", {x.dissipated, y.dissipated}},
      {"stress control work", {x.stress_control_work, y.stress_control_work}},
      {"first half", {x.shear_stress_first_half, y.shear_stress_first_half}},
      {"second half", {x.shear_stress_second_half, y.shear_stress_second_half}},
      {"mean pressure", {x.mean_pressure, y.mean_pressure}},
      {"stress xy", {x.stress_tensor[3], y.stress_tensor[3]}},
      {"friction error", {x.friction_error.standard_error, y.friction_error.standard_error}},
      {"powder dissipation error",
       {x.powder_dissipation_error.standard_error, y.powder_dissipation_error.standard_error}},
  };
  EXPECT_EQ(x.blocks, y.blocks);
  EXPECT_EQ(x.stationary, y.stationary);
  EXPECT_EQ(x.converged, y.converged);
  for (const auto& [name, pair] : values)
    EXPECT_TRUE(same_bits(pair.first, pair.second))
        << name << ": " << pair.first << " vs " << pair.second;
  for (std::size_t t = 0; t < kContactTypeCount; ++t) {
    EXPECT_TRUE(same_bits(x.dissipation_density[t], y.dissipation_density[t]))
        << "dissipation of type " << t;
    EXPECT_TRUE(same_bits(x.collisions[t].count, y.collisions[t].count))
        << "collisions of type " << t;
    expect_same_histogram(x.collisions[t].dissipated_energy, y.collisions[t].dissipated_energy,
                          "spectrum");
    EXPECT_TRUE(same_bits(x.overlaps[t].mean_fraction, y.overlaps[t].mean_fraction))
        << "overlap of type " << t;
    EXPECT_TRUE(same_bits(x.overlaps[t].p95_fraction, y.overlaps[t].p95_fraction))
        << "overlap p95 of type " << t;
  }
  const System& s = a.cell().system();
  const System& t = b.cell().system();
  ASSERT_EQ(s.step_count(), t.step_count());
  for (std::size_t p = 0; p < s.size(); ++p) {
    for (int axis = 0; axis < 3; ++axis) {
      ASSERT_TRUE(same_bits(s.positions()[p][axis], t.positions()[p][axis])) << "particle " << p;
      ASSERT_TRUE(same_bits(s.velocities()[p][axis], t.velocities()[p][axis])) << "particle " << p;
    }
  }
}

class ShearCellCheckpoint : public ::testing::TestWithParam<ShearCellSetup::Boundary> {
 protected:
  void SetUp() override { spdlog::set_level(spdlog::level::warn); }
  millflow::testing::ScratchDir dir;
};

TEST_P(ShearCellCheckpoint, StoppingAnywhereAndContinuingGivesTheSameBits) {
  const ShearCellSetup setup = tiny_cell(GetParam());
  ShearCellRun uninterrupted(setup, tiny_protocol());
  while (!uninterrupted.advance(1000)) {
  }
  ASSERT_GT(uninterrupted.measurements().work_in, 0.0);
  // The window finishes collisions, which a stop inside it must carry over.
  ASSERT_GT(uninterrupted.measurements().media_collisions.count, 0.0);

  // Stop before compaction, after every chunk of an odd size while it compacts (a chunk ends
  // there at the first control interval's end past it), then after every few chunks, through
  // both warm-up windows and the measurement; each stop saves, and a new run continues from the
  // file.
  const std::filesystem::path file = dir.path() / "cell.ckpt";
  ShearCellRun first(setup, tiny_protocol());
  first.save(file);
  ShearCellRun run = ShearCellRun::resume(setup, tiny_protocol(), file);
  std::set<std::string> stopped_in;
  int stops_while_compacting = 0;
  for (int chunk = 1; !run.advance(37); ++chunk) {
    const bool compacting = !run.cell().compacted();
    if (chunk % 9 != 0 && !compacting) continue;
    stopped_in.insert(run.phase_name());
    stops_while_compacting += compacting;
    run.save(file);
    run = ShearCellRun::resume(setup, tiny_protocol(), file);
  }
  EXPECT_EQ(stopped_in, (std::set<std::string>{"compacting", "warm-up window 1 (at most 2)",
                                               "warm-up window 2 (at most 2)", "measuring"}));
  EXPECT_GE(stops_while_compacting, 3);
  expect_same_bits(uninterrupted, run);
}

// At I = 0.3 and k_n / (p d) = 1e4 the barostat splits its answers into parts over the interval
// (dem/stress_control.hpp); stops at odd steps fall between parts, whose strain still to stretch
// the checkpoint must carry.
TEST_F(ShearCellCheckpoint, StoppingBetweenTheBarostatsPartsGivesTheSameBits) {
  ShearCellSetup setup = tiny_cell(ShearCellSetup::Boundary::LeesEdwards);
  setup.shear_rate *= 3.0;  // I = 0.3
  setup.media_media.normal_stiffness = 1e4 * setup.normal_stress * setup.media_diameter;
  setup.steps_per_collision = 40;
  ShearCellRun uninterrupted(setup, tiny_protocol());
  while (!uninterrupted.advance(1000)) {
  }
  const std::filesystem::path file = dir.path() / "cell.ckpt";
  ShearCellRun run(setup, tiny_protocol());
  for (int chunk = 1; !run.advance(37); ++chunk) {
    if (chunk % 5 != 0) continue;
    run.save(file);
    run = ShearCellRun::resume(setup, tiny_protocol(), file);
  }
  expect_same_bits(uninterrupted, run);
}

INSTANTIATE_TEST_SUITE_P(Boundaries, ShearCellCheckpoint,
                         ::testing::Values(ShearCellSetup::Boundary::RoughWalls,
                                           ShearCellSetup::Boundary::LeesEdwards));

std::string resume_error(const ShearCellSetup& setup, const std::filesystem::path& file) {
  try {
    ShearCellRun::resume(setup, tiny_protocol(), file);
  } catch (const CorruptData& error) {
    return error.what();
  }
  return "no error";
}

TEST(ShearCellCheckpointFile, TruncatedAlteredForeignAndMissingFilesAreRefused) {
  spdlog::set_level(spdlog::level::warn);
  millflow::testing::ScratchDir dir;
  const ShearCellSetup setup = tiny_cell(ShearCellSetup::Boundary::LeesEdwards);
  ShearCellRun run(setup, tiny_protocol());
  run.advance(200);
  const std::filesystem::path file = dir.path() / "cell.ckpt";
  run.save(file);
  std::ifstream stream(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(stream)),
                          std::istreambuf_iterator<char>());
  auto write = [&](const std::string& content) {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out << content;
  };

  write(bytes.substr(0, bytes.size() / 2));
  EXPECT_NE(resume_error(setup, file).find("is truncated"), std::string::npos)
      << resume_error(setup, file);
  std::string altered = bytes;
  altered[altered.size() / 2] ^= 0x20;
  write(altered);
  EXPECT_NE(resume_error(setup, file).find("checksum mismatch"), std::string::npos)
      << resume_error(setup, file);
  write(bytes);
  ShearCellSetup other = setup;
  other.seed += 1;
  EXPECT_NE(resume_error(other, file).find("the checkpoint is of another shear cell or protocol"),
            std::string::npos);
  EXPECT_EQ(resume_error(setup, file), "no error");
  // The same payload in a container of the previous version: refused, not misread.
  write_checksummed_file(file, "MFSHRCKP", kShearCellCheckpointVersion - 1,
                         read_checksummed_file(file, "MFSHRCKP", kShearCellCheckpointVersion));
  EXPECT_NE(resume_error(setup, file)
                .find(fmt::format(
                    "a shear cell checkpoint of version {}, this build continues version {} only",
                    kShearCellCheckpointVersion - 1, kShearCellCheckpointVersion)),
            std::string::npos)
      << resume_error(setup, file);
  std::filesystem::remove(file);
  EXPECT_NE(resume_error(setup, file).find("cannot read"), std::string::npos);
}

// A cell interrupted under one build's physics is not finished under another's: the checkpoint
// names the code version that wrote it (the task kind's), and a run of another version refuses it.
TEST(ShearCellCheckpointFile, ACheckpointOfAnotherCodeVersionIsRefusedNamingBoth) {
  spdlog::set_level(spdlog::level::warn);
  millflow::testing::ScratchDir dir;
  const ShearCellSetup setup = tiny_cell(ShearCellSetup::Boundary::LeesEdwards);
  ShearCellProtocol written_by = tiny_protocol();
  written_by.code_version = "15";
  ShearCellRun run(setup, written_by);
  run.advance(200);
  const std::filesystem::path file = dir.path() / "cell.ckpt";
  run.save(file);
  ShearCellProtocol continued_by = written_by;
  continued_by.code_version = "16";
  try {
    ShearCellRun::resume(setup, continued_by, file);
    ADD_FAILURE() << "a checkpoint of code version 15 was continued by version 16";
  } catch (const CorruptData& error) {
    EXPECT_EQ(std::string(error.what()),
              file.string() +
                  ": the checkpoint was written by shear cell code version '15', this run is "
                  "version '16' (it would finish under other physics than it started with)");
  }
  const ShearCellRun same = ShearCellRun::resume(setup, written_by, file);
  EXPECT_EQ(same.cell().system().step_count(), run.cell().system().step_count());
}

// with_interactions: a run continued with its own setup keeps every bit; continued with stiffer
// powder contacts, it holds what a cell built with them holds (the materials, the time step) and
// the same particles; a setup that differs in anything but its interactions is refused.
TEST(ShearCellWithInteractions, AtItsOwnSetupTheRunKeepsEveryBit) {
  const ShearCellSetup setup = tiny_cell(ShearCellSetup::Boundary::LeesEdwards);
  ShearCellRun uninterrupted(setup, tiny_protocol());
  while (!uninterrupted.advance(1000)) {
  }
  ShearCellRun run(setup, tiny_protocol());
  for (int chunk = 0; chunk < 12; ++chunk) run.advance(37);
  ShearCellRun continued = run.with_interactions(setup);
  EXPECT_EQ(checkpoint_payload(continued.cell().system()), checkpoint_payload(run.cell().system()));
  while (!continued.advance(1000)) {
  }
  expect_same_bits(uninterrupted, continued);
}

TEST(ShearCellWithInteractions, StifferPowderContactsAreThoseOfACellBuiltWithThem) {
  const ShearCellSetup real = tiny_cell(ShearCellSetup::Boundary::LeesEdwards);
  ShearCellSetup soft = real;
  soft.media_powder.normal_stiffness /= 16.0;
  soft.powder_powder.normal_stiffness /= 16.0;
  ShearCellRun run(soft, tiny_protocol());
  for (int chunk = 0; chunk < 12; ++chunk) run.advance(37);
  const ShearCellRun stiff = run.with_interactions(real);
  const ShearCellRun fresh(real, tiny_protocol());
  const System& got = stiff.cell().system();
  const System& want = fresh.cell().system();
  ASSERT_EQ(got.materials().size(), want.materials().size());
  for (MaterialId a = 0; a < want.materials().size(); ++a) {
    for (MaterialId b = a; b < want.materials().size(); ++b) {
      EXPECT_EQ(got.materials().pair(a, b).normal_stiffness,
                want.materials().pair(a, b).normal_stiffness)
          << a << "-" << b;
    }
  }
  EXPECT_EQ(got.time_step(), want.time_step());
  EXPECT_NE(got.time_step(), run.cell().system().time_step());
  ASSERT_EQ(got.size(), run.cell().system().size());
  for (std::size_t p = 0; p < got.size(); ++p) {
    EXPECT_EQ(got.positions()[p], run.cell().system().positions()[p]) << p;
    EXPECT_EQ(got.velocities()[p], run.cell().system().velocities()[p]) << p;
  }
}

TEST(ShearCellWithInteractions, ASetupThatDiffersInMoreThanItsInteractionsIsRefused) {
  const ShearCellSetup setup = tiny_cell(ShearCellSetup::Boundary::LeesEdwards);
  ShearCellRun run(setup, tiny_protocol());
  ShearCellSetup faster = setup;
  faster.shear_rate *= 2.0;
  EXPECT_THROW(run.with_interactions(faster), std::invalid_argument);
}

// relieve_normal_stress: a dense cell prepared with soft powder contacts holds many times its
// target once they are made real; the relief stretches it back to the target with the barostat
// held (its state untouched), the same bits every time; rough walls are refused.
ShearCellRun stiffened_dense_cell() {
  ShearCellSetup real = small_shear_cell(0.01, 1.5, 0.5);
  real.boundary = ShearCellSetup::Boundary::LeesEdwards;
  real.size_diameters = Vec3(4, 5, 4);
  ShearCellSetup soft = real;
  soft.media_powder.normal_stiffness /= 16.0;
  soft.powder_powder.normal_stiffness /= 16.0;
  const ShearCellProtocol protocol{.warmup_strain = 0.05,
                                   .warmup_windows = 1,
                                   .max_warmup_strain = 0.05,
                                   .measure_strain = 10.0,
                                   .measure = {}};
  ShearCellRun run(soft, protocol);
  while (run.phase_name() != "measuring") run.advance(1000);
  run.advance(2000);
  return run.with_interactions(real);
}

TEST(ShearCellRelief, StretchesAStiffenedCellBackToItsTargetWithTheBarostatHeld) {
  ShearCellRun a = stiffened_dense_cell();
  ShearCell& cell = a.cell();
  const double target = cell.setup().normal_stress;
  const double height = cell.system().domain().length().y();
  const double smoothed = cell.stress_control().smoothed_stress();
  const double last = cell.stress_control().last_interval_stress();
  const std::uint64_t step = cell.system().step_count();
  const StressReliefResult relief = cell.relieve_normal_stress({.tolerance = 0.1});
  EXPECT_GT(relief.first_stress, 3.0 * target);
  EXPECT_TRUE(relief.relieved);
  EXPECT_LE(std::abs(relief.normal_stress / target - 1.0), 0.1);
  EXPECT_GT(relief.strain, 0.0);
  EXPECT_NEAR(relief.strain, std::log(cell.system().domain().length().y() / height), 1e-12);
  EXPECT_EQ(cell.system().step_count(), step + relief.steps);
  EXPECT_EQ(relief.steps,
            static_cast<std::uint64_t>(relief.intervals * cell.setup().steps_per_collision));
  EXPECT_EQ(cell.stress_control().smoothed_stress(), smoothed);
  EXPECT_EQ(cell.stress_control().last_interval_stress(), last);
  // The images' velocity follows the height: the shear rate stays.
  EXPECT_NEAR(cell.wall_speed() / cell.system().domain().length().y(), cell.setup().shear_rate,
              1e-9 * cell.setup().shear_rate);
  // The relief's finished contacts wait in the buffer for the measured window's tally, which
  // takes them first when the window goes on (ShearCell::advance_measurement).
  EXPECT_GT(cell.system().memory_use().collision_events, 0u);
  // The run goes on from the relieved state.
  a.advance(200);
  EXPECT_EQ(a.phase_name(), "measuring");
  EXPECT_EQ(cell.system().memory_use().collision_events, 0u);

  ShearCellRun b = stiffened_dense_cell();
  const StressReliefResult again = b.cell().relieve_normal_stress({.tolerance = 0.1});
  EXPECT_EQ(again.steps, relief.steps);
  EXPECT_TRUE(same_bits(again.normal_stress, relief.normal_stress));
  b.advance(200);
  EXPECT_EQ(checkpoint_payload(b.cell().system()), checkpoint_payload(a.cell().system()));
}

TEST(ShearCellRelief, HoldsOnTargetForItsHoldAndResetsTheBarostatsIntegralTerm) {
  ShearCellRun plain = stiffened_dense_cell();
  const StressReliefResult quick = plain.cell().relieve_normal_stress({.tolerance = 0.1});
  ASSERT_TRUE(quick.relieved);

  ShearCellRun a = stiffened_dense_cell();
  ShearCell& cell = a.cell();
  const double target = cell.setup().normal_stress;
  // The dense cell's barostat ran before the stiffening: its integral term is not 0.
  EXPECT_NE(cell.stress_control().integral_term(), 0.0);
  const std::uint64_t hold = 20 * static_cast<std::uint64_t>(cell.setup().steps_per_collision);
  const StressReliefResult held =
      cell.relieve_normal_stress({.tolerance = 0.1, .max_steps = 40000, .hold_steps = hold});
  EXPECT_TRUE(held.relieved);
  EXPECT_LE(std::abs(held.normal_stress / target - 1.0), 0.1);
  // The same law up to the first interval on target (not the first: it holds 3x the target),
  // then `hold` steps more at least.
  const auto interval = static_cast<std::uint64_t>(cell.setup().steps_per_collision);
  EXPECT_GE(held.steps, 2 * interval + hold);
  EXPECT_GT(held.steps, quick.steps);
  EXPECT_EQ(cell.stress_control().integral_term(), 0.0);
  EXPECT_EQ(plain.cell().stress_control().integral_term(), 0.0);
  a.advance(200);
  EXPECT_EQ(a.phase_name(), "measuring");
}

TEST(ShearCellRelief, OnlyLeesEdwardsCellsAfterCompaction) {
  ShearCell walled(tiny_cell(ShearCellSetup::Boundary::RoughWalls));
  walled.compact();
  EXPECT_THROW(walled.relieve_normal_stress(), std::logic_error);
  ShearCell loose(tiny_cell(ShearCellSetup::Boundary::LeesEdwards));
  EXPECT_THROW(loose.relieve_normal_stress(), std::logic_error);
}

}  // namespace
}  // namespace millflow::dem
