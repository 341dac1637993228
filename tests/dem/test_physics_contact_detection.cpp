// The neighbour list misses no contact while a held cell shears: the Lees-Edwards barostat
// stretches the box and the particles affinely between steps without forcing a rebuild (the
// displacement test catches the stretch), the shear moves the images, and the grains are an
// eighth of a ball, so one ball's list holds hundreds of them. After any step the contacts the
// force pass found must be every overlapping pair a brute-force search finds. (A contact count
// read straight after a stretch lags by the stretch, which the next step's forces see: the check
// steps a copy once first.)
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstdio>

#include "dem/neighbor_search.hpp"
#include "dem/shear_cell.hpp"
#include "tests/dem/shear_cells.hpp"

namespace millflow::dem {
namespace {

// With no skin the brute-force cutoff is the contact criterion itself (|d|^2 < (r_i + r_j)^2, as
// the force pass tests it).
std::size_t overlapping_pairs(const System& s) {
  return brute_force_pairs(s.domain(), s.positions(), s.radii(), 0.0).size();
}

// A 4 x 4 x 4 d Lees-Edwards cell of balls and 0.25 d powder at load 1 at the campaigns'
// stiffness (k_n / (p d) = 1e4, the powder's by size), held at I = 0.3 from compaction on
// (2,179 particles checked 30 times over 18,000 steps, 4 s: 40 contacts at the first check, about
// 400 at the last).
TEST(ContactDetection, AHeldCellWithPowderMissesNoContactThroughTheBarostatsStretches) {
  spdlog::set_level(spdlog::level::warn);
  constexpr double kRatio = 0.25;
  ShearCellSetup setup = testing::small_shear_cell(0.3, 1.0, kRatio);
  setup.boundary = ShearCellSetup::Boundary::LeesEdwards;
  setup.size_diameters = Vec3(4, 4, 4);
  const double d = setup.media_diameter, k = 1e4 * setup.normal_stress * d;
  setup.media_media.normal_stiffness = k;
  setup.media_powder.normal_stiffness = size_scaled_stiffness(k, d, d, kRatio * d);
  setup.powder_powder.normal_stiffness = size_scaled_stiffness(k, d, kRatio * d, kRatio * d);
  ShearCellRun run(setup, {.warmup_strain = 0.5,
                           .warmup_windows = 2,
                           .max_warmup_strain = 1.0,
                           .measure_strain = 1.0,
                           .measure = {.samples = 20}});
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

}  // namespace
}  // namespace millflow::dem
