// The report's SVG charts: tick choice worked out by hand, log axes, escaping, and what is drawn.
#include <gtest/gtest.h>

#include <cmath>

#include "tasks/svg_plot.hpp"

namespace millflow::tasks {
namespace {

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

void expect_ticks(const std::vector<double>& got, const std::vector<double>& expected) {
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t k = 0; k < got.size(); ++k) EXPECT_NEAR(got[k], expected[k], 1e-12 * std::abs(expected[k]) + 1e-15);
}

TEST(SvgPlot, NiceTicksAreOneTwoOrFiveTimesAPowerOfTenAndCoverTheRange) {
  expect_ticks(nice_ticks(0.0, 1.0), {0.0, 0.2, 0.4, 0.6, 0.8, 1.0});      // raw step 0.2
  expect_ticks(nice_ticks(643.0, 1109.0), {600, 700, 800, 900, 1000, 1100, 1200});  // raw 93 -> 100
  expect_ticks(nice_ticks(0.65, 0.8), {0.65, 0.7, 0.75, 0.8});             // raw 0.03 -> 0.05
  expect_ticks(nice_ticks(-3.0, 7.0), {-4, -2, 0, 2, 4, 6, 8});            // raw 2
  expect_ticks(nice_ticks(5.0, 5.0), {4.4, 4.6, 4.8, 5.0, 5.2, 5.4, 5.6});  // +-10%, then raw step 0.2
  EXPECT_THROW(nice_ticks(1.0, 0.0), std::invalid_argument);
}

TEST(SvgPlot, DecadeTicksSpanWholePowersOfTen) {
  expect_ticks(decade_ticks(3e-9, 2e-3), {1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2});
  expect_ticks(decade_ticks(10.0, 10.0), {10.0, 100.0});
  EXPECT_THROW(decade_ticks(0.0, 1.0), std::invalid_argument);
}

TEST(SvgPlot, TextIsEscaped) { EXPECT_EQ(xml_escape("a<b & \"c\">"), "a&lt;b &amp; &quot;c&quot;&gt;"); }

TEST(SvgPlot, DrawsOneMarkerPerPlottablePointAndALegendEntryPerSeries) {
  const std::vector<PlotSeries> series = {
      {.name = "J = 0.2", .x = {0.65, 0.8}, .y = {600.0, 700.0}, .dashed = false},
      {.name = "U = 1 <dry>", .x = {0.65, 0.8, 0.9}, .y = {610.0, std::nan(""), 720.0}, .dashed = true}};
  const std::string svg = line_chart({"Power", "speed", "power (W)"}, series);
  EXPECT_EQ(svg.rfind("<svg ", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_EQ(count(svg, "<circle"), 4u) << "the NaN point is left out";
  EXPECT_EQ(count(svg, "<polyline"), 2u);
  EXPECT_EQ(count(svg, "stroke-dasharray"), 2u) << "the dashed line and its legend entry";
  EXPECT_NE(svg.find("U = 1 &lt;dry&gt;"), std::string::npos);
  EXPECT_NE(svg.find(">0.85<"), std::string::npos) << "a tick label of the x axis (0.65 ... 0.9, step 0.05)";
}

TEST(SvgPlot, LogAxesLeaveOutNonPositiveValuesAndRefuseAnEmptyChart) {
  const PlotAxes log_axes{"Spectra", "energy (J)", "rate (1/s)", true, true};
  const std::string svg = line_chart(log_axes, {{.name = "U = 0", .x = {1e-6, 1e-5, 1e-4}, .y = {5.0, 0.0, 2.0}}});
  EXPECT_EQ(count(svg, "<circle"), 2u);
  EXPECT_NE(svg.find(">1e-06<"), std::string::npos);
  EXPECT_THROW(line_chart(log_axes, {{.name = "none", .x = {1.0}, .y = {0.0}}}), std::invalid_argument);
  EXPECT_THROW(line_chart({}, {{.name = "bad", .x = {1.0, 2.0}, .y = {1.0}}}), std::invalid_argument);
}

}  // namespace
}  // namespace millflow::tasks
