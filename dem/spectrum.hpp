#pragma once
// Collision energy spectra: weighted histograms on logarithmic bins.
//
// Binning: every histogram with the same bins_per_decade b shares one global grid of edges
// 10^(i / b), i an integer, so that decades (i a multiple of b) are exact: bin_lower() returns
// exactly the double literal 1e-6, 1e-5, ... there (for decades 1e-22 ... 1e22). The constructor
// widens [min_value, max_value] outwards to the nearest grid edges. Bin k covers
// [bin_lower(k), bin_upper(k)): a value exactly on an edge counts in the bin above it. Values below
// the first edge (zero and negative ones included) go to underflow(), values at or above the last
// edge to overflow().
//
// Serialised form (BinaryWriter, see dem/binary_io.hpp): int32 bins_per_decade, int32 grid index
// of the first edge, put_span<double> of the bin counts, double underflow, double overflow.
#include <cstddef>
#include <vector>

#include "dem/binary_io.hpp"

namespace millflow::dem {

class LogHistogram {
 public:
  // Throws std::invalid_argument unless 1e-300 <= min_value < max_value <= 1e300 and
  // 1 <= bins_per_decade <= 1000 (and the range needs at most a million bins).
  LogHistogram(double min_value, double max_value, int bins_per_decade);

  // Adds `weight` (finite, >= 0; std::invalid_argument otherwise) at `value` (not NaN).
  void add(double value, double weight = 1.0);
  // Adds the other histogram's counts; std::invalid_argument unless the binning is the same.
  void merge(const LogHistogram& other);

  std::size_t bin_count() const { return counts_.size(); }
  double bin_lower(std::size_t bin) const { return edges_.at(bin); }
  double bin_upper(std::size_t bin) const { return edges_.at(bin + 1); }
  double count(std::size_t bin) const { return counts_.at(bin); }
  double underflow() const { return underflow_; }
  double overflow() const { return overflow_; }
  // All weight added: underflow + bins + overflow.
  double total() const;
  int bins_per_decade() const { return bins_per_decade_; }

  // For each bin k: the fraction of all weight with value >= bin_lower(k) (overflow included),
  // the usual form of DEM collision energy spectra. All zeros for an empty histogram.
  std::vector<double> cumulative_fraction_above() const;

  void write(BinaryWriter& out) const;
  // Throws CorruptData for bytes that do not describe a valid histogram.
  static LogHistogram read(BinaryReader& in);

 private:
  // Which edges of the global grid a histogram uses.
  struct Grid {
    int bins_per_decade;
    int first_edge;  // grid index i of bin_lower(0)
    std::size_t bins;
  };
  explicit LogHistogram(const Grid& grid);
  static Grid grid_covering(double min_value, double max_value, int bins_per_decade);

  int bins_per_decade_;
  int first_edge_;             // grid index i of bin_lower(0)
  std::vector<double> edges_;  // bin_count() + 1 edges
  std::vector<double> counts_;
  double underflow_ = 0.0;
  double overflow_ = 0.0;
};

}  // namespace millflow::dem
