// The neighbour list misses no contact while a held cell shears: the Lees-Edwards barostat
// stretches the box and the particles affinely between steps without forcing a rebuild (the
// displacement test catches the stretch), the shear moves the images, and the grains are an
// eighth of a ball, so one ball's list holds hundreds of them. After any step the contacts the
// force pass found must be every overlapping pair a brute-force search finds. (A contact count
// read straight after a stretch lags by the stretch, which the next step's forces see: the check
// steps a copy once first.)
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>

#include "dem/neighbor_search.hpp"
#include "dem/shear_cell.hpp"
#include "tests/dem/scenes.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

// With no skin the brute-force cutoff is the contact criterion itself (|d|^2 < (r_i + r_j)^2, as
// the force pass tests it).
std::size_t overlapping_pairs(const System& s) {
  return brute_force_pairs(s.domain(), s.positions(), s.radii(), 0.0).size();
}

// A 4 x 4 x 4 d Lees-Edwards cell of balls and 0.25 d powder at load 1 at the campaigns'
// stiffness (k_n / (p d) = 1e4, the powder's by size), held at I = 0.3 from compaction on.
ShearCellRun held_cell_with_powder() {
  spdlog::set_level(spdlog::level::warn);
  constexpr double kRatio = 0.25;
  ShearCellSetup setup = testing::small_shear_cell(0.3, 1.0, kRatio);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.size_diameters = Vec3(4, 4, 4);
  const double d = setup.media_diameter, k = 1e4 * setup.normal_stress * d;
  setup.media_media.normal_stiffness = k;
  setup.media_powder.normal_stiffness = size_scaled_stiffness(k, d, d, kRatio * d);
  setup.powder_powder.normal_stiffness = size_scaled_stiffness(k, d, kRatio * d, kRatio * d);
  return ShearCellRun(setup, {.warmup_strain = 0.5,
                              .warmup_windows = 2,
                              .max_warmup_strain = 1.0,
                              .measure_strain = 1.0,
                              .measure = {.samples = 20}});
}

// The held cell: 2,179 particles checked 30 times over 18,000 steps, 4 s: 40 contacts at the first
// check, 268 at the last.
TEST(ContactDetection, AHeldCellWithPowderMissesNoContactThroughTheBarostatsStretches) {
  ShearCellRun run = held_cell_with_powder();
  std::size_t last_contacts = 0, particles = 0;
  for (int check = 0; check < 30; ++check) {
    run.advance(599);  // prime to the barostat's interval: every phase of it
    System stepped = run.cell().system();
    stepped.step(1);
    const std::size_t brute = overlapping_pairs(stepped);
    EXPECT_EQ(stepped.active_contact_count(), brute) << "at step " << stepped.step_count();
    last_contacts = brute;
    particles = stepped.size();
  }
  std::printf("%zu particles, %zu contacts at the last check\n", particles, last_contacts);
  EXPECT_GT(10 * last_contacts, particles) << "a compacted cell, not a gas";
}

// The gap between a pair's surfaces (negative where they overlap), minimum image.
double pair_gap(const System& s, const NeighborPair& pair) {
  return s.domain().separation(s.positions()[pair.i], s.positions()[pair.j]).norm() -
         (s.radii()[pair.i] + s.radii()[pair.j]);
}

// Steps two spheres one step at a time until `steps_after` steps after they first touch; after
// every step the screening found the contact exactly when a brute-force search does, and what it
// knows of their gap while the pair sleeps is never more than the gap they have. Returns how often
// the pair was screened.
std::uint64_t step_two_spheres_checking_their_sleep(System& s, std::size_t steps_after) {
  s.set_neighbor_skin(0.004);
  std::size_t asleep = 0, since_contact = 0;
  for (std::size_t n = 0; n < 100000 && since_contact < steps_after; ++n) {
    s.step();
    EXPECT_EQ(s.active_contact_count(), overlapping_pairs(s)) << "at step " << s.step_count();
    since_contact += since_contact > 0 || s.active_contact_count() > 0;
    const auto pairs = s.candidate_pairs();
    for (std::size_t p = 0; p < pairs.size(); ++p) {
      const double gap = pair_gap(s, pairs[p]);
      const double slept_on = s.pair_sleeping_gap(p);
      if (slept_on == 0.0) continue;
      ++asleep;
      EXPECT_GE(gap, slept_on) << "at step " << s.step_count();
    }
  }
  EXPECT_EQ(since_contact, steps_after) << "they never met";
  std::printf("%zu steps, %zu of them asleep; %llu screenings, %llu neighbour-list builds\n",
              static_cast<std::size_t>(s.step_count()), asleep,
              static_cast<unsigned long long>(s.pairs_screened()),
              static_cast<unsigned long long>(s.neighbor_rebuild_count()));
  return s.pairs_screened();
}

// Two spheres of 4 mm radius 3 mm apart in the middle of a periodic box `period` long along x,
// closing head on at 0.5 m/s each: 1 um closer each step, 3,000 steps to meet.
System spheres_head_on(double period) {
  Domain box;
  box.hi = Vec3(period, 0.08, 0.06);
  box.periodic = {true, true, true};
  System s(testing::steel_table(0.5, 0.5), box, Vec3::Zero());
  for (const double side : {-1.0, 1.0}) {
    s.add_particle({.position = Vec3(0.5 * period + side * 0.0055, 0.04, 0.03),
                    .velocity = Vec3(-side * 0.5, 0, 0),
                    .radius = 0.004});
  }
  s.set_time_step(1e-6);
  return s;
}

// Their gap closes at twice the speed, as fast as the bound lets it, so the pair sleeps until the
// step before they touch.
TEST(ContactDetection, SpheresMeetingHeadOnSleepUntilTheirGapCouldHaveClosed) {
  System s = spheres_head_on(0.1);
  // Screened before the first step, then from the step they touch on: never while they approach.
  EXPECT_EQ(step_two_spheres_checking_their_sleep(s, 20), 21u);
}

// In a period shorter than twice the largest candidate separation and a skin (here 30 mm against
// 2 x (16 + 4) mm), another image of a pair could come near faster than the bound allows for:
// no pair sleeps, and every step screens the pair.
TEST(ContactDetection, NoPairSleepsInAPeriodTooShortForTheBound) {
  System s = spheres_head_on(0.03);
  const std::uint64_t screened = step_two_spheres_checking_their_sleep(s, 20);
  EXPECT_EQ(screened, s.step_count() + 1);
}

// Across the Lees-Edwards boundary, each sphere at rest in the shear flow: only the flow's
// difference between their heights (the image velocity's share of it) brings them together.
TEST(ContactDetection, SpheresBroughtTogetherByTheShearFlowAcrossTheImageSleepUntilTheyCouldMeet) {
  Domain box;
  box.hi = Vec3(0.1, 0.08, 0.06);
  box.periodic = {true, true, true};
  const double shear_rate = 6.25, r = 0.004;  // an image velocity of 0.5 m/s
  box.lees_edwards = {.enabled = true, .flow_axis = 0, .gradient_axis = 1, .velocity = 0.5};
  System s(testing::steel_table(0.5, 0.5), box, Vec3::Zero());
  // The upper sphere 0.0036 below the top, the lower one 0.0036 above the bottom: 0.9 of the
  // reach apart along y through the image, whose x lags the upper sphere's by 9 mm.
  const auto at_rest_in_the_flow = [&](double x, double y) {
    return ParticleSpec{
        .position = Vec3(x, y, 0.03), .velocity = Vec3(shear_rate * (y - 0.04), 0, 0), .radius = r};
  };
  s.add_particle(at_rest_in_the_flow(0.05, 0.08 - 0.0036));
  s.add_particle(at_rest_in_the_flow(0.041, 0.0036));
  s.set_time_step(1e-5);
  // 12,250 steps to meet. Each neighbour-list build (29) wakes the pair, which then sleeps while
  // the flow's difference across the bound's separation, 2.2 times theirs, could close its gap: 77
  // screenings in all, 319 if the flow were taken the wrong way round.
  EXPECT_LT(step_two_spheres_checking_their_sleep(s, 20), 100u);
}

// The screening skips a candidate pair while its gap cannot have closed
// (System::pair_sleeping_gap): in the same held cell, with its shear, its images and the barostat's
// stretches, every sleeping pair is at least as far apart as the gap it sleeps on, checked at 40
// moments of every phase of the barostat's interval; and most pairs apart do sleep, or the check
// would say nothing.
TEST(ContactDetection, APairSleepsOnlyWhileItsGapCannotHaveClosed) {
  ShearCellRun run = held_cell_with_powder();
  const double d = run.cell().setup().media_diameter;
  std::size_t sleeping = 0, apart = 0;
  double closest_call = 1.0;  // the least gap left over the gap slept on, in diameters
  for (int check = 0; check < 40; ++check) {
    run.advance(293);  // prime to the barostat's interval: every phase of it
    const System& s = run.cell().system();
    const auto pairs = s.candidate_pairs();
    for (std::size_t p = 0; p < pairs.size(); ++p) {
      const auto [i, j] = pairs[p];
      const double gap = pair_gap(s, pairs[p]);
      if (gap <= 0.0) continue;
      ++apart;
      const double slept_on = s.pair_sleeping_gap(p);
      if (slept_on == 0.0) continue;
      ++sleeping;
      ASSERT_GE(gap, slept_on) << "pair (" << i << ", " << j << ") at step " << s.step_count();
      closest_call = std::min(closest_call, (gap - slept_on) / d);
    }
  }
  std::printf("%zu of %zu pairs apart sleep; the closest is %.3g d beyond its gap\n", sleeping,
              apart, closest_call);
  EXPECT_GT(2 * sleeping, apart);
}

}  // namespace
}  // namespace millflow::dem
