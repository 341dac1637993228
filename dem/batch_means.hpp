#pragma once
// Standard errors of a time average by batch means. A measured window is a series of equal
// blocks, each with its own mean; consecutive blocks are grouped into batches of b blocks, and
// the standard error of the window's mean is the standard deviation of the batch means over
// sqrt(batches). b is the smallest power of two that leaves at least kMinBatches batches whose
// lag-1 autocorrelation is at most kMaxBatchCorrelation (batches that long are uncorrelated);
// when none does, the longest b that leaves kMinBatches batches (or 1 when there are fewer
// blocks), and the error may be low.
#include <cstddef>
#include <span>

namespace millflow::dem {

inline constexpr std::size_t kMinBatches = 8;
inline constexpr double kMaxBatchCorrelation = 0.2;

struct MeanWithError {
  double mean = 0.0, standard_error = 0.0;
};

// The batch length, in blocks, for a series by the rule above.
std::size_t uncorrelated_batch_blocks(std::span<const double> blocks);

// Mean of the series (over whole batches) and its standard error with batches of batch_blocks.
MeanWithError batch_mean(std::span<const double> blocks, std::size_t batch_blocks);

}  // namespace millflow::dem
