#include <fmt/format.h>
#include <unistd.h>

#include <cmath>
#include <fstream>

#include "tests/dem/scenes.hpp"
#include "tests/tasks/mill_frames.hpp"

namespace millflow::tasks::testing {
namespace {

constexpr double kFill = 0.4, kSpeedFraction = 0.2, kSpinUp = 0.5, kInterval = 0.02;
constexpr int kSegments = 3, kFramesPerSegment = 8;
constexpr const char* kCacheVersion = "v5";  // bump when the macro run's bits change

std::filesystem::path cache_dir() {
  return std::filesystem::path(MILLFLOW_BINARY_DIR) / "test_data" /
         fmt::format("small_mill_{}", kCacheVersion);
}

MillSample make_sample() {
  MillSample sample;
  const auto dir = cache_dir();
  std::filesystem::create_directories(dir);
  for (int s = 0; s < kSegments; ++s)
    sample.segments.push_back(dir / fmt::format("segment_{:04d}.mfs", s));
  const auto result_file = dir / "macro_result.json";
  if (std::filesystem::exists(result_file)) {
    std::ifstream in(result_file);
    sample.macro_result = nlohmann::json::parse(in);
    return sample;
  }
  sample.macro_result =
      run_and_write_mill_frames(dem::testing::small_mill(kFill, kSpeedFraction), kSpinUp, kInterval,
                                sample.segments, kFramesPerSegment);
  const auto temp = dir / fmt::format("macro_result.json.{}", ::getpid());
  std::ofstream(temp) << sample.macro_result.dump(1);
  std::filesystem::rename(temp, result_file);  // last: marks the cache complete
  return sample;
}

}  // namespace

const MillSample& small_mill_sample() {
  static const MillSample sample = make_sample();
  return sample;
}

}  // namespace millflow::tasks::testing
