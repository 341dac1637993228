#include "dem/spectrum.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace millflow::dem {
namespace {

TEST(LogHistogram, DecadeEdgesAreExact) {
  const LogHistogram h(1e-9, 1e1, 5);
  ASSERT_EQ(h.bin_count(), 50u);
  const std::array<double, 11> decades{1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4,
                                       1e-3, 1e-2, 1e-1, 1e0,  1e1};
  for (std::size_t d = 0; d + 1 < decades.size(); ++d) EXPECT_EQ(h.bin_lower(5 * d), decades[d]);
  EXPECT_EQ(h.bin_upper(49), 1e1);
}

TEST(LogHistogram, EdgesBetweenDecadesAreEvenlySpacedInLog) {
  const LogHistogram h(1e-6, 1e-3, 4);
  for (std::size_t k = 0; k < h.bin_count(); ++k) {
    EXPECT_NEAR(std::log10(h.bin_lower(k)), -6.0 + 0.25 * static_cast<double>(k), 1e-14);
    if (k + 1 < h.bin_count()) {
      EXPECT_EQ(h.bin_upper(k), h.bin_lower(k + 1));
    }
  }
  EXPECT_EQ(h.bin_upper(h.bin_count() - 1), 1e-3);
}

TEST(LogHistogram, RangeIsWidenedOutwardsToTheGrid) {
  const LogHistogram h(2e-9, 3e-7, 1);
  ASSERT_EQ(h.bin_count(), 3u);
  EXPECT_EQ(h.bin_lower(0), 1e-9);
  EXPECT_EQ(h.bin_upper(2), 1e-6);
}

TEST(LogHistogram, ValuesOnEdgesGoToTheUpperBin) {
  LogHistogram h(1e-4, 1e2, 3);
  for (std::size_t k = 0; k < h.bin_count(); ++k) {
    h.add(h.bin_lower(k));
    EXPECT_EQ(h.count(k), 1.0) << "edge " << k;
    if (k > 0) {
      h.add(std::nextafter(h.bin_lower(k), 0.0));  // just below the edge: the bin under it
      EXPECT_EQ(h.count(k - 1), 2.0) << "edge " << k;
    }
  }
  h.add(h.bin_upper(h.bin_count() - 1));
  EXPECT_EQ(h.overflow(), 1.0);
  EXPECT_EQ(h.underflow(), 0.0);
}

TEST(LogHistogram, UnderflowAndOverflow) {
  LogHistogram h(1e-3, 1e0, 2);
  for (double v : {0.0, -1.0, 1e-4, -std::numeric_limits<double>::infinity()}) h.add(v);
  h.add(5.0, 2.5);
  h.add(std::numeric_limits<double>::infinity());
  h.add(0.05, 0.75);
  EXPECT_EQ(h.underflow(), 4.0);
  EXPECT_EQ(h.overflow(), 3.5);
  EXPECT_EQ(h.total(), 8.25);
  // 0.05 = 10^-1.3 lies in [10^-1.5, 10^-1): bin 3.
  EXPECT_EQ(h.count(3), 0.75);
}

TEST(LogHistogram, RejectsNanValuesAndBadWeights) {
  LogHistogram h(1e-3, 1e0, 2);
  EXPECT_THROW(h.add(std::nan("")), std::invalid_argument);
  EXPECT_THROW(h.add(1e-2, -1.0), std::invalid_argument);
  EXPECT_THROW(h.add(1e-2, std::numeric_limits<double>::infinity()), std::invalid_argument);
  EXPECT_EQ(h.total(), 0.0);
}

TEST(LogHistogram, ConstructorMessagesNameTheValue) {
  auto message = [](double lo, double hi, int b) {
    try {
      LogHistogram h(lo, hi, b);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(valid)");
  };
  EXPECT_EQ(message(0.0, 1.0, 10),
            "LogHistogram: min_value = 0 must be at least 1e-300 (log bins cannot reach 0; values "
            "below min_value count as underflow)");
  EXPECT_EQ(message(1.0, 1.0, 10),
            "LogHistogram: max_value = 1 must be greater than min_value = 1 and at most 1e+300");
  EXPECT_EQ(message(1e-3, 1.0, 0), "LogHistogram: bins_per_decade = 0 must be in [1, 1000]");
}

TEST(LogHistogram, MergeAddsCountsOfTheSameBinning) {
  LogHistogram a(1e-3, 1e0, 2), b(1e-3, 1e0, 2);
  a.add(2e-3);
  a.add(1e-5);
  b.add(2e-3, 2.0);
  b.add(0.5);
  b.add(10.0);
  a.merge(b);
  EXPECT_EQ(a.count(0), 3.0);
  EXPECT_EQ(a.count(5), 1.0);
  EXPECT_EQ(a.underflow(), 1.0);
  EXPECT_EQ(a.overflow(), 1.0);
  EXPECT_EQ(a.total(), 6.0);
}

TEST(LogHistogram, MergeRefusesADifferentBinning) {
  LogHistogram a(1e-3, 1e0, 2);
  EXPECT_THROW(a.merge(LogHistogram(1e-3, 1e0, 3)), std::invalid_argument);
  EXPECT_THROW(a.merge(LogHistogram(1e-4, 1e0, 2)), std::invalid_argument);
  EXPECT_THROW(a.merge(LogHistogram(1e-3, 1e1, 2)), std::invalid_argument);
}

TEST(LogHistogram, CumulativeFractionAbove) {
  LogHistogram h(1e-3, 1e0, 1);  // bins [1e-3, 1e-2), [1e-2, 1e-1), [1e-1, 1)
  h.add(1e-4, 1.0);
  h.add(5e-3, 2.0);
  h.add(5e-2, 3.0);
  h.add(5e-1, 4.0);
  h.add(5e0, 5.0);
  const auto above = h.cumulative_fraction_above();
  ASSERT_EQ(above.size(), 3u);
  EXPECT_DOUBLE_EQ(above[0], 14.0 / 15.0);
  EXPECT_DOUBLE_EQ(above[1], 12.0 / 15.0);
  EXPECT_DOUBLE_EQ(above[2], 9.0 / 15.0);
}

TEST(LogHistogram, CumulativeOfAnEmptyHistogramIsZero) {
  const auto above = LogHistogram(1e-3, 1e0, 1).cumulative_fraction_above();
  EXPECT_EQ(above, std::vector<double>(3, 0.0));
}

TEST(LogHistogram, BinaryRoundTrip) {
  LogHistogram h(1e-8, 1e-2, 7);
  for (int i = 0; i < 100; ++i) h.add(1e-9 * std::pow(1.3, i), 0.5 + i);
  BinaryWriter out;
  h.write(out);
  out.put<int>(99);  // whatever follows must still be readable
  BinaryReader in(out.bytes());
  const LogHistogram back = LogHistogram::read(in);
  EXPECT_EQ(in.get<int>(), 99);
  ASSERT_EQ(back.bin_count(), h.bin_count());
  EXPECT_EQ(back.bins_per_decade(), 7);
  for (std::size_t k = 0; k < h.bin_count(); ++k) {
    EXPECT_EQ(back.bin_lower(k), h.bin_lower(k));
    EXPECT_EQ(back.count(k), h.count(k));
  }
  EXPECT_EQ(back.bin_upper(back.bin_count() - 1), h.bin_upper(h.bin_count() - 1));
  EXPECT_EQ(back.underflow(), h.underflow());
  EXPECT_EQ(back.overflow(), h.overflow());
  EXPECT_GT(back.underflow(), 0.0);
  EXPECT_GT(back.overflow(), 0.0);
}

TEST(LogHistogram, ReadRejectsInvalidOrTruncatedBytes) {
  BinaryWriter bad;
  bad.put<std::int32_t>(2);
  bad.put<std::int32_t>(-6);
  const std::vector<double> counts{1.0, -2.0};
  bad.put_span(std::span<const double>(counts));
  bad.put(0.0);
  bad.put(0.0);
  BinaryReader bad_reader(bad.bytes());
  EXPECT_THROW(LogHistogram::read(bad_reader), CorruptData);

  BinaryWriter good;
  LogHistogram(1e-3, 1e0, 2).write(good);
  const std::string bytes = good.bytes();
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    BinaryReader cut(std::string_view(bytes).substr(0, length));
    EXPECT_THROW(LogHistogram::read(cut), CorruptData) << "length " << length;
  }
}

}  // namespace
}  // namespace millflow::dem
