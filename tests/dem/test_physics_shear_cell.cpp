// Shear cells in motion: the servo holds the normal stress, the energy balance closes, effective
// friction rises with the inertial number in the range of frictional spheres, and dissipation
// splits by contact type.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "dem/shear_cell.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

using testing::small_shear_cell;

std::size_t index(ContactType type) {
  return static_cast<std::size_t>(type);
}

// Jop, Forterre & Pouliquen (2006), glass beads: the reference, not a fit.
double jop_forterre_pouliquen(double inertial_number) {
  return 0.38 + (0.64 - 0.38) / (0.279 / inertial_number + 1.0);
}

class ShearCellPhysics : public ::testing::Test {
 protected:
  void SetUp() override { spdlog::set_level(spdlog::level::warn); }
};

// A Lees-Edwards cell 4 d deep along z: its FCC lattice has its z-planes exactly d apart, and a
// fill moving only in the x-y plane would shear as a stack of 2-D layers with p_zz = 0 for ever.
TEST_F(ShearCellPhysics, LeesEdwardsCellFourDiametersDeepShearsInThreeDimensions) {
  ShearCellSetup setup = small_shear_cell(0.1);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.size_diameters = Vec3(4, 4, 4);
  setup.media_media.normal_stiffness = 1e4 * setup.normal_stress * setup.media_diameter;
  ShearCell cell(setup);
  cell.compact();
  cell.warm_up(2.0, 2);
  const ShearCellMeasurements m = cell.measure(1.0);
  const double p_yy = m.stress_tensor[1], p_zz = m.stress_tensor[2];
  ASSERT_GT(p_yy, 0.0);
  // Sheared spheres carry comparable normal stresses on every axis (p_zz / p_yy ~ 0.7-1).
  EXPECT_GT(p_zz / p_yy, 0.4) << "p_zz = " << p_zz << " Pa, p_yy = " << p_yy << " Pa";
}

TEST_F(ShearCellPhysics, ServoHoldsTheNormalStressAndTheEnergyBalanceCloses) {
  ShearCellSetup setup = small_shear_cell(0.1);
  // The integrator's energy error is first order in dt here (1.0%, 0.55%, 0.27% at 20, 40, 80
  // steps per contact): 40 keeps it well inside 1%.
  setup.steps_per_collision = 40;
  ShearCell cell(setup);
  cell.warm_up(2.0, 2);
  // The servo acts once per control interval: the top wall keeps its y velocity through the
  // interval and at its end takes v = clamp(M (p_target / p_bed) (F_mean - F_target) + b H / tau,
  // +-v_max) from the interval's mean load, p_bed = min(p_target, running mean of the loads over
  // tau), b the integral term after the interval (H / tau = M K p_target A).
  System& system = cell.system();
  const StressControl& control = cell.stress_control();
  const std::uint64_t interval = control.settings().interval_steps;
  ASSERT_GT(interval, 1u);
  // run_strain runs ceil(strain / (rate dt)) steps: half a step less gives exactly n.
  const auto run_steps = [&](std::uint64_t n) {
    cell.run_strain((static_cast<double>(n) - 0.5) * setup.shear_rate * system.time_step());
  };
  if (const std::uint64_t into = system.step_count() % interval; into != 0)
    run_steps(interval - into);
  const double target = setup.normal_stress * cell.wall_area();
  double mean_load = 0.0;
  const int intervals = 40;
  for (int i = 0; i < intervals; ++i) {
    const double speed = system.group(2).velocity.y();
    run_steps(interval - 1);
    EXPECT_EQ(system.group(2).velocity.y(), speed) << "the wall moved off its interval's speed";
    run_steps(1);
    ASSERT_EQ(system.step_count() % interval, 0u);
    const double load = control.last_interval_stress() * cell.wall_area();
    const double bed_pressure = std::min(control.smoothed_stress(), setup.normal_stress);
    ASSERT_GT(bed_pressure, 0.0);
    const double expected = std::clamp(
        cell.servo_mobility() * (setup.normal_stress / bed_pressure) * (load - target) +
            cell.servo_mobility() * kFlowingBedModulus * target * control.integral_term(),
        -cell.servo_max_speed(), cell.servo_max_speed());
    EXPECT_NEAR(system.group(2).velocity.y(), expected, 1e-12 * cell.servo_max_speed())
        << "interval " << i;
    mean_load += load / intervals;
  }
  EXPECT_NEAR(mean_load, target, 0.25 * target) << "wall settled near the target";

  const ShearCellMeasurements m = cell.measure(2.0);
  EXPECT_NEAR(m.normal_stress, setup.normal_stress, 0.25 * setup.normal_stress);
  ASSERT_GT(m.work_in, 0.0);
  EXPECT_LT(m.energy_balance_error, 0.01)
      << "work " << m.work_in << " J, dissipated " << m.dissipated << " J";
  EXPECT_NEAR(m.power_density, m.work_in / (m.volume * m.duration), 1e-9 * m.power_density);
  // Media only: no powder dissipation at all, and no powder collisions.
  EXPECT_EQ(m.dissipation_density[index(ContactType::MediaPowder)], 0.0);
  EXPECT_EQ(m.dissipation_density[index(ContactType::PowderPowder)], 0.0);
  EXPECT_EQ(m.dissipation_density[index(ContactType::WallPowder)], 0.0);
  EXPECT_EQ(m.powder_collisions.count, 0.0);
  EXPECT_GT(m.media_collisions.count, 0.0);
  EXPECT_EQ(m.powder_solid_fraction, 0.0);
  // The walls drive the bulk: its rate is a good part of the nominal one (wall speed over the gap
  // between the wall layers' mean centre planes), and above it by no more than the walls' reach:
  // their balls stand up to 0.4 d proud of that plane (kWallBallJitter), so the planes where the
  // bed moves with a wall can lie that far inside the gap (in this 4 x 6 x 4 cell the bulk ran at
  // 1.03 of the nominal rate with those walls).
  const double reach = 2.0 * 0.4 * setup.media_diameter;
  EXPECT_GT(m.bulk_shear_rate, 0.5 * m.nominal_shear_rate);
  EXPECT_LT(m.bulk_shear_rate, m.nominal_shear_rate * m.gap / (m.gap - reach));
}

// At the campaign's parameters (50 mm steel under 20 kPa, k_n / (p d) = 1.16e4, 10 1/s) a servo
// acting every step on the instantaneous load of ~25 stiff wall contacts was unstable
// (M N k_n dt ~ 4 > 2): the wall chattered at its speed limit and the energy balance was open.
TEST_F(ShearCellPhysics, RoughWallsHoldTheStressOfTheCampaignsStiffBalls) {
  ShearCellSetup s = small_shear_cell(0.1);  // steel 7800 kg/m^3, 4 x 6 x 4 d, media only
  s.media_diameter = 0.05;
  s.normal_stress = 20000.0;
  s.media_media = {.restitution = 0.3,
                   .friction = 0.75,
                   .normal_stiffness = 1.16e4 * s.normal_stress * s.media_diameter};
  s.shear_rate = 10.0;
  // The integrator's energy error falls with dt (see above): 1.40%, 0.43%, 0.17% at 40, 80, 160
  // steps per collision here, the sliding spring reset with its dashpot as LAMMPS and MercuryDPM
  // reset theirs (0.76%, 0.23%, 0.11% with the whole limit force in the spring, as before 5
  // December 2026: the reset's abrupt tangential forces cost the books more per step).
  s.steps_per_collision = 80;
  ShearCell cell(s);
  cell.warm_up(3.0, 3);
  const ShearCellMeasurements m = cell.measure(2.0);
  EXPECT_NEAR(m.normal_stress, s.normal_stress, 0.05 * s.normal_stress);
  ASSERT_GT(m.work_in, 0.0);
  EXPECT_LT(m.energy_balance_error, 0.01)
      << "work " << m.work_in << " J, dissipated " << m.dissipated << " J";
}

TEST_F(ShearCellPhysics, FrictionRisesWithInertialNumberLikeFrictionalSpheres) {
  std::vector<ShearCellMeasurements> runs;
  for (double inertial_number : {0.03, 0.3}) {
    ShearCell cell(small_shear_cell(inertial_number));
    cell.warm_up(2.0, 3);
    runs.push_back(cell.measure(2.0));
    const ShearCellMeasurements& m = runs.back();
    std::printf(
        "I = %.4g (bulk rate %.4g 1/s, nominal %.4g 1/s): mu = %.4g, JFP mu(I) = %.4g, solid "
        "fraction %.3g\n",
        m.inertial_number, m.bulk_shear_rate, m.nominal_shear_rate, m.friction,
        jop_forterre_pouliquen(m.inertial_number), m.media_solid_fraction);
    EXPECT_GT(m.friction, 0.2);
    EXPECT_LT(m.friction, 0.8);
  }
  EXPECT_GT(runs[1].inertial_number, 3.0 * runs[0].inertial_number)
      << "the controller kept the rates apart";
  EXPECT_GT(runs[1].friction, runs[0].friction);
  EXPECT_LT(runs[1].media_solid_fraction, runs[0].media_solid_fraction) << "faster flow dilates";
}

TEST_F(ShearCellPhysics, DissipationWithPowderSplitsIntoTheFourTypesAndSumsToTheTotal) {
  ShearCell cell(small_shear_cell(0.1, 0.3, 0.3));
  ASSERT_GT(cell.powder_count(), 0u);
  cell.warm_up(0.5, 1);
  const ShearCellMeasurements m = cell.measure(0.5);
  const double wall = m.dissipation_density[index(ContactType::WallMedia)] +
                      m.dissipation_density[index(ContactType::WallPowder)];
  EXPECT_GT(m.dissipation_density[index(ContactType::MediaMedia)], 0.0);
  EXPECT_GT(m.dissipation_density[index(ContactType::MediaPowder)], 0.0);
  EXPECT_GT(m.dissipation_density[index(ContactType::PowderPowder)], 0.0);
  EXPECT_GT(wall, 0.0);
  const double sum = m.dissipation_density[index(ContactType::MediaMedia)] +
                     m.dissipation_density[index(ContactType::MediaPowder)] +
                     m.dissipation_density[index(ContactType::PowderPowder)] + wall;
  EXPECT_NEAR(sum, m.dissipated / (m.volume * m.duration), 1e-9 * sum);
  EXPECT_GT(m.powder_collisions.count, 0.0);
  EXPECT_DOUBLE_EQ(m.powder_collisions.dissipated_energy.total(), m.powder_collisions.count);
  EXPECT_GT(m.powder_solid_fraction, 0.0);
}

TEST_F(ShearCellPhysics, LeesEdwardsCellBalancesEnergyAndResistsShear) {
  ShearCellSetup setup = small_shear_cell(0.1);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.size_diameters = Vec3(6, 6, 6);
  setup.steps_per_collision = 40;
  ShearCell cell(setup);
  cell.run_strain(2.0);
  // The middle-half profile rate of a 6 d cell scatters by ~17% between seeds over 1.5 strains
  // (within 3% over 3).
  const ShearCellMeasurements m = cell.measure(3.0);
  std::printf(
      "LE with barostat: p = %.4g Pa (target %.4g), tau = %.4g Pa, mu = %.4g, phi = %.3g, bulk "
      "rate %.4g "
      "(target %.4g)\n",
      m.normal_stress, setup.normal_stress, m.shear_stress, m.friction, m.media_solid_fraction,
      m.bulk_shear_rate, m.target_shear_rate);
  // A 6-diameter cell fluctuates by ~20% over 0.2 strains; the window averages them out.
  EXPECT_NEAR(m.normal_stress, setup.normal_stress, 0.1 * setup.normal_stress)
      << "the barostat imposes it";
  EXPECT_GT(m.friction, 0.1);
  EXPECT_NEAR(m.bulk_shear_rate, setup.shear_rate, 0.2 * setup.shear_rate) << "no walls to slip";
  EXPECT_LT(m.energy_balance_error, 0.01) << "work " << m.work_in << " J, barostat included";
}

// Where a cell's energy balance error comes from (campaigns/README.md). The normal dashpots'
// dissipation, counted per step as C v^2 dt with the velocity predicted for the end of the step,
// is an O(dt^2) estimate: four-fold smaller per doubling of the steps per collision, and over-
// counted. The tangential spring follows the contact points' displacement over the step, as the
// overlap follows the positions, so it stores the work done on it and adds no error of its own
// order. Measured: frictionless -1.09%, -0.24%, -0.07% at 20, 40, 80 steps per collision,
// sticking (mu = 5) -0.82%, -0.15%, -0.03% (-0.64%, -0.01%, +0.05% while friction was booked in
// sliding steps only, below). Until 6 December 2026 the spring was advanced by the
// relative velocity predicted for the end of the step: an O(dt) loss no ledger entry held, the
// sticking cell +2.88%, +1.93%, +0.98% (first order), which both assertions on it reject.
TEST_F(ShearCellPhysics, EnergyBalanceErrorIsSecondOrderForNormalAndTangentialContacts) {
  auto signed_error = [](double friction, int steps_per_collision, double inertial_number = 0.1,
                         double stiffness_ratio = 100.0) {
    ShearCellSetup setup = small_shear_cell(inertial_number);
    setup.media_media.normal_stiffness =
        stiffness_ratio * setup.normal_stress * setup.media_diameter;
    setup.media_media.restitution = 0.3;
    setup.media_media.friction = friction;
    setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
    setup.size_diameters = Vec3(5, 5, 5);
    setup.steps_per_collision = steps_per_collision;
    ShearCell cell(setup);
    cell.warm_up(1.0, 2);
    const ShearCellMeasurements m = cell.measure(1.0);
    return (m.work_in - (m.kinetic_change + m.elastic_change + m.dissipated)) / m.work_in;
  };
  std::array<double, 3> frictionless{}, sticking{};
  for (std::size_t k = 0; k < 3; ++k) {
    frictionless[k] = signed_error(0.0, 20 << k);
    sticking[k] = signed_error(5.0, 20 << k);
    std::printf(
        "%d steps per collision: energy balance error %+.3f%% frictionless, %+.3f%% sticking\n",
        20 << k, 100 * frictionless[k], 100 * sticking[k]);
  }
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_LT(frictionless[k], 0.0) << "the dashpots' dissipation is over-counted";
    EXPECT_GT(frictionless[k] / frictionless[k + 1], 3.0) << "second order";
    EXPECT_LT(std::abs(sticking[k]), std::abs(frictionless[k]))
        << "the tangential springs add no error above the dashpots'";
  }
  EXPECT_GT(std::abs(sticking[0]), 3.0 * std::abs(sticking[1])) << "second order or better";
  // Sliding contacts (the campaigns' friction: at I = 0.3 most contacts slide), at the test
  // cells' stiffness and at the cement campaign's, k_n / (p d) = 1e4. Until 6 December 2026 the
  // books missed half a step of tangential work wherever a contact started or stopped sliding, a
  // part of first order: +0.24%, +0.16%, +0.10% of the work at 40, 80, 160 steps per collision
  // here, +0.57% and +0.37% at 1e4 (campaigns/README.md); now -0.13%, -0.02%, -0.006% and -0.18%,
  // -0.03%.
  struct Stiffness {
    double ratio;             // k_n / (p d)
    std::size_t resolutions;  // 40, 80 (and 160) steps per collision
  };
  for (const auto [stiffness_ratio, resolutions] : {Stiffness{100.0, 3}, Stiffness{1e4, 2}}) {
    std::array<double, 3> sliding{};
    for (std::size_t k = 0; k < resolutions; ++k) {
      sliding[k] = signed_error(0.75, 40 << k, 0.3, stiffness_ratio);
      std::printf("k_n / (p d) = %g, I = 0.3, friction 0.75, %d steps per collision: %+.3f%%\n",
                  stiffness_ratio, 40 << k, 100 * sliding[k]);
    }
    for (std::size_t k = 0; k + 1 < resolutions; ++k) {
      EXPECT_GT(std::abs(sliding[k]), 2.5 * std::abs(sliding[k + 1]))
          << "second order (first order halves the error), k_n / (p d) = " << stiffness_ratio;
    }
    EXPECT_LT(std::abs(sliding[0]), 0.005) << "k_n / (p d) = " << stiffness_ratio;
  }
}

// Cushioning: powder between the balls takes part of the work, so at the same shear rate and
// normal stress the media-media contacts dissipate less (the quick campaign measures 0.3-0.35 of
// the powder-free rate at load 1).
TEST_F(ShearCellPhysics, PowderCushionsTheMediaMediaCollisions) {
  auto media_media_dissipation = [](double powder_load) {
    ShearCellSetup setup = small_shear_cell(0.1, powder_load, 0.5);
    setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
    setup.size_diameters = Vec3(5, 5, 5);
    ShearCell cell(setup);
    cell.run_strain(2.0);
    const ShearCellMeasurements m = cell.measure(2.0);
    EXPECT_NEAR(m.normal_stress, setup.normal_stress, 0.1 * setup.normal_stress)
        << "load " << powder_load;
    return m.dissipation_density[index(ContactType::MediaMedia)];
  };
  const double without = media_media_dissipation(0.0), with = media_media_dissipation(1.0);
  std::printf(
      "media-media dissipation: %.4g W/m^3 without powder, %.4g W/m^3 at load 1 (ratio %.3f)\n",
      without, with, with / without);
  EXPECT_GT(without, 0.0);
  EXPECT_LT(with, 0.5 * without);
}

}  // namespace
}  // namespace millflow::dem
