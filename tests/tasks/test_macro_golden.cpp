// Golden regression of the macro kind: a tiny run with a fixed seed and key must reproduce the
// values in tests/tasks/golden/macro.json (relative tolerance 1e-9: the run is deterministic, so
// only a change of the code's results moves them) as long as kMacroVersion is the version stored
// there. A change of results must come with a version bump, so a stale cache is never served.
//
// To regenerate after an intended change (bump kMacroVersion in tasks/macro.hpp first):
//   MILLFLOW_REGENERATE_GOLDEN=1 build/tests/tasks_test_macro_golden
// and commit the new tests/tasks/golden/macro.json.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>

#include "tests/tasks/macro_fixtures.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

constexpr double kRelativeTolerance = 1e-9;
const std::filesystem::path kGoldenFile =
    std::filesystem::path(MILLFLOW_SOURCE_DIR) / "tests/tasks/golden/macro.json";

// The values the golden file pins, by JSON pointer into the result.
const std::vector<std::string> kPinned = {"/n_balls",
                                          "/ball_mass_kg",
                                          "/dt_s",
                                          "/frame_count",
                                          "/measure_end_s",
                                          "/power/mean_kw",
                                          "/power/std_kw",
                                          "/power/torque_arm_kw",
                                          "/power/dissipation_kw",
                                          "/charge/toe_angle_deg",
                                          "/charge/shoulder_angle_deg",
                                          "/collisions/ball_ball/count",
                                          "/collisions/ball_liner/count",
                                          "/collisions/ball_ball/mean_impact_energy_j",
                                          "/collisions/ball_liner/mean_dissipated_j",
                                          "/frame_means/drive_torque_n_m/liner",
                                          "/frame_means/drive_torque_n_m/lifters",
                                          "/frame_means/kinetic_energy_j/translational",
                                          "/frame_means/kinetic_energy_j/rotational",
                                          "/frame_means/centre_of_mass_m/x",
                                          "/frame_means/centre_of_mass_m/y"};

json golden_params() {
  json params = testing::tiny_macro_params(0.3, 0.8);
  params["macro"]["measure_revolutions"] = 0.5;
  return params;
}

json run_golden_case() {
  testing::ScratchDir scratch("macro_golden");
  return testing::DirectRun{golden_params(), scratch.path() / "work", "golden-macro"}.run().result;
}

TEST(MacroGolden, ResultsChangeOnlyWithAVersionBump) {
  const json result = run_golden_case();
  if (const char* regenerate = std::getenv("MILLFLOW_REGENERATE_GOLDEN");
      regenerate && *regenerate) {
    json golden = {
        {"kind", "macro"},
        {"version", kMacroVersion},
        {"relative_tolerance", kRelativeTolerance},
        {"how_to_regenerate", "MILLFLOW_REGENERATE_GOLDEN=1 build/tests/tasks_test_macro_golden"},
        {"params", golden_params()},
        {"task_key", "golden-macro"},
        {"values", json::object()}};
    for (const auto& pointer : kPinned)
      golden["values"][pointer] = result.at(json::json_pointer(pointer));
    std::ofstream(kGoldenFile) << golden.dump(2) << '\n';
    GTEST_SKIP() << "regenerated " << kGoldenFile;
  }
  std::ifstream in(kGoldenFile);
  ASSERT_TRUE(in) << "missing " << kGoldenFile << ": regenerate it (see this file's header)";
  const json golden = json::parse(in);
  ASSERT_EQ(golden["version"], kMacroVersion)
      << "the macro kind's version changed: regenerate the golden values (see this file's header)";
  ASSERT_EQ(golden["params"], golden_params())
      << "the golden case changed: regenerate the golden values";
  for (const auto& pointer : kPinned) {
    const double expected = golden["values"].at(pointer).get<double>();
    const double actual = result.at(json::json_pointer(pointer)).get<double>();
    EXPECT_NEAR(actual, expected, kRelativeTolerance * std::abs(expected))
        << pointer
        << ": the macro results changed without a version bump; bump kMacroVersion in "
           "tasks/macro.hpp "
        << "and regenerate the golden values (see this file's header)";
  }
}

}  // namespace
}  // namespace millflow::tasks
