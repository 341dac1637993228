// The report's SVG writer: tick choice (values derived by hand from the 1-2-5 rule), log ticks,
// XML escaping, and charts, histograms and heat maps that are well-formed XML with one element per
// datum (see the element conventions in report/svg_plot.hpp).
#include "report/svg_plot.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace millflow::report::svg {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Element counts by name of a well-formed document; fails the test on unbalanced tags, a raw '&'
// that starts no entity, or text outside the root element.
std::map<std::string, int> elements_of(const std::string& xml) {
  std::map<std::string, int> counts;
  std::vector<std::string> open;
  std::size_t at = 0;
  while ((at = xml.find('<', at)) != std::string::npos) {
    const std::size_t end = xml.find('>', at);
    if (end == std::string::npos) {
      ADD_FAILURE() << "unterminated tag at " << at;
      break;
    }
    const std::string tag = xml.substr(at + 1, end - at - 1);
    const std::size_t name_end = tag.find_first_of(" /");
    if (tag.starts_with('/')) {
      const std::string name = tag.substr(1);
      if (open.empty() || open.back() != name)
        ADD_FAILURE() << "closing </" << name << "> does not match";
      else
        open.pop_back();
    } else {
      const std::string name = tag.substr(0, name_end);
      if (open.empty() && !counts.empty())
        ADD_FAILURE() << "a second root element <" << name << ">";
      ++counts[name];
      if (!tag.ends_with('/')) open.push_back(name);
    }
    at = end + 1;
  }
  EXPECT_TRUE(open.empty()) << "unclosed elements, innermost <" << (open.empty() ? "" : open.back())
                            << ">";
  for (std::size_t amp = xml.find('&'); amp != std::string::npos; amp = xml.find('&', amp + 1)) {
    const std::string rest = xml.substr(amp, 6);
    const bool entity = rest.starts_with("&amp;") || rest.starts_with("&lt;") ||
                        rest.starts_with("&gt;") || rest.starts_with("&quot;") ||
                        rest.starts_with("&apos;");
    EXPECT_TRUE(entity) << "raw & at " << amp;
  }
  return counts;
}

std::size_t occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(NiceTicks, UnitRangeStepsByTwoTenths) {
  // range 1 / 5 = 0.2: steps 0.1 give 10 intervals, 0.2 give 5.
  EXPECT_EQ(nice_ticks(0.0, 1.0), (std::vector<double>{0.0, 0.2, 0.4, 0.6, 0.8, 1.0}));
}

TEST(NiceTicks, NarrowRangeCoveredByTenths) {
  // [0.55, 0.85]: 0.01 -> 30, 0.02 -> 27..43 = 16, 0.05 -> 11..17 = 6, 0.1 -> 5..9 = 4 intervals.
  EXPECT_EQ(nice_ticks(0.55, 0.85), (std::vector<double>{0.5, 0.6, 0.7, 0.8, 0.9}));
}

TEST(NiceTicks, RangeAcrossZeroStepsByFive) {
  // [-3, 17]: 1 -> 20, 2 -> -2..9 = 11, 5 -> -1..4 = 5 intervals.
  EXPECT_EQ(nice_ticks(-3.0, 17.0), (std::vector<double>{-5.0, 0.0, 5.0, 10.0, 15.0, 20.0}));
}

TEST(NiceTicks, HundredsOfWatts) {
  // [900, 1234]: 10 -> 34, 20 -> 17, 50 -> 18..25 = 7, 100 -> 9..13 = 4 intervals.
  EXPECT_EQ(nice_ticks(900.0, 1234.0),
            (std::vector<double>{900.0, 1000.0, 1100.0, 1200.0, 1300.0}));
}

TEST(NiceTicks, SingleValueIsWidenedByTenPercent) {
  // 0.2 +- 0.02: 0.001 -> 40, 0.002 -> 20, 0.005 -> 36..44 = 8, 0.01 -> 18..22 = 4 intervals.
  EXPECT_EQ(nice_ticks(0.2, 0.2), (std::vector<double>{0.18, 0.19, 0.2, 0.21, 0.22}));
  EXPECT_EQ(nice_ticks(0.0, 0.0), (std::vector<double>{-1.0, -0.5, 0.0, 0.5, 1.0}));
}

TEST(NiceTicks, RefusesAnUnusableRange) {
  EXPECT_THROW(nice_ticks(1.0, 0.0), std::invalid_argument);
  EXPECT_THROW(nice_ticks(kNaN, 1.0), std::invalid_argument);
}

TEST(LogTicks, DecadesCoveringTheRange) {
  // 3e-16 lies above 1e-16 and 2e-12 above 1e-12: the covering decades are 1e-16 .. 1e-11.
  EXPECT_EQ(log_ticks(3e-16, 2e-12),
            (std::vector<double>{1e-16, 1e-15, 1e-14, 1e-13, 1e-12, 1e-11}));
  EXPECT_EQ(log_ticks(1.0, 1000.0), (std::vector<double>{1.0, 10.0, 100.0, 1000.0}));
  // Within one decade the axis still spans a whole decade.
  EXPECT_EQ(log_ticks(2.0, 3.0), (std::vector<double>{1.0, 10.0}));
}

TEST(LogTicks, WideRangeTakesEveryThirdDecade) {
  // 10^-20 .. 10^1 is 21 decades; at most 8 intervals -> stride ceil(21 / 8) = 3.
  EXPECT_EQ(log_ticks(5e-20, 5.0),
            (std::vector<double>{1e-20, 1e-17, 1e-14, 1e-11, 1e-8, 1e-5, 1e-2, 10.0}));
}

TEST(LogTicks, RefusesNonPositiveRange) {
  EXPECT_THROW(log_ticks(0.0, 1.0), std::invalid_argument);
}

TEST(EscapeXml, EscapesTheFiveSpecialCharacters) {
  EXPECT_EQ(escape_xml(R"(a<b & "c" > 'd')"), "a&lt;b &amp; &quot;c&quot; &gt; &apos;d&apos;");
  EXPECT_EQ(escape_xml("plain J=0.2"), "plain J=0.2");
}

TEST(LineChart, OnePathPerSeriesAndOneCirclePerPoint) {
  LineChart chart{
      .title = "power <draw> & speed",
      .x = {"speed fraction (-)"},
      .y = {"power draw (W)"},
      .series = {{.name = "J=0.2", .x = {0.6, 0.7, 0.8}, .y = {900, 1000, 1100}},
                 {.name = "J=0.3", .x = {0.6, 0.7}, .y = {1200, 1300}, .dashed = true}}};
  const Figure figure = line_chart(chart);
  const auto counts = elements_of(figure.svg);
  EXPECT_EQ(counts.at("svg"), 1);
  EXPECT_EQ(counts.at("path"), 2);
  EXPECT_EQ(counts.at("circle"), 5);
  EXPECT_NE(figure.svg.find("power &lt;draw&gt; &amp; speed"), std::string::npos);
  EXPECT_EQ(occurrences(figure.svg, "stroke-dasharray"),
            2u);  // the dashed series and its legend swatch
}

TEST(LineChart, NaNPointsAreSkippedAndBreakTheLine) {
  LineChart chart{.title = "t",
                  .x = {"x"},
                  .y = {"y"},
                  .series = {{.name = "gappy", .x = {1, 2, 3, 4}, .y = {1, kNaN, 3, 4}}}};
  const Figure figure = line_chart(chart);
  const auto counts = elements_of(figure.svg);
  EXPECT_EQ(counts.at("circle"), 3);
  EXPECT_EQ(counts.at("path"), 1);
  const std::size_t d = figure.svg.find("<path d=\"");
  const std::string path = figure.svg.substr(d, figure.svg.find('"', d + 9) - d);
  EXPECT_EQ(occurrences(path, "M"), 2u) << path;
  EXPECT_EQ(occurrences(path, "L"), 1u) << path;
}

TEST(LineChart, NonPositiveValuesAreSkippedOnALogAxis) {
  LineChart chart{.title = "t",
                  .x = {"x"},
                  .y = {"y", Scale::log},
                  .series = {{.name = "s", .x = {1, 2, 3}, .y = {0.0, 10.0, 100.0}}}};
  EXPECT_EQ(elements_of(line_chart(chart).svg).at("circle"), 2);
}

TEST(LineChart, EmptySeriesIsNamedInTheLegendAndAnEmptyChartSaysNoData) {
  LineChart chart{
      .title = "t",
      .x = {"x"},
      .y = {"y"},
      .series = {{.name = "full", .x = {1, 2}, .y = {1, 2}}, {.name = "hollow", .x = {}, .y = {}}}};
  const std::string svg = line_chart(chart).svg;
  EXPECT_EQ(elements_of(svg).at("path"), 1);
  EXPECT_NE(svg.find("hollow (no data)"), std::string::npos);

  const std::string empty = line_chart({.title = "nothing",
                                        .x = {"x"},
                                        .y = {"y"},
                                        .series = {{.name = "nan", .x = {kNaN}, .y = {1.0}}}})
                                .svg;
  EXPECT_EQ(elements_of(empty).count("path"), 0u);
  EXPECT_NE(empty.find(">no data<"), std::string::npos);
}

TEST(LineChart, MismatchedSizesNameTheSeries) {
  LineChart chart{
      .title = "t", .x = {"x"}, .y = {"y"}, .series = {{.name = "broken", .x = {1, 2}, .y = {1}}}};
  try {
    line_chart(chart);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("\"broken\""), std::string::npos) << error.what();
  }
}

TEST(LineChart, ErrorBarsWhereTheErrorIsKnownAndTheAxisCoversThem) {
  LineChart chart{.title = "t",
                  .x = {"x"},
                  .y = {"y"},
                  .series = {{.name = "s", .x = {1, 2, 3}, .y = {10, 20, 30}}}};
  chart.series[0].y_error = {1, kNaN, 50};  // no bar where the error is unknown
  const std::string svg = line_chart(chart).svg;
  EXPECT_EQ(occurrences(svg, "class=\"error-bar\""), 2u * 3u);  // bar and two caps each
  EXPECT_EQ(elements_of(svg).at("circle"), 3);
  // The bars span [-20, 80]: ticks -20 .. 80 by 20, so y(v) = 360 - 3.24 (v + 20); x(1) = 78.
  EXPECT_NE(svg.find(">-20<"), std::string::npos);
  EXPECT_NE(svg.find(">80<"), std::string::npos);
  EXPECT_NE(svg.find("x1=\"78.00\" y1=\"266.04\" x2=\"78.00\" y2=\"259.56\""), std::string::npos)
      << svg;

  chart.series[0].y_error = {1, 2};
  EXPECT_THROW(line_chart(chart), std::invalid_argument);
}

TEST(LineChart, ErrorBarBelowZeroOnALogAxisRunsToTheBottom) {
  LineChart chart{.title = "t",
                  .x = {"x"},
                  .y = {"y", Scale::log},
                  .series = {{.name = "s", .x = {1, 2}, .y = {10, 20}, .y_error = {20, kNaN}}}};
  const std::string svg = line_chart(chart).svg;
  EXPECT_EQ(occurrences(svg, "class=\"error-bar\""), 3u);
  // x(1) = 78 (ticks 1 .. 2 by 0.2); 360 is the plot's bottom edge.
  EXPECT_NE(svg.find("class=\"error-bar\" x1=\"78.00\" y1=\"360.00\" x2=\"78.00\""),
            std::string::npos)
      << svg;
}

TEST(LineChart, LegendBeyondItsLimitIsSummarised) {
  LineChart chart{.title = "t", .x = {"x"}, .y = {"y"}, .legend_limit = 3};
  for (int s = 0; s < 5; ++s)
    chart.series.push_back({.name = fmt::format("s{}", s), .x = {1, 2}, .y = {1.0 * s, 2.0}});
  const std::string svg = line_chart(chart).svg;
  EXPECT_NE(svg.find(">+ 3 more<"), std::string::npos);
  EXPECT_EQ(svg.find(">s2<"), std::string::npos);
  EXPECT_EQ(elements_of(svg).at("path"), 5);
}

TEST(HistogramChart, StepsOverEveryPlottableBin) {
  HistogramChart chart{
      .title = "spectra",
      .x = {"energy (J)", Scale::log},
      .y = {"rate (1/s)", Scale::log},
      .series = {{.name = "U=0.5", .edges = {1e-9, 1e-8, 1e-7, 1e-6}, .values = {5, 0, 2}},
                 {.name = "U=1", .edges = {1e-9, 1e-8}, .values = {7}}}};
  const std::string svg = histogram_chart(chart).svg;
  const auto counts = elements_of(svg);
  EXPECT_EQ(counts.at("path"), 2);
  EXPECT_EQ(counts.count("circle"), 0u);
  // The first series: bin 0, then a break at the empty bin 1, then bin 2.
  const std::size_t d = svg.find("<path d=\"");
  const std::string path = svg.substr(d, svg.find('"', d + 9) - d);
  EXPECT_EQ(occurrences(path, "M"), 2u) << path;
  EXPECT_EQ(occurrences(path, "L"), 2u) << path;
  EXPECT_THROW(histogram_chart(
                   {.title = "bad", .series = {{.name = "h", .edges = {1, 2}, .values = {1, 2}}}}),
               std::invalid_argument);
}

TEST(HeatMap, CellsInsideTheCircleOnlyAndOneCirclePerSite) {
  // 4 x 4 cells over [-1, 1]^2: centres at +-0.25 and +-0.75; the four corner cells (r = 1.06)
  // lie outside the unit circle, the other 12 inside. One cell is NaN and stays blank.
  HeatMap map{.title = "shear rate", .quantity = "shear rate (1/s)", .grid = {4, 4, 1.0}};
  for (int c = 0; c < 16; ++c) map.values.push_back(c);
  map.values[5] = kNaN;
  map.markers = {{0.2, -0.3, "toe-0"}, {-0.5, 0.1, "bulk<1>"}};
  const std::string svg = heat_map(map).svg;
  const auto counts = elements_of(svg);
  constexpr int kBarSteps = 32;
  EXPECT_EQ(counts.at("rect"),
            1 + 11 + kBarSteps + 1);      // background, the 11 plottable cells, colour bar, frame
  EXPECT_EQ(counts.at("circle"), 1 + 2);  // the mill outline and the sites
  EXPECT_NE(svg.find(">bulk&lt;1&gt;<"), std::string::npos);
}

TEST(HeatMap, BlankCellsStayOutOfTheMapAndItsColourRange) {
  HeatMap map{.title = "m", .quantity = "q", .grid = {2, 2, 1.0}, .values = {1, 2, 3, 1000}};
  map.blank = {false, false, false, true};
  const std::string svg = heat_map(map).svg;
  EXPECT_EQ(elements_of(svg).at("rect"), 1 + 3 + 32 + 1);
  EXPECT_EQ(svg.find(">1000<"), std::string::npos);  // no colour-bar tick reaches the blank value
  map.blank = {true};
  EXPECT_THROW(heat_map(map), std::invalid_argument);
}

TEST(HeatMap, CrowdedSiteLabelsDoNotCoverEachOther) {
  HeatMap map{.title = "m", .quantity = "q", .grid = {2, 2, 1.0}, .values = {1, 2, 3, 4}};
  for (int k = 0; k < 6; ++k)
    map.markers.push_back({0.01 * k, 0.0, fmt::format("cascading-{}", k)});
  const std::string svg = heat_map(map).svg;
  std::vector<std::pair<double, double>> starts;  // x, baseline of each 9 px label
  for (auto at = svg.find("font-size=\"9\""); at != std::string::npos;
       at = svg.find("font-size=\"9\"", at + 1)) {
    const auto open = svg.rfind("<text", at);
    const auto x = std::stod(svg.substr(svg.find("x=\"", open) + 3));
    const auto y = std::stod(svg.substr(svg.find("y=\"", open) + 3));
    starts.emplace_back(x, y);
  }
  ASSERT_EQ(starts.size(), 6u);
  const double width = text_width("cascading-0", 9), height = 9 * (kAscentEm + kDescentEm);
  for (std::size_t a = 0; a < starts.size(); ++a) {
    for (std::size_t b = a + 1; b < starts.size(); ++b) {
      const bool apart = std::abs(starts[a].first - starts[b].first) >= width ||
                         std::abs(starts[a].second - starts[b].second) >= height;
      EXPECT_TRUE(apart) << a << " and " << b;
    }
  }
}

TEST(HeatMap, ValuesMustMatchTheGrid) {
  EXPECT_THROW(heat_map({.title = "m", .grid = {2, 2, 1.0}, .values = {1, 2, 3}}),
               std::invalid_argument);
}

TEST(PanelGrid, NestsEveryPanelInOneDocument) {
  const Figure a = line_chart(
      {.title = "a", .x = {"x"}, .y = {"y"}, .series = {{.name = "s", .x = {1}, .y = {1}}}});
  const Figure b = heat_map({.title = "b", .grid = {2, 2, 1.0}, .values = {1, 2, 3, 4}});
  const Figure grid = panel_grid({a, b, a}, 2, "panels");
  const auto counts = elements_of(grid.svg);
  EXPECT_EQ(counts.at("svg"), 4);
  EXPECT_EQ(counts.at("g"), 3 + 1);  // one translate per panel, the heat map's cell group
  EXPECT_DOUBLE_EQ(grid.width, 2 * (std::max(a.width, b.width) + kPanelGap));
  EXPECT_DOUBLE_EQ(grid.height, 32 + 2 * std::max(a.height, b.height));
}

}  // namespace
}  // namespace millflow::report::svg
