#include "dem/spectrum.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace millflow::dem {

namespace {

constexpr int kMaxBinsPerDecade = 1000;
constexpr std::size_t kMaxBins = 1'000'000;
// Keeps every edge a finite, normal double.
constexpr int kMaxDecade = 300;
constexpr double kMinValue = 1e-300;
constexpr double kMaxValue = 1e300;

// 10^k, exactly rounded for |k| <= 22: positive powers up to 10^22 are exact doubles, and one
// correctly rounded division gives the double nearest to 10^-k.
double power_of_ten(int k) {
  if (k < -22 || k > 22) return std::pow(10.0, k);
  double p = 1.0;
  for (int i = 0; i < std::abs(k); ++i) p *= 10.0;
  return k < 0 ? 1.0 / p : p;
}

int floor_div(int a, int b) {
  return a / b - ((a % b != 0) && ((a < 0) != (b < 0)));
}

// Edge i of the grid with b bins per decade: 10^(i / b), exact at decades.
double grid_edge(int i, int b) {
  const int decade = floor_div(i, b);
  const int step = i - decade * b;
  const double base = power_of_ten(decade);
  return step == 0 ? base : base * std::pow(10.0, static_cast<double>(step) / b);
}

// The largest grid index whose edge is <= value (value > 0, finite). log10 gives a guess that
// rounding can put one off; the edges themselves decide.
int grid_index_at_or_below(double value, int b) {
  int i = static_cast<int>(std::floor(std::log10(value) * b));
  while (grid_edge(i + 1, b) <= value) ++i;
  while (grid_edge(i, b) > value) --i;
  return i;
}

void require_histogram(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument("LogHistogram: " + message);
}

}  // namespace

LogHistogram::Grid LogHistogram::grid_covering(double min_value, double max_value,
                                               int bins_per_decade) {
  require_histogram(min_value >= kMinValue,
                    fmt::format("min_value = {} must be at least {} (log bins cannot reach 0; "
                                "values below min_value count as underflow)",
                                min_value, kMinValue));
  require_histogram(max_value > min_value && max_value <= kMaxValue,
                    fmt::format("max_value = {} must be greater than min_value = {} and at most {}",
                                max_value, min_value, kMaxValue));
  require_histogram(
      bins_per_decade >= 1 && bins_per_decade <= kMaxBinsPerDecade,
      fmt::format("bins_per_decade = {} must be in [1, {}]", bins_per_decade, kMaxBinsPerDecade));
  const int first = grid_index_at_or_below(min_value, bins_per_decade);
  int last = grid_index_at_or_below(max_value, bins_per_decade);
  if (grid_edge(last, bins_per_decade) < max_value) ++last;
  const auto bins = static_cast<std::size_t>(last - first);
  require_histogram(bins <= kMaxBins,
                    fmt::format("[{}, {}] at {} bins per decade needs {} bins, more than {}; use "
                                "fewer bins per decade or a narrower range",
                                min_value, max_value, bins_per_decade, bins, kMaxBins));
  return Grid{bins_per_decade, first, bins};
}

LogHistogram::LogHistogram(double min_value, double max_value, int bins_per_decade)
    : LogHistogram(grid_covering(min_value, max_value, bins_per_decade)) {}

LogHistogram::LogHistogram(const Grid& grid)
    : bins_per_decade_(grid.bins_per_decade),
      first_edge_(grid.first_edge),
      counts_(grid.bins, 0.0) {
  edges_.reserve(grid.bins + 1);
  for (std::size_t k = 0; k <= grid.bins; ++k) {
    edges_.push_back(grid_edge(first_edge_ + static_cast<int>(k), bins_per_decade_));
  }
}

void LogHistogram::add(double value, double weight) {
  // Once per collision of a shear cell's measured window: a message is made only for a bad value.
  if (std::isnan(value)) require_histogram(false, "add: value is NaN");
  if (!(std::isfinite(weight) && weight >= 0.0))
    require_histogram(false, fmt::format("add: weight = {} must be finite and >= 0", weight));
  // The first edge above the value: a value on an edge belongs to the bin starting there.
  const auto above = std::upper_bound(edges_.begin(), edges_.end(), value);
  if (above == edges_.begin()) {
    underflow_ += weight;
  } else if (above == edges_.end()) {
    overflow_ += weight;
  } else {
    counts_[static_cast<std::size_t>(above - edges_.begin()) - 1] += weight;
  }
}

void LogHistogram::merge(const LogHistogram& other) {
  require_histogram(
      bins_per_decade_ == other.bins_per_decade_ && first_edge_ == other.first_edge_ &&
          counts_.size() == other.counts_.size(),
      fmt::format("merge: binnings differ ([{}, {}) with {} bins per decade vs [{}, {}) with "
                  "{}); merge only histograms built with the same range and bins_per_decade",
                  edges_.front(), edges_.back(), bins_per_decade_, other.edges_.front(),
                  other.edges_.back(), other.bins_per_decade_));
  for (std::size_t k = 0; k < counts_.size(); ++k) counts_[k] += other.counts_[k];
  underflow_ += other.underflow_;
  overflow_ += other.overflow_;
}

double LogHistogram::total() const {
  double sum = underflow_;
  for (double c : counts_) sum += c;
  return sum + overflow_;
}

std::vector<double> LogHistogram::cumulative_fraction_above() const {
  std::vector<double> fraction(counts_.size(), 0.0);
  const double all = total();
  if (all == 0.0) return fraction;
  double above = overflow_;
  for (std::size_t k = counts_.size(); k-- > 0;) {
    above += counts_[k];
    fraction[k] = above / all;
  }
  return fraction;
}

void LogHistogram::write(BinaryWriter& out) const {
  out.put<std::int32_t>(bins_per_decade_);
  out.put<std::int32_t>(first_edge_);
  out.put_span(std::span<const double>(counts_));
  out.put(underflow_);
  out.put(overflow_);
}

LogHistogram LogHistogram::read(BinaryReader& in) {
  const auto bins_per_decade = in.get<std::int32_t>();
  const auto first_edge = in.get<std::int32_t>();
  const std::vector<double> counts = in.get_vector<double>();
  const auto underflow = in.get<double>();
  const auto overflow = in.get<double>();
  auto valid_weight = [](double w) { return std::isfinite(w) && w >= 0.0; };
  if (bins_per_decade < 1 || bins_per_decade > kMaxBinsPerDecade || counts.empty() ||
      counts.size() > kMaxBins || !valid_weight(underflow) || !valid_weight(overflow) ||
      !std::all_of(counts.begin(), counts.end(), valid_weight)) {
    throw CorruptData(
        fmt::format("LogHistogram: stored histogram is invalid ({} bins per decade, "
                    "{} bins, or a negative or non-finite count)",
                    bins_per_decade, counts.size()));
  }
  // The edges must stay within the range the constructor allows (one bin beyond, as it rounds
  // outwards).
  const long first = first_edge, last = first + static_cast<long>(counts.size());
  if (first < -static_cast<long>(kMaxDecade + 1) * bins_per_decade ||
      last > static_cast<long>(kMaxDecade + 1) * bins_per_decade) {
    throw CorruptData(
        fmt::format("LogHistogram: stored grid edges {} .. {} at {} bins per decade "
                    "are out of range",
                    first, last, bins_per_decade));
  }
  LogHistogram histogram(Grid{bins_per_decade, first_edge, counts.size()});
  histogram.counts_ = counts;
  histogram.underflow_ = underflow;
  histogram.overflow_ = overflow;
  return histogram;
}

}  // namespace millflow::dem
