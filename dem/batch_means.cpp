#include "dem/batch_means.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace millflow::dem {
namespace {

std::vector<double> batch_values(std::span<const double> blocks, std::size_t batch_blocks) {
  std::vector<double> batches(blocks.size() / batch_blocks, 0.0);
  for (std::size_t b = 0; b < batches.size(); ++b) {
    for (std::size_t k = 0; k < batch_blocks; ++k) batches[b] += blocks[b * batch_blocks + k];
    batches[b] /= static_cast<double>(batch_blocks);
  }
  return batches;
}

double mean_of(const std::vector<double>& v) {
  double sum = 0.0;
  for (double x : v) sum += x;
  return v.empty() ? 0.0 : sum / static_cast<double>(v.size());
}

double lag1_correlation(const std::vector<double>& v) {
  const double mean = mean_of(v);
  double variance = 0.0, covariance = 0.0;
  for (std::size_t k = 0; k < v.size(); ++k) {
    variance += (v[k] - mean) * (v[k] - mean);
    if (k + 1 < v.size()) covariance += (v[k] - mean) * (v[k + 1] - mean);
  }
  return variance > 0.0 ? covariance / variance : 0.0;
}

}  // namespace

std::size_t uncorrelated_batch_blocks(std::span<const double> blocks) {
  std::size_t longest = 1;
  for (std::size_t b = 1; blocks.size() / b >= kMinBatches; b *= 2) {
    longest = b;
    if (lag1_correlation(batch_values(blocks, b)) <= kMaxBatchCorrelation) return b;
  }
  return longest;
}

MeanWithError batch_mean(std::span<const double> blocks, std::size_t batch_blocks) {
  const std::vector<double> batches = batch_values(blocks, std::max<std::size_t>(1, batch_blocks));
  MeanWithError out;
  out.mean = mean_of(batches);
  if (batches.size() < 2) return out;
  double variance = 0.0;
  for (double x : batches) variance += (x - out.mean) * (x - out.mean);
  variance /= static_cast<double>(batches.size() - 1);
  out.standard_error = std::sqrt(variance / static_cast<double>(batches.size()));
  return out;
}

}  // namespace millflow::dem
