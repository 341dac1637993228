#include "dem/awake_pairs.hpp"

#include <array>
#include <bit>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

namespace millflow::dem {
namespace {

#if defined(__AVX2__)

// Per 4-bit mask of awake pairs, their positions in the group of four, in increasing order (the
// lanes past the mask's count are never counted).
constexpr std::array<std::array<std::uint32_t, 4>, 16> kAwakeOrder = [] {
  std::array<std::array<std::uint32_t, 4>, 16> order{};
  for (std::uint32_t mask = 0; mask < 16; ++mask) {
    std::uint32_t n = 0;
    for (std::uint32_t lane = 0; lane < 4; ++lane) {
      if (mask & (1u << lane)) order[mask][n++] = lane;
    }
  }
  return order;
}();

std::size_t awake_on_lanes(const float* wake, double bound, std::size_t begin, std::size_t end,
                           std::uint32_t* awake) {
  const __m256d bound_lanes = _mm256_set1_pd(bound);
  std::size_t count = 0, k = begin;
  for (; k + 4 <= end; k += 4) {
    // !(bound < wake), exactly: the floats widened to doubles, compared unordered-or-not-less.
    const __m256d threshold = _mm256_cvtps_pd(_mm_loadu_ps(wake + k));
    const int mask = _mm256_movemask_pd(_mm256_cmp_pd(bound_lanes, threshold, _CMP_NLT_UQ));
    // Four indices stored at `count`, which is at most k - begin: inside the room.
    const __m128i order =
        _mm_loadu_si128(reinterpret_cast<const __m128i*>(kAwakeOrder[mask].data()));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(awake + count),
                     _mm_add_epi32(order, _mm_set1_epi32(static_cast<int>(k))));
    count += static_cast<std::size_t>(std::popcount(static_cast<unsigned>(mask)));
  }
  return count + collect_awake_pairs_one_at_a_time(wake, bound, k, end, awake + count);
}

#endif

}  // namespace

std::size_t collect_awake_pairs_one_at_a_time(const float* wake, double bound, std::size_t begin,
                                              std::size_t end, std::uint32_t* awake) {
  std::size_t count = 0;
  for (std::size_t k = begin; k != end; ++k) {
    awake[count] = static_cast<std::uint32_t>(k);
    count += !(bound < static_cast<double>(wake[k]));
  }
  return count;
}

std::size_t collect_awake_pairs(const float* wake, double bound, std::size_t begin, std::size_t end,
                                std::uint32_t* awake) {
#if defined(__AVX2__)
  return awake_on_lanes(wake, bound, begin, end, awake);
#else
  return collect_awake_pairs_one_at_a_time(wake, bound, begin, end, awake);
#endif
}

}  // namespace millflow::dem
