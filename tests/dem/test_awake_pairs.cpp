// The sleeping pairs' test on four lanes against the same one pair at a time: the same pairs
// awake, in the same order, for every block length and start, with thresholds at the bound, zero,
// infinite and NaN.
#include "dem/awake_pairs.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace millflow::dem {
namespace {

TEST(AwakePairs, FourLanesWakeThePairsOneAtATimeWakes) {
  const double bound = 1.5e-5;
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> around(0.0, 3e-5);
  std::vector<float> wake(263);
  for (std::size_t k = 0; k < wake.size(); ++k) wake[k] = static_cast<float>(around(rng));
  wake[3] = static_cast<float>(bound);  // rounded: just above or below the bound
  wake[4] = 0.0f;                       // a pair that touched last step
  wake[9] = std::numeric_limits<float>::infinity();
  wake[10] = std::numeric_limits<float>::quiet_NaN();
  wake[11] = std::nextafter(static_cast<float>(bound), 0.0f);
  for (const std::size_t begin : {0u, 1u, 2u, 3u, 5u}) {
    for (const std::size_t end : {begin, begin + 1, begin + 4, begin + 7, wake.size()}) {
      std::vector<std::uint32_t> got(end - begin + 1), want(end - begin + 1);
      const std::size_t got_count = collect_awake_pairs(wake.data(), bound, begin, end, got.data());
      const std::size_t want_count =
          collect_awake_pairs_one_at_a_time(wake.data(), bound, begin, end, want.data());
      ASSERT_EQ(got_count, want_count) << "pairs " << begin << "-" << end;
      got.resize(got_count);
      want.resize(want_count);
      EXPECT_EQ(got, want) << "pairs " << begin << "-" << end;
    }
  }
}

TEST(AwakePairs, BothWaysWakeExactlyThePairsTheBoundHasReached) {
  const std::vector<float> wake = {0.0f, 2.0f, 1.0f, std::numeric_limits<float>::quiet_NaN(), 0.5f};
  for (const bool lanes : {true, false}) {
    std::vector<std::uint32_t> awake(wake.size());
    const std::size_t count =
        lanes ? collect_awake_pairs(wake.data(), 1.0, 0, wake.size(), awake.data())
              : collect_awake_pairs_one_at_a_time(wake.data(), 1.0, 0, wake.size(), awake.data());
    awake.resize(count);
    EXPECT_EQ(awake, (std::vector<std::uint32_t>{0, 2, 3, 4}))
        << (lanes ? "lanes" : "one at a time");
  }
}

}  // namespace
}  // namespace millflow::dem
