#include "method/macro_run.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>

#include "dem/checkpoint.hpp"
#include "dem/vtk.hpp"
#include "util/durable_file.hpp"
#include "util/sha256.hpp"

namespace millflow::method {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::size_t kFramesPerSegment = 16;
constexpr double kBlocksPerRevolution = 200.0;
constexpr std::string_view kStateMagic = "MFMACRO1";
// 2: the VTK files' SHA-256s (version 1 held their times only: a file damaged before the
// checkpoint went into the results; such a state is refused and the run starts again).
constexpr std::uint32_t kStateVersion = 2;
constexpr std::uint32_t kShellWall = 0;  // dem::build_mill's shell
constexpr dem::MaterialId kMedia = 0;    // dem::build_mill's media material

// The most steps an interval may take: 2^53, where doubles stop counting exactly. An interval
// longer than any run (a VTK interval of 1e15 s) saturates there and so comes only at step 0;
// converted to an integer unchecked, it wrapped to 1, an action every step.
constexpr std::uint64_t kMostStepsForAnInterval = std::uint64_t{1}
                                                  << std::numeric_limits<double>::digits;

std::uint64_t steps_for(double seconds, double dt) {
  const double steps = std::round(seconds / dt);
  if (!(steps < static_cast<double>(kMostStepsForAnInterval))) return kMostStepsForAnInterval;
  return std::max<std::uint64_t>(1, static_cast<std::uint64_t>(steps));
}

std::string segment_name(std::uint64_t index) {
  return fmt::format("flow/segment_{:04d}.mfs", index);
}
std::string vtk_name(std::size_t index) {
  return fmt::format("particles_{:04d}.vtp", index);
}
std::string outline_name(std::size_t index) {
  return fmt::format("mill_{:04d}.vtp", index);
}
fs::path checkpoint_file(const fs::path& dir, std::uint64_t step) {
  return dir / fmt::format("checkpoint_{}.ckpt", step);
}
fs::path pending_file(const fs::path& dir, std::uint64_t step) {
  return dir / fmt::format("pending_{}.mfs", step);
}

// The committed checkpoint's step, if a previous attempt left one.
std::optional<std::uint64_t> committed_step(const fs::path& dir) {
  if (!fs::exists(dir / "state.bin")) return std::nullopt;
  const std::string payload =
      dem::read_checksummed_file(dir / "state.bin", kStateMagic, kStateVersion);
  dem::BinaryReader in(payload);
  return in.get<std::uint64_t>();
}

double smallest_diameter(const dem::MillSetup& mill) {
  double smallest = std::numeric_limits<double>::infinity();
  for (const auto& size : dem::ball_size_classes(mill))
    smallest = std::min(smallest, size.diameter);
  return smallest;
}

dem::System fresh_system(const MacroSettings& settings) {
  dem::System system = dem::build_mill(settings.mill);
  system.set_time_step_from_collisions(settings.steps_per_collision);
  system.set_neighbor_skin(settings.skin_fraction.value_or(dem::kDefaultSkinFraction) *
                           smallest_diameter(settings.mill));
  return system;
}

// The collision energy spectra of the result as a table: a row per bin, a column per
// category and energy (collisions in the bin over the measurement).
void write_spectra_csv(const MacroResult& result, const fs::path& path) {
  const std::vector<double>& edges = result.spectrum_bin_edges_j;
  std::string text = "energy_low_j,energy_high_j";
  for (const auto& [label, collisions] : result.collisions)
    text += fmt::format(",{0}_impact_energy_count,{0}_dissipated_energy_count", label);
  text += '\n';
  for (std::size_t bin = 0; bin + 1 < edges.size(); ++bin) {
    text += fmt::format("{},{}", edges[bin], edges[bin + 1]);
    // A count as the result's JSON writes it (a double keeps its ".0").
    for (const auto& [label, c] : result.collisions) {
      text += fmt::format(",{},{}", json(c.impact_energy.counts[bin]).dump(),
                          json(c.dissipated_energy.counts[bin]).dump());
    }
    text += '\n';
  }
  util::write_file_durably(path, text);
}

}  // namespace

MacroRun::Schedule::Schedule(const MacroSettings& settings, double time_step) : dt(time_step) {
  omega_c = dem::critical_speed(2 * settings.mill.shell.radius,
                                dem::mean_ball_diameter(settings.mill), settings.mill.gravity);
  omega = settings.mill.speed_fraction * omega_c;
  const double revolution = 2 * std::numbers::pi / omega;
  settle_end = static_cast<std::uint64_t>(std::ceil(settings.settle_time / dt));
  warm_end = settle_end + static_cast<std::uint64_t>(
                              std::llround(settings.warmup_revolutions * revolution / dt));
  sample_steps = steps_for(settings.sample_interval, dt);
  frame_count = std::max<std::uint64_t>(
      1, static_cast<std::uint64_t>(
             std::llround(settings.measure_revolutions * revolution / (sample_steps * dt))));
  measure_end = warm_end + frame_count * sample_steps;
  vtk_steps = steps_for(settings.vtk_interval, dt);
  block_steps = steps_for(revolution / kBlocksPerRevolution, dt);
}

double MacroRun::Schedule::revolutions(std::uint64_t steps) const {
  return static_cast<double>(steps) * dt * omega / (2 * std::numbers::pi);
}

MacroRun::MacroRun(const MacroSettings& settings, const fs::path& dir, Log log, dem::System system)
    : settings_(settings),
      dir_(dir),
      log_(std::move(log)),
      system_(std::move(system)),
      schedule_(settings_, system_.time_step()),
      power_(schedule_.block_steps),
      collisions_({{"ball_ball", system_.pair_category(kMedia, kMedia)},
                   {"ball_liner", system_.wall_category(kShellWall, kMedia)}}) {
  fs::create_directories(dir_ / "flow");
  fs::create_directories(dir_ / "vtk");
}

MacroRun::MacroRun(const MacroSettings& settings, const fs::path& dir, Log log)
    : MacroRun(settings, dir, std::move(log), fresh_system(settings)) {
  log_setup();
}

bool MacroRun::saved_in(const fs::path& dir) {
  return fs::exists(dir / "state.bin");
}

MacroRun MacroRun::resume(const MacroSettings& settings, const fs::path& dir, Log log) {
  const auto step = committed_step(dir);
  if (!step) throw dem::CorruptData("macro state: no state.bin in " + dir.string());
  MacroRun run(settings, dir, std::move(log), dem::load_checkpoint(checkpoint_file(dir, *step)));
  run.restore();
  return run;
}

bool MacroRun::advance(std::uint64_t max_steps) {
  for (std::uint64_t n = 0; n < max_steps && !finished_; ++n) {
    const std::uint64_t s = system_.step_count();
    act(s);
    if (s == schedule_.measure_end) {
      finished_ = true;
      break;
    }
    system_.step(1);
    if (s >= schedule_.warm_end) measure_step(s + 1);
  }
  return finished_;
}

double MacroRun::progress() const {
  return static_cast<double>(system_.step_count()) / static_cast<double>(schedule_.measure_end);
}

std::string MacroRun::phase_name() const {
  const std::uint64_t s = system_.step_count();
  if (s < schedule_.settle_end) {
    return fmt::format("settling {:.2f}/{:.2f} s", s * schedule_.dt,
                       schedule_.settle_end * schedule_.dt);
  }
  if (s < schedule_.warm_end) {
    return fmt::format("warm-up rev {:.1f}/{:.1f}", schedule_.revolutions(s - schedule_.settle_end),
                       schedule_.revolutions(schedule_.warm_end - schedule_.settle_end));
  }
  return fmt::format("rev {:.1f}/{:.1f}", schedule_.revolutions(s - schedule_.warm_end),
                     schedule_.revolutions(schedule_.measure_end - schedule_.warm_end));
}

// Checkpoint: pending frames and the DEM state under the step's name, then state.bin (the
// commit), then the previous checkpoint's files go.
void MacroRun::save() {
  if (finished_) throw std::logic_error("MacroRun::save: the run is done");
  auto taken = system_.take_collision_events();
  pending_events_.insert(pending_events_.end(), taken.begin(), taken.end());
  const std::uint64_t step = system_.step_count();
  if (!pending_frames_.empty()) dem::write_flow_segment(pending_file(dir_, step), pending_frames_);
  dem::save_checkpoint(system_, checkpoint_file(dir_, step));
  dem::BinaryWriter out;
  out.put(step);
  write_state(out);
  dem::write_checksummed_file(dir_ / "state.bin", kStateMagic, kStateVersion, out.bytes());
  remove_checkpoints_except(step);
}

MacroOutcome MacroRun::finish() {
  if (!finished_) throw std::logic_error("MacroRun::finish: the run is not done");
  MacroOutcome outcome{.result = result(), .artifacts = {}};
  auto add = [&](const std::string& name) { outcome.artifacts.push_back(name); };
  write_power_csv(dir_ / "power.csv");
  add("power.csv");
  write_spectra_csv(outcome.result, dir_ / "collision_spectra.csv");
  add("collision_spectra.csv");
  for (std::uint64_t k = 0; k < segments_; ++k) add(segment_name(k));
  std::vector<dem::PvdEntry> particles, outlines;
  for (std::size_t k = 0; k < vtk_times_.size(); ++k) {
    particles.push_back({vtk_times_[k], vtk_name(k)});
    outlines.push_back({vtk_times_[k], outline_name(k)});
    add("vtk/" + vtk_name(k));
    add("vtk/" + outline_name(k));
  }
  dem::write_pvd(dir_ / "vtk/particles.pvd", particles);
  add("vtk/particles.pvd");
  dem::write_pvd(dir_ / "vtk/mill.pvd", outlines);
  add("vtk/mill.pvd");
  // The last checkpoint stays: the work directory goes after the task's commit, and an attempt
  // killed while its artifacts are stored continues from it instead of from scratch.
  const MacroPower& power = outcome.result.power;
  log(fmt::format(
      "macro: power {:.4g} kW ({:.4g} kW/m, {:.4g} kW/t), torque arm {:.4g} kW; {} frames in {} "
      "segments",
      power.mean_kw, power.kw_per_m, power.kw_per_t_balls, power.torque_arm_kw, frames_,
      segments_));
  return outcome;
}

void MacroRun::log(const std::string& message) const {
  if (log_) log_(message);
}

// What happens at step count s, before the step from s to s + 1.
void MacroRun::act(std::uint64_t s) {
  if (s == schedule_.settle_end) dem::set_mill_speed(system_, schedule_.omega);
  if (s == schedule_.warm_end) start_measuring();
  if (s > schedule_.warm_end && (s - schedule_.warm_end) % schedule_.sample_steps == 0)
    capture_frame();
  if (s % schedule_.vtk_steps == 0) write_vtk();
}

void MacroRun::start_measuring() {
  // "auto": the skin is chosen on the charge in motion, before the measurement records collisions
  // (the trials step copies; no result depends on the skin).
  if (!settings_.skin_fraction) {
    const dem::SkinChoice choice = dem::adopt_skin_by_trials(system_);
    log(fmt::format("macro: neighbour skin \"auto\" chose {:.3g} x the smallest diameter",
                    choice.skin_fraction()));
  }
  system_.set_record_collisions(true);
  measure_start_s_ = system_.time();
  dissipated_at_start_ = system_.energy().dissipated;
  log(fmt::format(
      "macro: measuring from t = {:.4g} s for {} frames of {:.4g} s ({:.4g} revolutions)",
      measure_start_s_, schedule_.frame_count, schedule_.sample_steps * schedule_.dt,
      schedule_.revolutions(schedule_.measure_end - schedule_.warm_end)));
}

void MacroRun::measure_step(std::uint64_t s) {
  if (power_.add_step(system_.wall_load(kShellWall).power) ||
      (s == schedule_.measure_end && power_.block_open())) {
    power_.close_block(system_.time(), torque_arm_power(system_, schedule_.omega));
  }
}

void MacroRun::capture_frame() {
  auto taken = system_.take_collision_events();
  pending_events_.insert(pending_events_.end(), taken.begin(), taken.end());
  collisions_.add(pending_events_);
  pending_frames_.push_back(dem::capture_frame(system_, mill_angle(), pending_events_));
  pending_events_.clear();
  charge_.add_frame(pending_frames_.back(), kShellWall);
  ++frames_;
  if (pending_frames_.size() == kFramesPerSegment || frames_ == schedule_.frame_count) {
    dem::write_flow_segment(dir_ / segment_name(segments_), pending_frames_);
    ++segments_;
    pending_frames_.clear();
  }
}

// The particles and the shell with its lifters at the same moment, so they turn together.
void MacroRun::write_vtk() {
  const fs::path particles = dir_ / "vtk" / vtk_name(vtk_times_.size());
  const fs::path outline = dir_ / "vtk" / outline_name(vtk_times_.size());
  dem::write_particles_vtp(system_, particles);
  dem::write_mill_outline_vtp(settings_.mill.shell, mill_angle(), outline);
  vtk_times_.push_back(system_.time());
  for (const fs::path& file : {particles, outline})
    vtk_digests_.push_back(util::sha256_file_hex(file));
}

double MacroRun::mill_angle() const {
  return std::get<dem::MillWall>(system_.wall(kShellWall).shape).angle;
}

void MacroRun::remove_checkpoints_except(std::uint64_t keep) const {
  for (const auto& entry : fs::directory_iterator(dir_)) {
    const fs::path& path = entry.path();
    if (path == checkpoint_file(dir_, keep) || path == pending_file(dir_, keep)) continue;
    const std::string name = path.filename().string();
    if (name.starts_with("checkpoint_") || name.starts_with("pending_")) fs::remove(path);
  }
}

void MacroRun::write_state(dem::BinaryWriter& out) const {
  out.put(measure_start_s_);
  out.put(dissipated_at_start_);
  out.put(frames_);
  out.put(segments_);
  out.put<std::uint64_t>(pending_frames_.size());
  out.put_span(std::span<const double>(vtk_times_));
  for (const std::string& digest : vtk_digests_) out.put_string(digest);
  write_events(out, pending_events_);
  power_.write(out);
  charge_.write(out);
  collisions_.write(out);
}

void MacroRun::restore() {
  const std::string payload =
      dem::read_checksummed_file(dir_ / "state.bin", kStateMagic, kStateVersion);
  dem::BinaryReader in(payload);
  const auto step = in.get<std::uint64_t>();
  if (step != system_.step_count()) {
    throw dem::CorruptData(fmt::format(
        "macro state is for step {} but its checkpoint is at step {}", step, system_.step_count()));
  }
  measure_start_s_ = in.get<double>();
  dissipated_at_start_ = in.get<double>();
  frames_ = in.get<std::uint64_t>();
  segments_ = in.get<std::uint64_t>();
  const auto pending = in.get<std::uint64_t>();
  vtk_times_ = in.get_vector<double>();
  vtk_digests_.clear();
  for (std::size_t k = 0; k < 2 * vtk_times_.size(); ++k) vtk_digests_.push_back(in.get_string());
  pending_events_ = read_events(in);
  power_.read(in);
  charge_.read(in);
  collisions_.read(in);
  if (pending > 0) pending_frames_ = dem::read_flow_segment(pending_file(dir_, step));
  if (pending_frames_.size() != pending)
    throw dem::CorruptData("macro state: the pending flow frames are missing");
  // The flow segments and VTK files written before the checkpoint belong to its state: one
  // damaged or gone would fail the run at its end, so the checkpoint is refused now instead.
  for (std::uint64_t k = 0; k < segments_; ++k) dem::read_flow_segment(dir_ / segment_name(k));
  for (std::size_t k = 0; k < vtk_times_.size(); ++k) {
    const std::string names[] = {vtk_name(k), outline_name(k)};
    for (std::size_t f = 0; f < 2; ++f) {
      const fs::path file = dir_ / "vtk" / names[f];
      if (!fs::is_regular_file(file))
        throw dem::CorruptData(fmt::format("macro state: vtk/{} is missing", names[f]));
      if (util::sha256_file_hex(file) != vtk_digests_[2 * k + f])
        throw dem::CorruptData(
            fmt::format("macro state: vtk/{} is not the file written", names[f]));
    }
  }
  log(fmt::format(
      "macro: continuing from the checkpoint at step {} (t = {:.4g} s), {} flow frames written",
      step, system_.time(), frames_));
}

void MacroRun::log_setup() const {
  const auto& mill = settings_.mill;
  log(fmt::format(
      "macro: D = {} m, L = {} m ({}), {} lifters; {} balls, mass {:.4g} kg, mean diameter {} m",
      2 * mill.shell.radius, mill.shell.length, mill.shell.end_walls ? "end walls" : "periodic",
      mill.shell.lifter_count, system_.size(), ball_mass(), dem::mean_ball_diameter(mill)));
  for (const auto& [label, contact] : contacts()) {
    log(fmt::format(
        "macro: {} ({}): k_n = {:.4g} N/m, k_t = {:.4g} N/m, t_c = {:.4g} s for m_eff = {:.4g} "
        "kg",
        label, contact.pair, contact.normal_stiffness_n_m, contact.tangential_stiffness_n_m,
        contact.collision_time_s, contact.reference_mass_kg));
  }
  log(fmt::format(
      "macro: t_c(min) = {:.4g} s, dt = {:.4g} s; critical speed {:.4g} rad/s, omega = {:.4g} "
      "rad/s "
      "({} x critical); steps: settle {}, warm-up to {}, measure to {}",
      system_.min_collision_duration(), schedule_.dt, schedule_.omega_c, schedule_.omega,
      mill.speed_fraction, schedule_.settle_end, schedule_.warm_end, schedule_.measure_end));
}

double MacroRun::ball_mass() const {
  double mass = 0.0;
  for (double m : system_.masses()) mass += m;
  return mass;
}

std::map<std::string, MacroContact> MacroRun::contacts() const {
  const double m = dem::reference_ball_mass(settings_.mill);
  std::map<std::string, MacroContact> contacts;
  auto describe = [&](const char* label, dem::MaterialId other, double m_eff) {
    const dem::PairParams& p = system_.materials().pair(kMedia, other);
    contacts[label] = {
        .pair = system_.materials().pair_name(kMedia, other),
        .normal_stiffness_n_m = p.normal_stiffness,
        .tangential_stiffness_n_m = p.tangential_stiffness,
        .restitution = system_.materials().interaction(kMedia, other).restitution,
        .friction = p.friction,
        .reference_mass_kg = m_eff,
        .collision_time_s = dem::collision_duration(p.normal_stiffness, m_eff, p.damping_ratio)};
  };
  describe("ball_ball", kMedia, dem::effective_mass(m, m));
  describe("ball_liner", system_.wall(kShellWall).material, m);
  return contacts;
}

MacroPower MacroRun::power(double duration) const {
  const double mass_t = ball_mass() / 1000.0, length = settings_.mill.shell.length;
  const double mean = power_.mean(), torque_arm = power_.torque_arm_mean();
  return {
      .mean_w = mean,
      .std_w = power_.standard_deviation(),
      .mean_kw = mean / 1000.0,
      .std_kw = power_.standard_deviation() / 1000.0,
      .kw_per_m = mean / 1000.0 / length,
      .kw_per_t_balls = mean / 1000.0 / mass_t,
      .torque_arm_kw = torque_arm / 1000.0,
      .torque_arm_relative_difference = mean != 0.0 ? (torque_arm - mean) / mean : 0.0,
      .dissipation_kw = (system_.energy().dissipated - dissipated_at_start_) / duration / 1000.0,
      .block_s = schedule_.block_steps * schedule_.dt};
}

MacroCorrelations MacroRun::correlations(double kw_per_t) const {
  const auto& mill = settings_.mill;
  const double bond = bond_kw_per_tonne(2 * mill.shell.radius, mill.fill, mill.speed_fraction);
  const double hogg =
      hogg_fuerstenau_kw_per_tonne(2 * mill.shell.radius, mill.fill, mill.speed_fraction);
  return {.bond_kw_per_t = bond,
          .hogg_fuerstenau_kw_per_t = hogg,
          .hogg_fuerstenau_repose_deg = 35.0,
          .ratio_to_bond = kw_per_t / bond,
          .ratio_to_hogg_fuerstenau = kw_per_t / hogg};
}

MacroCharge MacroRun::charge() const {
  const auto angles = charge_.angles();
  return {.toe_angle_deg = angles ? std::optional(angles->toe_deg) : std::nullopt,
          .shoulder_angle_deg = angles ? std::optional(angles->shoulder_deg) : std::nullopt,
          .contact_angle_bin_deg = 360.0 / ChargeShape::kBins,
          .contact_angle_counts = {charge_.counts().begin(), charge_.counts().end()}};
}

// The frame means (method/macro_measure.hpp) from the flow segments written so far.
MacroFrameMeans MacroRun::frame_means() const {
  FrameMeans means(settings_.mill.shell, system_.masses(), 0.5 * smallest_diameter(settings_.mill));
  for (std::uint64_t k = 0; k < segments_; ++k) {
    for (const dem::FlowFrame& frame : dem::read_flow_segment(dir_ / segment_name(k)))
      means.add_frame(frame);
  }
  return means.means(schedule_.omega);
}

MacroResult MacroRun::result() const {
  const auto& mill = settings_.mill;
  const double duration = system_.time() - measure_start_s_;
  std::vector<std::string> categories;
  for (std::uint32_t c = 0; c < system_.category_count(); ++c)
    categories.push_back(system_.category_name(c));
  MacroResult result{
      .n_balls = system_.size(),
      .ball_mass_kg = ball_mass(),
      .media_diameter_m = dem::mean_ball_diameter(mill),
      .dt_s = schedule_.dt,
      .collision_time_s = system_.min_collision_duration(),
      .critical_speed_rad_s = schedule_.omega_c,
      .angular_velocity_rad_s = schedule_.omega,
      .speed_fraction = mill.speed_fraction,
      .fill = mill.fill,
      .gravity_m_s2 = mill.gravity,
      .mill = {.radius_m = mill.shell.radius,
               .length_m = mill.shell.length,
               .axial_ends = mill.shell.end_walls ? "walls" : "periodic",
               .lifter_count = mill.shell.lifter_count},
      .contacts = contacts(),
      .measure_start_s = measure_start_s_,
      .measure_end_s = system_.time(),
      .measure_revolutions = schedule_.revolutions(schedule_.measure_end - schedule_.warm_end),
      .sample_interval_s = schedule_.sample_steps * schedule_.dt,
      .frame_count = frames_,
      .segment_count = segments_,
      .categories = categories,
      .power = power(duration),
      .correlations = {},
      .charge = charge(),
      .frame_means = frame_means(),
      .spectrum_bin_edges_j = collisions_.bin_edges(),
      .collisions = collisions_.collisions(duration, system_)};
  result.correlations = correlations(result.power.kw_per_t_balls);
  return result;
}

void MacroRun::write_power_csv(const fs::path& path) const {
  std::string text = "time_s,power_w,torque_arm_power_w\n";
  for (std::size_t k = 0; k < power_.times().size(); ++k) {
    text += fmt::format("{},{},{}\n", power_.times()[k], power_.powers()[k],
                        power_.torque_arm_powers()[k]);
  }
  util::write_file_durably(path, text);
}

double bond_kw_per_tonne(double diameter, double fill, double speed_fraction) {
  return 4.879 * std::pow(diameter, 0.3) * (3.2 - 3.0 * fill) * speed_fraction *
         (1.0 - 0.1 / std::pow(2.0, 9.0 - 10.0 * speed_fraction));
}

double hogg_fuerstenau_kw_per_tonne(double diameter, double fill, double speed_fraction,
                                    double repose_deg) {
  return 17.06 / (std::numbers::pi / 4.0) * speed_fraction * std::sqrt(diameter) *
         (1.0 - 1.065 * fill) * std::sin(repose_deg * std::numbers::pi / 180.0);
}

}  // namespace millflow::method
