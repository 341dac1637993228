#pragma once
// A small SVG line chart for the campaign report: several named series (solid or dashed) with
// markers, linear or log axes with "nice" ticks, axis labels and a legend. Pure functions that
// return the SVG text, so the report's bytes depend only on the data.
#include <string>
#include <vector>

namespace millflow::tasks {

struct PlotSeries {
  std::string name;
  std::vector<double> x, y;  // same length; points with a non-finite (or, on a log axis,
                             // non-positive) coordinate are left out
  bool dashed = false;
};

struct PlotAxes {
  std::string title, x_label, y_label;
  bool log_x = false, log_y = false;
};

// Tick values covering [lo, hi]: multiples of 1, 2 or 5 x 10^k, about `target` of them, from the
// largest multiple <= lo to the smallest >= hi. lo == hi gives a range around the value.
std::vector<double> nice_ticks(double lo, double hi, int target = 5);
// Powers of ten covering [lo, hi] (lo > 0): 10^floor(log10 lo) ... 10^ceil(log10 hi).
std::vector<double> decade_ticks(double lo, double hi);

// Throws std::invalid_argument when x and y differ in length or no series has a plottable point.
std::string line_chart(const PlotAxes& axes, const std::vector<PlotSeries>& series);

// Escapes &, <, >, " for SVG text and attributes.
std::string xml_escape(const std::string& text);

}  // namespace millflow::tasks
