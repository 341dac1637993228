#pragma once
// The microscale Couette shear cell of the multiscale method (step 3; the rules of its results:
// docs/shear_cells.md): media balls and fine powder sheared at a site's shear rate under the site's
// normal stress.
//
// Geometry (x flow, y gradient, z spanwise; periodic in x and z):
//  - RoughWalls: two layers of media-sized balls glued to the walls (two kinematic groups) at the
//    bottom (y = 0, moving at -U/2 along x) and at the top (y = H, moving at +U/2 along x). The
//    layer is a square lattice of spacing <= 0.7 d, so neighbouring wall balls overlap and leave
//    no hole that powder could leak through, while the surface stays bumpy on the media scale.
//    The top layer is stress-controlled along y (control law below), so the cell finds its own
//    gap and solid fraction. The wall balls are a material of their own ("<media>_wall", the
//    media's density and contact parameters) so their contacts are counted as "wall".
//  - LeesEdwards: periodic in all three axes, Lees-Edwards images along y moving at
//    gdot * L_y along x: no walls, so no slip and no wall layers; the bulk shears at gdot. A
//    barostat (below) imposes the normal stress along y, so the cell finds its own height.
//
// Contents: N_m = phi_m A H / (pi d^3 / 6) media balls (A = L_x L_z, H = size_diameters.y d) at
// random non-overlapping positions, then powder filling a fraction U (powder_load) of the media
// bed's voids, the powder bed itself at solid fraction powder_bed_solid_fraction:
//   powder solid volume = U (1 - phi_m) A H phi_powder_bed,
// inserted by random sequential addition checked against two cell grids (media and powder).
// The particles are first placed in a taller, looser cell (solid fraction kPlacementSolidFraction)
// that the servo or the barostat compresses; with Lees-Edwards the media take a random subset of
// the sites of an FCC lattice that fits that box.
//
// Stress control (dem/stress_control.hpp): one interface, the rough walls' servo or the
// Lees-Edwards barostat. Every steps_per_collision steps (one control interval) the boundary
// answers the mean normal stress of the interval. Wave crossing time of the gap
// t_wave = (H / d) t_c,media; relaxation time tau = max(t_wave, 0.1 / gdot) / g with the gain g;
// speed limit v_max = g d / t_wave; mobility M = H / (K p A tau). Compaction closes the loose fill
// at v_max until an interval's mean reaches half the target. The warm-up then ends on the
// stationarity test of ShearCellProtocol (docs/shear_cells.md).
//
// Shear rate. Rough walls slip, so the bulk shear rate is measured: a least-squares line through
// (y, v_x) of all free particles (mass-weighted) whose centres lie in the middle half of the gap,
// over all samples of a window. warm_up() adjusts the wall speed between windows by the
// wall-speed controller (dem/wall_speed_controller.hpp), which steps only on a steady estimate
// of the bulk fraction (bulk over nominal rate) and learns how the bulk rate answers the wall
// speed from its steady points (secant, regula falsi), so the bulk approaches the target rate. The
// strain of run_strain() and measure() is target rate x time.
#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "dem/batch_means.hpp"
#include "dem/skin_choice.hpp"
#include "dem/spectrum.hpp"
#include "dem/stationarity.hpp"
#include "dem/stress_control.hpp"
#include "dem/system.hpp"
#include "dem/wall_speed_controller.hpp"

namespace millflow::dem {

// The overlap a cell allows, as a fraction of the smaller diameter of each contact: the stiffness
// policy (dem/stiffness_policy.hpp) derives k_n from the mean, and a cell whose measured 95th
// percentile exceeds p95_fraction is flagged (ShearCellMeasurements::overlap_ok).
struct OverlapBound {
  double mean_fraction = 0.01;
  double p95_fraction = 0.03;
  // A floor on the media-media pair's k_n / (sigma_n d_m), the balls' rigidity (0: none); the
  // stiffness policy's rigidity bound.
  double media_rigidity = 0.0;
};

struct ShearCellSetup {
  double media_diameter = 0.01;  // m
  Material media{"steel", 7800.0};
  Material powder{"powder", 3000.0};
  InteractionSpec media_media, media_powder, powder_powder;
  double powder_diameter_ratio = 0.2;  // powder / media diameter
  double powder_load = 0.0;  // U: fraction of the media bed's voids filled with powder bed
  double powder_bed_solid_fraction = 0.6;  // solid fraction of the powder bed filling the voids
  Vec3 size_diameters{6, 8, 6};  // cell size in media diameters: x flow, y gradient, z spanwise
  enum class Boundary { RoughWalls, LeesEdwards } boundary = Boundary::RoughWalls;
  double shear_rate = 10.0;    // target BULK shear rate, 1/s
  double normal_stress = 1e4;  // Pa, imposed along y (RoughWalls)
  bool gravity = false;        // 9.81 m/s^2 along -y when on
  double servo_gain = 0.5;     // g of the control law above, in (0, 1]
  std::uint64_t seed = 1;
  double media_solid_fraction = 0.55;  // sets the number of media balls
  int steps_per_collision = 20;        // dt = shortest contact duration / this
  OverlapBound overlap_bound;
  // Neighbour-list skin / smallest particle diameter (the campaign's /dem/neighbor_skin_fraction);
  // empty ("auto"): compaction runs at kDefaultSkinFraction, and the cell then keeps the
  // cheapest of kSkinFractionCandidates by trial (dem/skin_choice.hpp). Costs only: a resumed
  // cell keeps its checkpoint's skin, and it is no part of the run's identity.
  std::optional<double> neighbor_skin_fraction = kDefaultSkinFraction;
};

// Checks a setup; throws std::invalid_argument naming the bad value and how to fix it.
void validate(const ShearCellSetup& setup);

// The overall solid fraction a compacted cell reaches at most.
inline constexpr double kCompactedSolidFraction = 0.64;

// The particles a cell of this setup is built with (ShearCell's constructor places exactly
// these), the height of its loose fill before compaction and what compaction is expected to
// close of it: what a cost estimate needs before any cell exists.
struct ShearCellPopulation {
  std::size_t media = 0, powder = 0, wall_balls = 0;
  double solid_fraction = 0.0;    // media and powder in the nominal gap
  double placement_height = 0.0;  // m
  // From the placement height down to the nominal height, or to the height that holds all solid
  // at kCompactedSolidFraction where that is larger, m. Compaction closes it at the control's
  // speed limit (measured: the cement campaign's cells compacted in 0.87-1.08 times the steps
  // this gives, docs/shear_cells.md).
  double compaction_distance = 0.0;
};
ShearCellPopulation shear_cell_population(const ShearCellSetup& setup);

// The stress control's speed limit, at which it closes the loose fill: servo_gain x d /
// ((H / d) t_c), m/s, t_c the contact duration of two media balls. The cost model prices
// compaction with it before any cell exists.
double boundary_speed_limit(const ShearCellSetup& setup, double media_contact_time);

// Size-scaled stiffness (k_n ~ E d, a model choice): the stiffness of a pair of diameters d_a,
// d_b is k_ref * d_eff / d_ref with d_eff = 2 d_a d_b / (d_a + d_b) the harmonic-mean diameter.
double size_scaled_stiffness(double reference_stiffness, double reference_diameter,
                             double diameter_a, double diameter_b);

// Contact types of the cell. "Wall" types involve a ball glued to a rough wall.
enum class ContactType { MediaMedia, MediaPowder, PowderPowder, WallMedia, WallPowder };
inline constexpr std::size_t kContactTypeCount = 5;
std::string contact_type_name(ContactType type);

// Collisions (finished contacts) of one type in a window, and the spectrum of the energy each
// dissipated (the usual DEM collision energy spectrum), J.
struct CollisionStats {
  double count = 0.0;
  double rate_per_volume = 0.0;  // collisions / (m^3 s)
  LogHistogram dissipated_energy{1e-16, 1.0, 5};
};

// Overlap of the contacts of one type over the measured samples, as a fraction of the smaller
// diameter of each contact: mean, 95th percentile (to the histogram's bin of kOverlapBinWidth)
// and maximum.
struct OverlapStats {
  double contacts = 0.0;  // contact samples
  double mean_fraction = 0.0, p95_fraction = 0.0, max_fraction = 0.0;
};
inline constexpr double kOverlapBinWidth = 5e-4;
inline constexpr std::size_t kOverlapBins = 2000;  // up to an overlap of the whole diameter

// The measured window is cut into blocks of this much strain; the standard errors group the
// blocks into batches (dem/batch_means.hpp).
inline constexpr double kBlockStrain = 0.05;
// The wall-speed controller answers a warm-up window only when its solid fraction is within this
// of the window before: the profile of a bed whose gap still shrinks is not the steady one.
inline constexpr double kCompactedFractionChange = 0.02;

struct ShearCellMeasurements {
  double strain = 0.0;    // target shear rate x duration
  double duration = 0.0;  // s
  std::uint64_t steps = 0;
  // Shear rates, 1/s. Nominal: wall speed difference / gap (RoughWalls) or the LE rate.
  double target_shear_rate = 0.0, bulk_shear_rate = 0.0, nominal_shear_rate = 0.0;
  double wall_speed = 0.0;  // relative speed of the walls (or LE images), m/s
  // Slip of each wall against the bulk profile extended to it: (U - bulk rate x gap) / 2, m/s.
  double wall_slip = 0.0;
  double gap = 0.0;     // mean distance between the wall ball centre planes (L_y for LE), m
  double volume = 0.0;  // mean cell volume A x gap, m^3
  // Stresses (compression positive), Pa.
  double shear_stress = 0.0, normal_stress = 0.0;
  double friction = 0.0;  // mu = shear / normal stress
  // Stress tensor of the cell, compression positive: the virial of the contacts plus the kinetic
  // part of the motion relative to the mean profile, over the cell volume (with walls the wall
  // balls' contacts count, and the volume is A x gap). Order xx, yy, zz, xy, xz, yz (the
  // symmetric part); the shear stress above is -xy in LE.
  std::array<double, 6> stress_tensor{};
  double mean_pressure = 0.0;           // p = trace / 3
  double friction_mean_pressure = 0.0;  // shear stress / p
  // Imposed rate (LE) or the measured bulk rate (walls) x d_media / sqrt(normal stress / rho),
  // and the same with the measured bulk rate.
  double inertial_number = 0.0;
  double inertial_number_measured_rate = 0.0;
  // Solid fractions in the middle half of the gap.
  double media_solid_fraction = 0.0, powder_solid_fraction = 0.0;
  // Work put in by the walls (LE: by the sheared images, tau gdot) per volume and time, W/m^3.
  double power_density = 0.0;
  std::array<double, kContactTypeCount> dissipation_density{};  // W/m^3, by ContactType
  double dissipation_density_total = 0.0;
  std::array<CollisionStats, kContactTypeCount> collisions;  // by ContactType
  CollisionStats media_collisions;                           // media-media and wall-media
  CollisionStats powder_collisions;                          // every collision involving powder
  // Energy balance over the window: work in = change of (kinetic + elastic) + dissipated, J.
  // work_in includes stress_control_work, what the LE barostat's stretches put in (0 with walls,
  // whose servo work is part of the walls' work).
  double work_in = 0.0, kinetic_change = 0.0, elastic_change = 0.0, dissipated = 0.0;
  double stress_control_work = 0.0;
  // |work - accounted| / work. What remains is each dashpot's dissipation, the O(dt^2) estimate
  // C v^2 dt (over-counts, ~1% at 20 steps per collision, four-fold less per doubling); the
  // tangential springs follow the contact points' displacements and add no error of that order.
  // (The tangential spring a contact holds when a barostat stretch pulls it apart is counted as
  // dissipated, dem/system.hpp.) campaigns/README.md gives what it is in quick.json's cells;
  // DissipationAccounting and ShearCellPhysics test it.
  double energy_balance_error = 0.0;
  // Steady state: shear stress means over the two halves of the window.
  double shear_stress_first_half = 0.0, shear_stress_second_half = 0.0;
  double steady_state_deviation = 0.0;  // |first - second| / mean of both
  // Whether the warm-up ended on the stationarity test (ShearCellRun; see there) and the strain
  // since the start (compaction included) at which it did.
  bool stationary = false;
  double stationary_strain = 0.0;
  // deviation <= the tolerance asked for and, in a ShearCellRun, stationary.
  bool steady = false;
  // Overlaps by ContactType, and whether every type's p95 is within the setup's bound.
  std::array<OverlapStats, kContactTypeCount> overlaps;
  bool overlap_ok = true;
  // Standard errors of the window's means (batch means); dissipation by ContactType.
  MeanWithError friction_error, friction_mean_pressure_error, shear_stress_error,
      normal_stress_error, power_density_error, powder_dissipation_error, dissipation_total_error;
  std::array<double, kContactTypeCount> dissipation_standard_error{};
  std::size_t blocks = 0, batch_blocks = 0;
  // Whether the relative standard errors of friction and powder dissipation reached the target.
  bool converged = false;
  double wall_seconds = 0.0;  // wall-clock time of the window
  double particle_steps_per_second = 0.0;
};

struct MeasureOptions {
  int samples = 200;               // velocity-profile / solid-fraction samples in the window
  double steady_tolerance = 0.15;  // on steady_state_deviation
  bool record_collisions = true;
  // Convergence: after the strain asked for, go on block by block until the relative standard
  // errors of friction and of the powder dissipation rate (when there is powder) are at most
  // standard_error_target, or max_strain is reached (0: stop at the strain asked for).
  double standard_error_target = 0.03;
  double max_strain = 0.0;
};

class ShearCellRun;

// A stiffened Lees-Edwards cell brought back to its target normal stress by stretching it along y
// (ShearCell::relieve_normal_stress). Each control interval (steps_per_collision steps) answers
// the interval's mean p_yy; while it is off the target by more than `tolerance`, the box is
// stretched by
//   e = clamp(gain x (1 - target / p_yy) x f, +-max_strain_per_interval),
// f the mean overlap of the contacts in force as a fraction of their centre distance (the
// stretch that would take the overlaps' excess out if every contact lay along y; a bed answers
// a y-stretch with some of it only, and the intervals after take the rest). It ends after
// settled_intervals intervals in a row within the tolerance, or at max_steps. With hold_steps,
// once an interval is within the tolerance the relief goes on for at least hold_steps more steps
// and stretches by the law every interval, within the tolerance too, so that it follows a bed
// that is still relaxing (the real contacts' network re-forms under shear for strains after a
// stiffening; the barostat, with its time constant of 0.2 strain here, lags it and overshoots).
struct StressRelief {
  double tolerance = 0.05;
  double gain = 1.0;
  double max_strain_per_interval = 1e-3;
  int settled_intervals = 5;
  std::uint64_t max_steps = 20000;
  std::uint64_t hold_steps = 0;
};
struct StressReliefResult {
  bool relieved = false;  // ended on the settled intervals, not on max_steps
  std::uint64_t steps = 0;
  int intervals = 0;
  double strain = 0.0;         // ln(L_y after / L_y before)
  double first_stress = 0.0;   // the first interval's mean p_yy (before any stretch), Pa
  double normal_stress = 0.0;  // the last interval's mean p_yy, Pa
};

// One block of the measured window (kBlockStrain): its stress sums and the energy it took in
// and dissipated.
struct MeasuredBlock {
  double shear_sum = 0.0, normal_sum = 0.0, gap_sum = 0.0, stress_samples = 0.0;
  double pressure_sum = 0.0, pressure_samples = 0.0;
  double shear_work = 0.0, duration = 0.0;             // J, s
  std::array<double, kContactTypeCount> dissipated{};  // J, by ContactType
  void write(BinaryWriter& out) const;
  void read(BinaryReader& in);
};

class ShearCell {
 public:
  explicit ShearCell(const ShearCellSetup& setup);

  System& system() { return system_; }
  const System& system() const { return system_; }
  const ShearCellSetup& setup() const { return setup_; }

  std::size_t media_count() const { return media_count_; }
  std::size_t powder_count() const { return powder_count_; }
  std::size_t wall_ball_count() const { return wall_ball_count_; }
  // The neighbour skin the cell steps at now, as a fraction of its smallest diameter (an "auto"
  // cell's choice once its first warm-up window ended).
  double neighbor_skin_fraction() const;

  // Closes the loose placement gap until the bed carries half the normal stress (CompactionEnd),
  // in whole control intervals. It stops after the interval that reaches `max_steps` more steps
  // and goes on at the next call, so that a checkpoint can come between (the same bits as a
  // compaction that never stopped); true once compacted. The first run below compacts whole if
  // it was not done.
  bool compact(std::uint64_t max_steps = std::numeric_limits<std::uint64_t>::max());
  bool compacted() const { return compaction_ == Compaction::Done; }
  // The steps compaction is expected to take: the population's compaction distance at the
  // control's speed limit. And the most it runs: it stops at a time limit of 4 placement gaps at
  // that speed even if the bed never carried half the target.
  std::uint64_t expected_compaction_steps() const;
  std::uint64_t compaction_step_cap() const;
  // Whether compaction ended with the bed carrying half the target (not at its time limit).
  bool compacted_under_load() const { return compaction_end_.compacted(); }
  // Runs `strain` of shear (target rate x time) with no measurement and no control.
  void run_strain(double strain);
  // Steps the system after compact(); with Lees-Edwards also integrates the boundary's work and
  // runs the barostat (step_controlled, which compact() itself uses).
  void advance(std::size_t steps);
  // From here on at dt / factor, its stress control's interval `factor` times as many steps (the
  // same time): the integrator's share of a result (bench_cell_physics --lammps_dt_refine).
  // Throws std::invalid_argument unless factor >= 1.
  void refine_time_step(int factor);
  // Runs `strain` of shear in `windows` equal windows, adjusting the wall speed after each so the
  // bulk shear rate approaches the target (RoughWalls; LE has no slip and only runs). An "auto"
  // skin (ShearCellSetup::neighbor_skin_fraction empty) is chosen by trial at the end of the
  // first window: right after compaction the bed still rearranges and rebuilds the list several
  // times as often as the sheared bed, which made the trials pick too wide a skin.
  void warm_up(double strain, int windows = 4);
  // Runs `strain` of shear and measures over it.
  ShearCellMeasurements measure(double strain, const MeasureOptions& options = {});

  // Relative speed of the walls (or of the LE images), m/s, and the distance between the wall
  // ball centre planes (L_y for LE), m.
  double wall_speed() const { return wall_speed_; }
  double gap() const;
  double wall_area() const;
  // The stress control and its derived constants: the servo's mobility (RoughWalls) and the
  // speed limit of the top wall or of the LE box height.
  const StressControl& stress_control() const { return *control_; }
  double servo_mobility() const { return control_->settings().mobility; }
  double servo_max_speed() const { return control_->settings().max_speed; }

  ContactType contact_type(std::uint32_t category) const;
  // Shear and normal stress, Pa, now: from the wall loads (RoughWalls) or the virial (LE).
  double shear_stress_now() const;
  double normal_stress_now() const;

  // Preparing a state (Lees-Edwards only): runs the cell with its barostat held (it neither
  // samples nor answers, so its running mean stays as it was; its integral term, wound up by the
  // softer bed, is reset to 0 at the end with any strain of its last answer not yet stretched,
  // the stress being on target) and stretches
  // the box along y between control intervals by the law of StressRelief until the normal stress
  // is on target. For a cell whose contacts were just made stiffer (ShearCellRun::
  // with_interactions): the softer contacts' overlaps would hold many times the target, and the
  // barostat, limited to 5% per relaxation time and with an integral term that winds up, takes
  // strains to let them out and overshoots. A stretch keeps each particle's velocity relative to
  // the imposed profile and the images' shear rate, as the barostat's does; the LE boundary's
  // work is integrated over the steps, but the springs' energy a relief stretch lets out is in
  // no ledger, so a measured window that spans a relief does not balance. Throws
  // std::logic_error with rough walls or before compaction.
  StressReliefResult relieve_normal_stress(const StressRelief& relief = {});

 private:
  friend class ShearCellRun;
  // Accumulated least-squares sums of the velocity profile.
  struct Profile {
    double w = 0.0, wy = 0.0, wyy = 0.0, wv = 0.0, wyv = 0.0;
    double media_volume = 0.0, powder_volume = 0.0, slab_volume = 0.0;
    void write(BinaryWriter& out) const;
    void read(BinaryReader& in);
  };
  // One warm-up window in progress: `steps` in all, the profile and the stresses sampled every
  // `every` steps over the second half (after `half`).
  struct WarmUpWindow {
    std::uint64_t steps = 0, half = 0, every = 1, done = 0;
    Profile profile;
    double shear_sum = 0.0, normal_sum = 0.0, samples = 0.0;
    bool finished() const { return done == steps; }
    void write(BinaryWriter& out) const;
    void read(BinaryReader& in);
  };
  // Overlaps of one contact type: a histogram of the fraction of the smaller diameter.
  struct OverlapHistogram {
    std::vector<double> counts;  // kOverlapBins bins of kOverlapBinWidth, the last open
    double sum = 0.0, max = 0.0;
    void add(double fraction);
    OverlapStats stats() const;
    void write(BinaryWriter& out) const;
    void read(BinaryReader& in);
  };
  // A measurement in progress: where its window started and what it has summed so far. It runs
  // at least min_steps and at most `steps`, and stops at a block's end once converged.
  struct Measurement {
    MeasureOptions options;
    std::uint64_t steps = 0, min_steps = 0, block_steps = 1, every = 1, stress_every = 1, done = 0;
    double work0 = 0.0, shear_work0 = 0.0, motion0 = 0.0;
    EnergyBudget budget0;
    std::vector<Dissipation> dissipation0;
    Profile profile;
    std::array<double, 6> tensor_sum{};
    double tensor_samples = 0.0;
    std::vector<MeasuredBlock> blocks;
    MeasuredBlock current;  // the block in progress
    double block_shear_work0 = 0.0;
    std::vector<double> block_dissipation0;  // by category, at the block's start, J
    std::array<OverlapHistogram, kContactTypeCount> overlaps;
    std::array<CollisionStats, kContactTypeCount> collisions;
    double wall_seconds = 0.0;
    bool converged = false;
    bool finished() const { return done == steps || converged; }
    // The options are the protocol's and are not written.
    void write(BinaryWriter& out) const;
    void read(BinaryReader& in);
  };

  // Continues a cell from its checkpointed system (ShearCellRun::resume).
  ShearCell(const ShearCellSetup& setup, System system);
  WarmUpWindow start_window(double strain) const;
  void advance_window(WarmUpWindow& window, std::uint64_t max_steps);
  // Adjusts the wall speed from a finished window's profile (RoughWalls, the wall-speed
  // controller) once the bed has compacted (its solid fraction within kCompactedFractionChange
  // of `previous`, the window before; nullptr for the first); returns the window's means. At the
  // end of the first (`index` 0) an "auto" skin is chosen.
  WindowMeans finish_window(const WarmUpWindow& window, int index, const WindowMeans* previous);
  // The stationarity test (dem/stationarity.hpp) of the last warm-up windows; with walls the
  // wall-speed controller must have settled too.
  bool stationary(std::span<const WindowMeans> windows) const;
  Measurement start_measurement(double strain, const MeasureOptions& options);
  void advance_measurement(Measurement& measurement, std::uint64_t max_steps);
  // Hands the measurement the collisions buffered while it records outside advance_measurement
  // (a relief's steps): before a checkpoint, which holds the tally and no events, and at the
  // window's end.
  void tally_collisions(Measurement& measurement);
  // Profile, stress tensor and overlaps at a sample; the block bookkeeping at a block's end.
  void sample_measurement(Measurement& measurement);
  void close_block(Measurement& measurement);
  // Sets the wall speed from the measured window's bulk rate so far (RoughWalls; the catch-up
  // law of dem/wall_speed_controller.hpp).
  void control_measured_wall_speed(const Measurement& measurement);
  void start_block(Measurement& measurement);
  // Standard errors from the finished blocks; true when they meet the target.
  bool errors_within_target(const Measurement& measurement) const;
  void fill_standard_errors(const Measurement& in, ShearCellMeasurements& m) const;
  // Stress tensor now (compression positive, xx yy zz xy xz yz), Pa.
  std::array<double, 6> stress_tensor_now() const;
  void sample_overlaps(Measurement& measurement) const;
  ShearCellMeasurements finish_measurement(Measurement& measurement);
  void write_state(BinaryWriter& out) const;
  void read_state(BinaryReader& in);

  bool walls() const { return setup_.boundary == ShearCellSetup::Boundary::RoughWalls; }
  void place_wall_layer(GroupId group, double y);
  void place_media_dilute(double height);
  void place_media_lattice();
  void place_powder(double y_lo, double y_hi);
  // The servo (RoughWalls) or the barostat (LeesEdwards) with its constants.
  std::unique_ptr<StressControl> make_stress_control() const;
  void set_wall_speed(double speed);
  // Sets the cheapest skin of kSkinFractionCandidates by trial (dem/skin_choice.hpp) when the
  // setup leaves it to the cell ("auto"); a fixed skin stays. finish_window calls it at the end of
  // the first window, ShearCellRun before a measurement with no warm-up.
  void choose_neighbor_skin();
  std::size_t steps_for_strain(double strain) const;
  // Simulated time after which compaction stops even if the bed never carried half the target.
  double compaction_time_limit() const;
  void step_controlled(std::size_t steps);
  // `steps` steps with the LE boundary's work integrated over each (trapezoidal rule); after each
  // step `after_step()` runs and returns true when it stretched the box (step_controlled: the
  // stress control; relieve_normal_stress: a held barostat's stress sample). Defined in
  // dem/shear_cell_stress_control.cpp, its only user.
  template <class AfterStep>
  void step_integrating_work(std::size_t steps, AfterStep&& after_step);
  // Work put in so far (walls or LE boundary), J.
  double work_in() const;
  // Work put in by shearing (walls or LE images) so far, J.
  double shear_work() const;
  // Kinetic (+ gravitational) energy of the free particles; with LE the kinetic energy of the
  // motion relative to the imposed profile (lab-frame velocities jump at the LE boundary), J.
  double motion_energy() const;
  void sample_profile(Profile& profile) const;
  static double bulk_shear_rate(const Profile& profile);
  // Power the LE boundary puts in now: V gdot tau, W.
  double lees_edwards_power() const;
  // Kinetic energy of the free particles relative to the imposed linear profile (LE), J.
  double peculiar_kinetic_energy() const;

  ShearCellSetup setup_;
  System system_;
  MaterialId media_ = 0, powder_ = 1, wall_material_ = 2;
  GroupId bottom_ = 0, top_ = 0;
  std::size_t media_count_ = 0, powder_count_ = 0, wall_ball_count_ = 0;
  double wall_speed_ = 0.0;
  StressControlPtr control_;
  WallSpeedController speed_controller_{setup_.shear_rate};  // RoughWalls
  double le_work_ = 0.0;  // work put in through the LE boundary so far, J
  // Where compaction stands (the values are the checkpoint's byte), and its end's count of
  // loaded intervals while it runs.
  enum class Compaction : std::uint8_t { NotStarted = 0, Done = 1, Running = 2 };
  Compaction compaction_ = Compaction::NotStarted;
  CompactionEnd compaction_end_{setup_.normal_stress};
};

// What a cell run does: compaction, warm-up in windows of warmup_strain / warmup_windows until
// the cell is stationary, then one measured window (measure_strain, and on to convergence up to
// measure.max_strain).
//
// Stationarity. After at least warmup_windows windows, the warm-up ends at the first window that
// passes the statistical test of dem/stationarity.hpp against the window before it (each
// window's samples over its second half); with walls the wall-speed controller must have settled
// too (dem/wall_speed_controller.hpp). The strain since the start at that window's end is the
// stationary strain. A cell that has not passed by max_warmup_strain measures anyway and is
// reported not stationary (steady = false); with warmup_strain 0 there is no warm-up and no
// stationarity.
struct ShearCellProtocol {
  double warmup_strain = 2.0;
  int warmup_windows = 4;
  double max_warmup_strain = 6.0;  // >= warmup_strain
  double measure_strain = 4.0;
  MeasureOptions measure;
  // The version of the code whose physics runs the cell (the shear_cell task kind's,
  // tasks/shear_cell.hpp; empty where no kind runs it). A checkpoint written under another is not
  // continued: it would finish under other physics than it started with.
  std::string code_version = {};
};

// A cell run that can stop between any two steps, or between two control intervals while it
// compacts, and continue from a checkpoint with the same bits as a run that never stopped.
// advance() in chunks of any size gives the same bits too.
//
// Checkpoint file: the checksummed container of dem/binary_io.hpp, magic "MFSHRCKP", payload
// version kShearCellCheckpointVersion. Payload (version 9; version 8 ran compaction whole, so it
// lacked the stress control's speed-limit flag and compaction's count of loaded intervals, and
// held compaction's state as 0 or 1; version 7 lacked the code version, so
// a cell could be continued by a build of other physics; version 7 had the layout of version 6: a
// version-6 file was written by the integrator whose tangential spring followed the end-of-step
// velocity, and continued now it would finish under another contact law, so it is refused and the
// cell starts again; version 5 lacked the barostat's strain
// still to stretch and its parts left; version 4 lacked the wall-speed
// controller's measured-window duration and travel and the servo's integral term; version 3 held
// the earlier filtered wall-speed controller's two sums, window count and settled flag, and a
// rough-wall window's stress sums over its profile samples only; version 2 only the previous
// warm-up window's means, no wall-speed controller, and the barostat's state for both boundaries),
// in order:
//   identity: string, the setup (overlap bound included) and protocol (warm-up cap, convergence
//             target and cap included) encoded field by field (resume() refuses a file whose
//             identity differs from the cell it is asked to continue)
//   code version: string, ShearCellProtocol::code_version of the run that wrote it (resume()
//             refuses another, naming both)
//   system: uint32 version of the DEM checkpoint payload, then that payload as a string
//           (dem/checkpoint.hpp)
//   cell: media, powder and wall ball counts (uint64), wall speed, LE boundary work; the stress
//         control (StressControl::write: stress sum and sample count since the last control
//         interval, the stress that interval answered and its running mean over the relaxation
//         time, whether it closes at the speed limit (uint8); the barostat then its stretches'
//         work, its integral term, the strain of its last answer still to stretch (double) and the
//         parts left to stretch it in (uint64), the servo its integral term); the wall-speed
//         controller (WallSpeedController::write: the bulk fractions of the windows at the current
//         speed (uint64 count, doubles), the last steady estimate (double), settled (uint8), its
//         steady points that stepped: the last, the latest below the target and the latest above
//         it, each speed, bulk fraction and its standard error (3 doubles, speed 0 for none), the
//         measured window's duration up to its last control point and the walls' travel over it (2
//         doubles)); compaction (uint8: 0 not started, 1 done, 2 under way), its loaded control
//         intervals in a row (int32, CompactionEnd)
//   run: phase (uint8: 0 compacting, 1 warm-up, 2 measuring), warm-up window index
//        (int32); the window in progress (uint64 steps, half, every, done; profile: 8 doubles;
//        shear stress sum, normal stress sum (with walls summed every step of the second half,
//        else at the samples), sample count); the finished windows' means (uint64
//        count; each: shear stress, normal stress, solid fraction, bulk shear rate), the
//        stationary strain (double) and stationary (uint8); the measurement (uint64 steps cap,
//        minimum steps, block steps, every, stress-sample interval, done; work, shear work and
//        motion energy at its start, energy budget at its start (kinetic, potential, elastic,
//        dissipated, wall work), dissipation per category at its start (uint64 count; normal,
//        tangential, friction each), profile, stress tensor sums (6) and sample count, the finished
//        blocks (uint64 count; each: shear, normal, gap and stress-sample sums, pressure sum and
//        sample count, shear work, duration, dissipated energy per contact type) and the block in
//        progress, the shear work and the dissipation per category (uint64 count, doubles) at
//        its start, per contact type the overlap histogram (uint64 bin count, 0 or
//        kOverlapBins; the counts, sum, max), per contact type the collision count and
//        dissipated-energy histogram (dem/spectrum.hpp), wall seconds measured so far,
//        converged (uint8))
// The system buffers no collision events while the cell measures: its recording flag is on and
// each finished contact goes to the measurement's tally as it finishes (those of a relief's steps
// are buffered, and tallied before a save).
inline constexpr std::uint32_t kShearCellCheckpointVersion = 9;

class ShearCellRun {
 public:
  ShearCellRun(const ShearCellSetup& setup, const ShearCellProtocol& protocol);
  // Continues the run saved at `path` for this setup and protocol. Throws CorruptData for a
  // missing, truncated, altered or newer file, and for one saved by another cell or protocol.
  static ShearCellRun resume(const ShearCellSetup& setup, const ShearCellProtocol& protocol,
                             const std::filesystem::path& path);

  // This run continued with `setup`'s contacts (a setup that differs from the run's own in its
  // interactions only, e.g. stiffer ones): the same particles, motion, contacts and run state,
  // every contact's dashpot and the time step worked out again from the new contacts, exactly as
  // a run saved and resumed with that setup would be. Throws std::invalid_argument for a setup
  // that differs in anything else, std::logic_error once done().
  ShearCellRun with_interactions(const ShearCellSetup& setup);

  // Runs at most `max_steps` more steps (compaction up to one control interval more: it stops
  // only between two); true when done.
  bool advance(std::uint64_t max_steps);
  bool done() const { return phase_ == Phase::Done; }
  // Fraction of the steps done: of compaction's expected steps, of the warm-up's and the
  // measurement's caps (max_warmup_strain, the measurement's max_strain); and what the run is
  // doing.
  double progress() const;
  std::string phase_name() const;
  // Writes atomically (temp file + rename). Throws std::logic_error once done().
  void save(const std::filesystem::path& path);

  ShearCell& cell() { return cell_; }
  const ShearCell& cell() const { return cell_; }
  // Throws std::logic_error until done().
  const ShearCellMeasurements& measurements() const;

 private:
  enum class Phase : std::uint8_t { Compacting, WarmUp, Measuring, Done };
  ShearCellRun(ShearCell cell, const ShearCellProtocol& protocol);
  // The checkpoint's payload (save() writes it into the file's container), and the run it
  // describes for `setup` (its identity must be that setup's), continued with `continue_with`'s
  // contacts when given (with_interactions); `source` names it in errors.
  std::string state();
  static ShearCellRun from_state(const ShearCellSetup& setup, const ShearCellProtocol& protocol,
                                 std::string_view state, const std::string& source,
                                 const ShearCellSetup* continue_with);
  // Starts what follows a finished piece (no steps are taken).
  void start_next_piece();

  ShearCell cell_;
  ShearCellProtocol protocol_;
  Phase phase_ = Phase::Compacting;
  int window_index_ = 0;
  ShearCell::WarmUpWindow window_;
  ShearCell::Measurement measurement_;
  ShearCellMeasurements result_;
  std::uint64_t window_steps_ = 0, measure_steps_ = 0;
  int max_windows_ = 0;
  std::vector<WindowMeans> windows_;  // the warm-up windows' means so far
  bool stationary_ = false;
  double stationary_strain_ = 0.0;
};

}  // namespace millflow::dem
