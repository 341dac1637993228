#pragma once
// The candidate pairs of a block that may touch by now (System::compute_pair_forces): a pair
// found apart sleeps while the approach bound stays below its wake threshold (docs/benchmarks.md,
// "Pairs apart sleep"). Most of a sparse cell's pairs sleep, and this test runs on every candidate
// pair every step: where the build has AVX2, four pairs at a time (docs/benchmarks.md, "The
// drift and the kick on four lanes"), with the same answer as one at a time.
#include <cstddef>
#include <cstdint>

namespace millflow::dem {

// Writes, in increasing order, each k in [begin, end) with !(bound < wake[k]) (a NaN threshold
// wakes its pair) to `awake`, which has room for end - begin indices (its entries past the count
// are overwritten); returns how many.
std::size_t collect_awake_pairs(const float* wake, double bound, std::size_t begin, std::size_t end,
                                std::uint32_t* awake);

// The same one pair at a time: what the lanes must match (tests).
std::size_t collect_awake_pairs_one_at_a_time(const float* wake, double bound, std::size_t begin,
                                              std::size_t end, std::uint32_t* awake);

}  // namespace millflow::dem
