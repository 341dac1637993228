#pragma once
// A small SVG writer for the campaign report: line/marker charts, step histograms (spectra) and
// heat maps of a cell grid over the mill cross-section, plus a grid of such panels. Every
// function is pure and returns the SVG text; the same input gives the same bytes (coordinates
// with two decimals, tick labels with "{:g}").
//
// Element conventions (tests count them): a chart draws each series' line as one <path> (with a
// new "M" where an unplottable point breaks it) and each plotted marker as one <circle>; axes,
// ticks, grid lines and legend swatches are <line>/<rect>/<text>, never <path> or <circle>; each
// error bar is three <line>s (the bar and its two caps) with class="error-bar". A heat
// map draws its cells and colour bar as <rect>, the mill outline as one <circle> and each site as
// one <circle>.
//
// Unplottable data: a point with a NaN or infinite coordinate, or a non-positive one on a log
// axis, is skipped (the line breaks there); a series with no plottable point is listed in the
// legend as "<name> (no data)"; a chart with no plottable point at all says "no data" in its plot
// area. Mismatched sizes throw std::invalid_argument naming the series.
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "method/cross_section_grid.hpp"

namespace millflow::report::svg {

enum class Scale { linear, log };

// "Nice" ticks covering [lo, hi]: the step is 1, 2 or 5 x 10^k, the smallest such step that
// gives at most `max_intervals` intervals; the first tick is <= lo and the last >= hi. Each tick
// is an integer multiple of the step (k * m / 10^-e), so 0.1-steps print and compare exactly.
// lo == hi widens the range by 10% of |lo| (or by 1 around 0). Throws for non-finite or lo > hi.
std::vector<double> nice_ticks(double lo, double hi, int max_intervals = 5);

// Powers of ten covering [lo, hi] (0 < lo <= hi): 10^floor(log10 lo) ... 10^ceil(log10 hi), every
// n-th decade so that there are at most `max_intervals` intervals. Throws for lo <= 0.
std::vector<double> log_ticks(double lo, double hi, int max_intervals = 8);

// Ticks of an axis of either scale over a data range.
std::vector<double> axis_ticks(Scale scale, double lo, double hi);

// Text boxes. Every label is laid out with this estimate of its extent (sans-serif: a
// character at most 0.64 em wide, e.g. DejaVu Sans digits; 0.75 em above the baseline, 0.22 em
// below), so labels neither leave the canvas nor cover each other (tests/report/check_svg_text.py
// checks the written SVG with the same estimate and renders it with rsvg-convert).
inline constexpr double kCharWidthEm = 0.64, kAscentEm = 0.75, kDescentEm = 0.22;
double text_width(std::string_view content, double font_size);

// & < > " ' as XML entities.
std::string escape_xml(std::string_view text);

// A complete <svg> document of a known size.
struct Figure {
  double width = 0.0;
  double height = 0.0;
  std::string svg{};
};

struct Axis {
  std::string label{};  // with the unit, e.g. "power draw (W)"
  Scale scale = Scale::linear;
};

// Series colours come from a fixed palette of kPaletteSize; colour < 0 takes the series' index.
inline constexpr int kPaletteSize = 10;

struct Series {
  std::string name{};
  std::vector<double> x{}, y{};
  // Empty, or one standard error per point: a bar over y +- error at each plotted point whose
  // error is finite and positive (none where it is NaN, e.g. unknown); the y axis covers the bars.
  // On a log axis a bar whose lower end is not positive runs down to the plot's bottom.
  std::vector<double> y_error{};
  int colour = -1;
  bool dashed = false;
  bool line = true;     // join the points
  bool markers = true;  // a circle at each point
};

struct LineChart {
  std::string title{};
  Axis x{}, y{};
  std::vector<Series> series{};
  std::size_t legend_limit = 12;  // entries beyond it are summarised as "+ n more"
};

Figure line_chart(const LineChart& chart);

// A histogram drawn as steps: value i spans [edges i, edges i+1).
struct Histogram {
  std::string name{};
  std::vector<double> edges{};   // n + 1, or none with no values
  std::vector<double> values{};  // n
  int colour = -1;
  bool dashed = false;
};

struct HistogramChart {
  std::string title{};
  Axis x{"", Scale::log}, y{"", Scale::log};
  std::vector<Histogram> series{};
  std::size_t legend_limit = 12;
};

// Each histogram is one <path>; no markers.
Figure histogram_chart(const HistogramChart& chart);

struct MapMarker {
  double x = 0.0, y = 0.0;  // m, in the grid's frame (y up)
  std::string label{};
};

// A field over the cross-section grid, with x and y axes in metres; cells whose centre lies
// outside the mill circle (radius grid.half_width), that `blank` marks (e.g. cells outside the
// charge, whose averages rest on a few balls passing by) or whose value is not plottable on the
// colour scale stay blank and out of the colour range. Site labels are placed beside their
// marker where they cover no other label.
struct HeatMap {
  std::string title{};
  std::string quantity{};  // colour-bar label with unit
  method::CrossSectionGrid grid{};
  std::vector<double> values{};  // grid.size(), index j * nx + i
  Scale scale = Scale::linear;
  std::vector<MapMarker> markers{};
  std::vector<bool> blank{};  // empty, or one per cell
};

// Throws std::invalid_argument when values do not match the grid.
Figure heat_map(const HeatMap& map);

// A map of categories (e.g. flow regions) over the cross-section grid: each cell with a category
// (index into `names`, -1 for none) is filled with that category's palette colour; the boundary
// of the categorised cells is one <path> (the outline); the legend lists the names with <rect>
// swatches. The mill outline and each marker are one <circle>; each disc is one dashed <circle>
// of its radius. Throws std::invalid_argument when the categories do not match the grid or name
// an unknown category.
struct MapDisc {
  double x = 0.0, y = 0.0, radius = 0.0;  // m
  std::string label{};
};

struct CategoryMap {
  std::string title{};
  method::CrossSectionGrid grid{};
  std::vector<int> category{};  // grid.size()
  std::vector<std::string> names{};
  std::vector<MapMarker> markers{};
  std::vector<MapDisc> discs{};
};

Figure category_map(const CategoryMap& map);

// Panels in rows of `columns` (each cell as large as the largest panel, kPanelGap apart), under
// a title.
inline constexpr double kPanelGap = 24;
Figure panel_grid(const std::vector<Figure>& panels, int columns, const std::string& title);

}  // namespace millflow::report::svg
