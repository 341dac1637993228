#pragma once
// A sum over [0, count) that any number of threads computes to the same bits: the range is cut
// into blocks of `grain` at fixed places, each block summed in order, the block sums joined in a
// fixed tree (tbb::parallel_deterministic_reduce). The bits differ from one serial sum's only by
// that grouping.
#include <cstddef>
#include <functional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace millflow::dem {

// The sum of term(k) over k in [0, count).
template <class Term>
double deterministic_sum(std::size_t count, std::size_t grain, Term&& term) {
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, count, grain), 0.0,
      [&](const tbb::blocked_range<std::size_t>& range, double sum) {
        for (std::size_t k = range.begin(); k != range.end(); ++k) sum += term(k);
        return sum;
      },
      std::plus<>());
}

}  // namespace millflow::dem
