// Mill power against speed on the tiny lifted mill: below the usual operating speed the torque
// stays roughly constant, so the power draw grows with speed. (The fall past ~80% of critical and
// the collapse when centrifuging need longer runs: bench/bench_macro_physics.cpp.)
#include <gtest/gtest.h>

#include "tests/tasks/macro_fixtures.hpp"

namespace millflow::tasks {
namespace {

double power_kw(double speed_fraction) {
  testing::ScratchDir scratch("macro_physics");
  nlohmann::json params = testing::tiny_macro_params(0.3, speed_fraction);
  params["macro"]["measure_revolutions"] = 0.5;
  params["macro"]["vtk_interval"] = 100.0;
  const auto result = testing::DirectRun{params, scratch.path() / "work"}.run().result;
  return result["power"]["mean_kw"].get<double>();
}

TEST(MacroPhysics, PowerRisesWithSpeedBelowTheOperatingRange) {
  const double slow = power_kw(0.3), operating = power_kw(0.75);
  // Power ~ torque x omega with a torque that changes little: 2.5x the speed, at least 1.5x the
  // power.
  EXPECT_GT(operating, 1.5 * slow) << "slow " << slow << " kW, operating " << operating << " kW";
}

}  // namespace
}  // namespace millflow::tasks
