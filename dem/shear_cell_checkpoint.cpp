// The shear cell run's checkpoint: its byte layout (documented at kShearCellCheckpointVersion),
// save and resume.
#include "dem/shear_cell.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "dem/checkpoint.hpp"

#include "dem/shear_cell_geometry.hpp"

namespace millflow::dem {
using namespace shear_cell_detail;

namespace {

constexpr std::string_view kRunMagic = "MFSHRCKP";

void put(BinaryWriter& out, const Vec3& v) {
  for (int a = 0; a < 3; ++a) out.put(v[a]);
}

std::array<double*, 4> means_fields(WindowMeans& w) {
  return {&w.shear_stress, &w.normal_stress, &w.solid_fraction, &w.bulk_shear_rate};
}

// Every setting that shapes the run, so a checkpoint is never continued by another cell.
std::string run_identity(const ShearCellSetup& s, const ShearCellProtocol& protocol) {
  BinaryWriter out;
  out.put(s.media_diameter);
  put_material(out, s.media);
  put_material(out, s.powder);
  for (const InteractionSpec* spec : {&s.media_media, &s.media_powder, &s.powder_powder})
    put_interaction(out, *spec);
  out.put(s.powder_diameter_ratio);
  out.put(s.powder_load);
  out.put(s.powder_bed_solid_fraction);
  put(out, s.size_diameters);
  out.put<std::uint8_t>(static_cast<std::uint8_t>(s.boundary));
  out.put(s.shear_rate);
  out.put(s.normal_stress);
  out.put<std::uint8_t>(s.gravity);
  out.put(s.servo_gain);
  out.put(s.seed);
  out.put(s.media_solid_fraction);
  out.put<std::int32_t>(s.steps_per_collision);
  out.put(s.overlap_bound.mean_fraction);
  out.put(s.overlap_bound.p95_fraction);
  out.put(protocol.warmup_strain);
  out.put<std::int32_t>(protocol.warmup_windows);
  out.put(protocol.max_warmup_strain);
  out.put(protocol.measure_strain);
  out.put<std::int32_t>(protocol.measure.samples);
  out.put(protocol.measure.steady_tolerance);
  out.put<std::uint8_t>(protocol.measure.record_collisions);
  out.put(protocol.measure.standard_error_target);
  out.put(protocol.measure.max_strain);
  return out.bytes();
}

}  // namespace

void ShearCell::Profile::write(BinaryWriter& out) const {
  for (double v : {w, wy, wyy, wv, wyv, media_volume, powder_volume, slab_volume}) out.put(v);
}

void ShearCell::Profile::read(BinaryReader& in) {
  for (double* v : {&w, &wy, &wyy, &wv, &wyv, &media_volume, &powder_volume, &slab_volume})
    *v = in.get<double>();
}

void ShearCell::WarmUpWindow::write(BinaryWriter& out) const {
  for (std::uint64_t v : {steps, half, every, done}) out.put(v);
  profile.write(out);
  for (double v : {shear_sum, normal_sum, samples}) out.put(v);
}

void ShearCell::WarmUpWindow::read(BinaryReader& in) {
  for (std::uint64_t* v : {&steps, &half, &every, &done}) *v = in.get<std::uint64_t>();
  profile.read(in);
  for (double* v : {&shear_sum, &normal_sum, &samples}) *v = in.get<double>();
  if (every == 0 || half > steps || done > steps)
    throw CorruptData("shear cell checkpoint: the warm-up window is out of range");
}

void ShearCell::OverlapHistogram::write(BinaryWriter& out) const {
  out.put<std::uint64_t>(counts.size());
  for (double c : counts) out.put(c);
  out.put(sum);
  out.put(max);
}

void ShearCell::OverlapHistogram::read(BinaryReader& in) {
  const auto size = in.get<std::uint64_t>();
  if (size != 0 && size != kOverlapBins)
    throw CorruptData("shear cell checkpoint: an overlap histogram has the wrong size");
  counts.resize(size);
  for (double& c : counts) c = in.get<double>();
  sum = in.get<double>();
  max = in.get<double>();
}

void MeasuredBlock::write(BinaryWriter& out) const {
  for (double v : {shear_sum, normal_sum, gap_sum, stress_samples, pressure_sum, pressure_samples,
                   shear_work, duration})
    out.put(v);
  for (double v : dissipated) out.put(v);
}

void MeasuredBlock::read(BinaryReader& in) {
  for (double* v : {&shear_sum, &normal_sum, &gap_sum, &stress_samples, &pressure_sum,
                    &pressure_samples, &shear_work, &duration})
    *v = in.get<double>();
  for (double& v : dissipated) v = in.get<double>();
}

void ShearCell::Measurement::write(BinaryWriter& out) const {
  for (std::uint64_t v : {steps, min_steps, block_steps, every, stress_every, done}) out.put(v);
  for (double v : {work0, shear_work0, motion0, budget0.kinetic, budget0.potential, budget0.elastic,
                   budget0.dissipated, budget0.wall_work}) {
    out.put(v);
  }
  out.put<std::uint64_t>(dissipation0.size());
  for (const Dissipation& d : dissipation0) {
    for (double v : {d.normal, d.tangential, d.friction}) out.put(v);
  }
  profile.write(out);
  for (double v : tensor_sum) out.put(v);
  out.put(tensor_samples);
  out.put<std::uint64_t>(blocks.size());
  for (const MeasuredBlock& b : blocks) b.write(out);
  current.write(out);
  out.put(block_shear_work0);
  out.put<std::uint64_t>(block_dissipation0.size());
  for (double v : block_dissipation0) out.put(v);
  for (const OverlapHistogram& h : overlaps) h.write(out);
  for (const CollisionStats& stats : collisions) {
    out.put(stats.count);
    stats.dissipated_energy.write(out);
  }
  out.put(wall_seconds);
  out.put<std::uint8_t>(converged);
}

void ShearCell::Measurement::read(BinaryReader& in) {
  for (std::uint64_t* v : {&steps, &min_steps, &block_steps, &every, &stress_every, &done})
    *v = in.get<std::uint64_t>();
  for (double* v : {&work0, &shear_work0, &motion0, &budget0.kinetic, &budget0.potential,
                    &budget0.elastic, &budget0.dissipated, &budget0.wall_work}) {
    *v = in.get<double>();
  }
  dissipation0.resize(in.get<std::uint64_t>());
  for (Dissipation& d : dissipation0) {
    for (double* v : {&d.normal, &d.tangential, &d.friction}) *v = in.get<double>();
  }
  profile.read(in);
  for (double& v : tensor_sum) v = in.get<double>();
  tensor_samples = in.get<double>();
  const auto block_count = in.get<std::uint64_t>();
  if (block_count > steps)
    throw CorruptData("shear cell checkpoint: more measured blocks than steps");
  blocks.resize(block_count);
  for (MeasuredBlock& b : blocks) b.read(in);
  current.read(in);
  block_shear_work0 = in.get<double>();
  const auto categories = in.get<std::uint64_t>();
  if (categories != dissipation0.size())
    throw CorruptData("shear cell checkpoint: the block's dissipation has the wrong size");
  block_dissipation0.resize(categories);
  for (double& v : block_dissipation0) v = in.get<double>();
  for (OverlapHistogram& h : overlaps) h.read(in);
  for (CollisionStats& stats : collisions) {
    stats.count = in.get<double>();
    stats.dissipated_energy = LogHistogram::read(in);
  }
  wall_seconds = in.get<double>();
  converged = in.get<std::uint8_t>() != 0;
  if (every == 0 || stress_every == 0 || block_steps == 0 || done > steps || min_steps > steps) {
    throw CorruptData("shear cell checkpoint: the measurement is out of range");
  }
}

void ShearCell::write_state(BinaryWriter& out) const {
  for (std::uint64_t count : {media_count_, powder_count_, wall_ball_count_}) out.put(count);
  out.put(wall_speed_);
  out.put(le_work_);
  control_->write(out);
  speed_controller_.write(out);
  out.put(static_cast<std::uint8_t>(compaction_));
  compaction_end_.write(out);
}

void ShearCell::read_state(BinaryReader& in) {
  for (std::size_t* count : {&media_count_, &powder_count_, &wall_ball_count_})
    *count = in.get<std::uint64_t>();
  wall_speed_ = in.get<double>();
  le_work_ = in.get<double>();
  control_->read(in);
  speed_controller_.read(in);
  const auto compaction = in.get<std::uint8_t>();
  if (compaction > static_cast<std::uint8_t>(Compaction::Running))
    throw CorruptData("shear cell checkpoint: compaction's state is out of range");
  compaction_ = static_cast<Compaction>(compaction);
  compaction_end_.read(in);
  if (media_count_ + powder_count_ + wall_ball_count_ != system_.size()) {
    throw CorruptData("shear cell checkpoint: the particle counts do not add up to the system's");
  }
}

ShearCellRun ShearCellRun::resume(const ShearCellSetup& setup, const ShearCellProtocol& protocol,
                                  const std::filesystem::path& path) {
  std::uint32_t version = 0;
  std::string state = read_checksummed_file(path, kRunMagic, kShearCellCheckpointVersion, &version);
  // Only this build's layout is read: an older payload lacks fields this one holds and would be
  // misread (the container accepts any version up to this build's).
  if (version != kShearCellCheckpointVersion) {
    throw CorruptData(fmt::format(
        "{}: a shear cell checkpoint of version {}, this build continues version {} only (the run "
        "starts again)",
        path.string(), version, kShearCellCheckpointVersion));
  }
  return from_state(setup, protocol, state, path.string(), nullptr);
}

ShearCellRun ShearCellRun::with_interactions(const ShearCellSetup& setup) {
  ShearCellSetup same_interactions = setup;
  same_interactions.media_media = cell_.setup().media_media;
  same_interactions.media_powder = cell_.setup().media_powder;
  same_interactions.powder_powder = cell_.setup().powder_powder;
  if (run_identity(same_interactions, protocol_) != run_identity(cell_.setup(), protocol_)) {
    throw std::invalid_argument(
        "shear cell run: with_interactions takes a setup that differs in its interactions only");
  }
  ShearCellRun run = from_state(cell_.setup(), protocol_, state(), "shear cell run", &setup);
  run.cell_.system().set_time_step_from_collisions(setup.steps_per_collision);
  return run;
}

ShearCellRun ShearCellRun::from_state(const ShearCellSetup& setup,
                                      const ShearCellProtocol& protocol, std::string_view state,
                                      const std::string& source,
                                      const ShearCellSetup* continue_with) {
  BinaryReader in(state);
  if (in.get_string() != run_identity(setup, protocol)) {
    throw CorruptData(
        fmt::format("{}: the checkpoint is of another shear cell or protocol", source));
  }
  if (const std::string written_by = in.get_string(); written_by != protocol.code_version) {
    throw CorruptData(fmt::format(
        "{}: the checkpoint was written by shear cell code version '{}', this run is version '{}' "
        "(it would finish under other physics than it started with)",
        source, written_by, protocol.code_version));
  }
  const auto system_version = in.get<std::uint32_t>();
  System system = system_from_checkpoint_payload(in.get_string(), system_version);
  if (continue_with) system = system_with_materials(system, make_materials(*continue_with));
  ShearCellRun run(ShearCell(continue_with ? *continue_with : setup, std::move(system)), protocol);
  run.cell_.read_state(in);
  const auto phase = in.get<std::uint8_t>();
  if (phase > static_cast<std::uint8_t>(Phase::Measuring)) {
    throw CorruptData(fmt::format("{}: unknown shear cell run phase {}", source, phase));
  }
  run.phase_ = static_cast<Phase>(phase);
  if ((run.phase_ == Phase::Compacting) == run.cell_.compacted()) {
    throw CorruptData(
        fmt::format("{}: the run's phase and the cell's compaction disagree", source));
  }
  run.window_index_ = in.get<std::int32_t>();
  run.window_.read(in);
  const auto windows = in.get<std::uint64_t>();
  if (windows > static_cast<std::uint64_t>(run.max_windows_))
    throw CorruptData(fmt::format("{}: more warm-up windows than the protocol allows", source));
  run.windows_.resize(windows);
  for (WindowMeans& w : run.windows_) {
    for (double* v : means_fields(w)) *v = in.get<double>();
  }
  run.stationary_strain_ = in.get<double>();
  run.stationary_ = in.get<std::uint8_t>() != 0;
  run.measurement_.read(in);
  run.measurement_.options = protocol.measure;
  if (!in.at_end())
    throw CorruptData(fmt::format("{}: trailing bytes after the shear cell run", source));
  return run;
}

void ShearCellRun::save(const std::filesystem::path& path) {
  write_checksummed_file(path, kRunMagic, kShearCellCheckpointVersion, state());
}

std::string ShearCellRun::state() {
  if (done()) throw std::logic_error("shear cell run: a finished run has nothing to checkpoint");
  if (phase_ == Phase::Measuring) cell_.tally_collisions(measurement_);
  BinaryWriter out;
  out.put_string(run_identity(cell_.setup(), protocol_));
  out.put_string(protocol_.code_version);
  out.put(kCheckpointVersion);
  out.put_string(checkpoint_payload(cell_.system()));
  cell_.write_state(out);
  out.put(static_cast<std::uint8_t>(phase_));
  out.put<std::int32_t>(window_index_);
  window_.write(out);
  out.put<std::uint64_t>(windows_.size());
  for (WindowMeans w : windows_) {
    for (double* v : means_fields(w)) out.put(*v);
  }
  out.put(stationary_strain_);
  out.put<std::uint8_t>(stationary_);
  measurement_.write(out);
  return out.bytes();
}

}  // namespace millflow::dem
