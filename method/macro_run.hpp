#pragma once
// One DEM run of the balls in a rotating mill slice (docs/method.md, step 1), with the same
// advance/save/resume interface as dem::ShearCellRun. The `macro` task kind (tasks/macro.hpp)
// turns its parameters into MacroSettings (tasks/macro_setup.hpp) and drives it.
//
// Run: build the charge (dem::build_mill), dt = t_c / dem.steps_per_collision; settle
// for macro.settle_time with the shell at rest; turn it at speed_fraction x critical speed
// (dem::critical_speed with the mass-weighted mean ball diameter) for warmup_revolutions, then
// measure for measure_revolutions, rounded to a whole number of flow-sample intervals. All
// cadences are whole step counts fixed at the start, so that a run continued from a checkpoint
// gives the same bits as one that never stopped.
//
// Result: method::MacroResult (method/macro_result.hpp says what it holds and its JSON).
// Artifacts: power.csv (time_s, power_w, torque_arm_power_w), collision_spectra.csv (per
// energy bin: energy_low_j, energy_high_j and <category>_<impact|dissipated>_energy_count, the
// spectra of the result as a table), flow/segment_NNNN.mfs (flow
// frames every sample interval of the measurement, dem/flow_sample.hpp, 16 frames a segment),
// vtk/particles_NNNN.vtp and vtk/mill_NNNN.vtp (the shell and lifters at the same angle) every
// vtk_interval from the start, and their collections vtk/particles.pvd and vtk/mill.pvd.
//
// Checkpoints: save() writes the DEM state, the measurement accumulators and the frames not yet
// in a segment into the run's directory (committed by renaming state.bin last); resume()
// continues from there with the same bits as a run that never stopped. state.bin (MFMACRO1,
// version 2, a dem/binary_io.hpp container): the step, the measurement's start time and
// dissipation, the frame, segment and pending-frame counts, the VTK frames' times and each
// frame's two files' SHA-256 (hex), the pending collision events, the power, charge and
// collision accumulators. A resume refuses a state whose segments or VTK files are gone or not
// the bytes written (the run then starts again).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dem/flow_sample.hpp"
#include "dem/mill_setup.hpp"
#include "dem/skin_choice.hpp"
#include "dem/system.hpp"
#include "method/macro_measure.hpp"
#include "method/macro_result.hpp"

namespace millflow::method {

struct MacroSettings {
  dem::MillSetup mill;
  int steps_per_collision = 20;
  // Neighbour skin / smallest ball diameter; empty ("auto"): dem::kDefaultSkinFraction until the
  // end of the warm-up, then the cheapest of dem::kSkinFractionCandidates by trial
  // (dem/skin_choice.hpp).
  std::optional<double> skin_fraction = dem::kDefaultSkinFraction;
  double settle_time = 0.5;  // s, shell at rest
  double warmup_revolutions = 2.0;
  double measure_revolutions = 3.0;
  double sample_interval = 0.01;        // s between flow frames
  double vtk_interval = 0.1;            // s between VTK files
  double checkpoint_interval_s = 60.0;  // wall-clock s between the task's checkpoints
};

// What a finished run leaves: the result and its artifacts' names, relative to the run's
// directory.
struct MacroOutcome {
  MacroResult result;
  std::vector<std::string> artifacts;
};

class MacroRun {
 public:
  // Where the run's messages (set-up, the start of the measurement, a resume) go.
  using Log = std::function<void(const std::string&)>;

  // A fresh run writing into `dir`.
  MacroRun(const MacroSettings& settings, const std::filesystem::path& dir, Log log = {});
  // Whether `dir` holds a run saved by save().
  static bool saved_in(const std::filesystem::path& dir);
  // Continues the run saved in `dir`. Throws dem::CorruptData for a missing, truncated or altered
  // checkpoint.
  static MacroRun resume(const MacroSettings& settings, const std::filesystem::path& dir,
                         Log log = {});

  // Runs at most `max_steps` more steps; true when done.
  bool advance(std::uint64_t max_steps);
  bool done() const { return finished_; }
  // Fraction of all steps done, and what the run is doing ("settling 0.20/0.50 s", ...).
  double progress() const;
  std::string phase_name() const;
  // Writes the checkpoint into the run's directory.
  void save();
  // Writes the artifacts and returns the result, keeping the last checkpoint (the task's work
  // directory, removed after its commit, holds it until then). Throws std::logic_error until
  // done().
  MacroOutcome finish();

  const dem::System& system() const { return system_; }

 private:
  struct Schedule {
    double dt = 0.0, omega_c = 0.0, omega = 0.0;
    std::uint64_t settle_end = 0, warm_end = 0, measure_end = 0;
    std::uint64_t sample_steps = 0, frame_count = 0, vtk_steps = 0, block_steps = 0;
    Schedule(const MacroSettings& settings, double time_step);
    double revolutions(std::uint64_t steps) const;
  };

  MacroRun(const MacroSettings& settings, const std::filesystem::path& dir, Log log,
           dem::System system);
  void act(std::uint64_t s);
  void start_measuring();
  void measure_step(std::uint64_t s);
  void capture_frame();
  void write_vtk();
  double mill_angle() const;
  void remove_checkpoints_except(std::uint64_t keep) const;
  void write_state(dem::BinaryWriter& out) const;
  void restore();
  void log_setup() const;
  void log(const std::string& message) const;
  double ball_mass() const;
  std::map<std::string, MacroContact> contacts() const;
  MacroPower power(double duration) const;
  MacroCorrelations correlations(double kw_per_t) const;
  MacroCharge charge() const;
  MacroFrameMeans frame_means() const;
  MacroResult result() const;
  void write_power_csv(const std::filesystem::path& path) const;

  MacroSettings settings_;
  std::filesystem::path dir_;
  Log log_;
  dem::System system_;
  Schedule schedule_;
  bool finished_ = false;

  // Measurement state, saved in checkpoints.
  PowerMeter power_;
  ChargeShape charge_;
  CollisionStats collisions_;
  double measure_start_s_ = 0.0;
  double dissipated_at_start_ = 0.0;
  std::uint64_t frames_ = 0, segments_ = 0;
  std::vector<dem::FlowFrame> pending_frames_;
  std::vector<dem::CollisionEvent> pending_events_;
  std::vector<double> vtk_times_;
  std::vector<std::string> vtk_digests_;  // SHA-256 of each frame's particles and mill files
};

// Specific power of ball mills from the classical correlations, kW per tonne of balls, for mill
// diameter D (m), fill J and speed fraction phi_c:
//   Bond: 4.879 D^0.3 (3.2 - 3 J) phi_c (1 - 0.1 / 2^(9 - 10 phi_c));
//   Hogg-Fuerstenau: P = 17.06 phi_c rho_c D^2.5 L J (1 - 1.065 J) sin(alpha) kW over the charge
//   mass rho_c J pi D^2 / 4 L t, i.e. 21.72 phi_c D^0.5 (1 - 1.065 J) sin(alpha).
double bond_kw_per_tonne(double diameter, double fill, double speed_fraction);
double hogg_fuerstenau_kw_per_tonne(double diameter, double fill, double speed_fraction,
                                    double repose_deg = 35.0);

}  // namespace millflow::method
