#pragma once
// Golden regressions of the task kinds: fixed input, the expected values and the kind's version
// in tests/tasks/golden/<kind>.json (see its README). A value that moves while the version stays
// fails, and so does a version bump until the file is regenerated with
// MILLFLOW_REGENERATE_GOLDEN=1 (which writes the file and skips the test).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace millflow::testing {

inline void check_golden(const std::string& kind, const std::string& version,
                         const nlohmann::json& values) {
  using nlohmann::json;
  const std::filesystem::path file =
      std::filesystem::path(MILLFLOW_SOURCE_DIR) / "tests/tasks/golden" / (kind + ".json");
  constexpr double kTolerance = 1e-9;  // relative: only rounding differences between builds
  if (std::getenv("MILLFLOW_REGENERATE_GOLDEN")) {
    std::ofstream(file) << json{{"kind", kind},
                                {"version", version},
                                {"relative_tolerance", kTolerance},
                                {"values", values}}
                               .dump(2)
                        << "\n";
    GTEST_SKIP() << "regenerated " << file;
  }
  std::ifstream stream(file);
  ASSERT_TRUE(stream) << "missing " << file << ": regenerate it with MILLFLOW_REGENERATE_GOLDEN=1";
  const json golden = json::parse(stream);
  ASSERT_EQ(golden.at("version").get<std::string>(), version)
      << kind << " changed version: regenerate " << file << " with MILLFLOW_REGENERATE_GOLDEN=1";
  for (const auto& [name, expected] : golden.at("values").items()) {
    ASSERT_TRUE(values.contains(name)) << name;
    if (expected.is_number()) {
      EXPECT_NEAR(values[name].get<double>(), expected.get<double>(),
                  kTolerance * (1e-30 + std::abs(expected.get<double>())))
          << kind << " " << name << " changed without a version bump (now " << version << ")";
    } else {
      EXPECT_EQ(values[name], expected) << kind << " " << name << " changed without a version bump";
    }
  }
}

}  // namespace millflow::testing
