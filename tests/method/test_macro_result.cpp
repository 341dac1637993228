// A mill run's result (method/macro_result.hpp): its JSON reads back to the same bytes, and a
// missing, ill-typed or inconsistent field is refused with its JSON pointer and owner.
#include <gtest/gtest.h>

#include <stdexcept>

#include "method/macro_result.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

// A result with a distinct value in the fields the consumers read, one undefined angle and two
// tracked categories over three bins.
MacroResult result() {
  MacroResult r;
  r.n_balls = 220;
  r.ball_mass_kg = 1.5;
  r.fill = 0.3;
  r.speed_fraction = 0.75;
  r.mill = {.radius_m = 0.1, .length_m = 0.036, .axial_ends = "periodic", .lifter_count = 4};
  r.contacts["ball_ball"] = {.pair = "steel-steel", .normal_stiffness_n_m = 1e5};
  r.measure_start_s = 1.5;
  r.measure_end_s = 3.5;
  r.frame_count = 40;
  r.categories = {"steel-steel", "steel-wall:shell"};
  r.power.mean_w = 120.0;
  r.charge.toe_angle_deg = 224.0;
  r.charge.contact_angle_bin_deg = 3.0;
  r.charge.contact_angle_counts = {4.0, 0.0};
  r.frame_means.frames = 40;
  r.spectrum_bin_edges_j = {1e-6, 1e-4, 1e-2, 1.0};
  for (const char* label : {"ball_ball", "ball_liner"}) {
    MacroCollisions& c = r.collisions[label];
    c.category = label;
    c.count = 7;
    c.impact_energy = {.counts = {1.0, 2.0, 3.0}, .underflow = 0.0, .overflow = 1.0};
    c.dissipated_energy = {.counts = {3.0, 2.0, 1.0}, .underflow = 1.0, .overflow = 0.0};
  }
  return r;
}

std::string refusal(const json& document) {
  try {
    read_macro_result(document, "macro task m");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

TEST(MacroResult, JsonReadsBackToTheSameBytes) {
  const json written = result();
  EXPECT_EQ(written.at("n_balls").dump(), "220") << "counts stay integers";
  EXPECT_TRUE(written.at("charge").at("shoulder_angle_deg").is_null());
  EXPECT_EQ(written.at("spectra").at("ball_liner").at("impact_energy").at("overflow"), 1.0);
  const auto read = written.get<MacroResult>();
  EXPECT_FALSE(read.charge.shoulder_angle_deg);
  EXPECT_EQ(read.collisions.at("ball_ball").dissipated_energy.counts,
            (std::vector<double>{3.0, 2.0, 1.0}));
  EXPECT_EQ(json(read).dump(), written.dump());
}

TEST(MacroResult, RefusesAFieldByItsPointer) {
  json missing = result();
  missing.erase("charge");
  EXPECT_EQ(refusal(missing).rfind("macro task m: field /charge/toe_angle_deg is missing", 0), 0u)
      << refusal(missing);
  json fraction = result();
  fraction["n_balls"] = 1.5;
  EXPECT_NE(refusal(fraction).find("field /n_balls is 1.5, not a count"), std::string::npos)
      << refusal(fraction);
  json short_spectrum = result();
  short_spectrum["spectra"]["ball_liner"]["dissipated_energy"]["counts"] = {1.0};
  EXPECT_NE(refusal(short_spectrum)
                .find("field /spectra/ball_liner/dissipated_energy/counts does not hold 3 bins"),
            std::string::npos)
      << refusal(short_spectrum);
}

}  // namespace
}  // namespace millflow::method
