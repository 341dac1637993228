#include "tasks/svg_plot.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

namespace millflow::tasks {
namespace {

constexpr double kWidth = 640, kHeight = 400;
constexpr double kLeft = 80, kRight = 180, kTop = 40, kBottom = 60;  // margins; the legend is right
constexpr std::array<const char*, 8> kColours = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e",
                                                 "#9467bd", "#8c564b", "#e377c2", "#17becf"};

bool plottable(double value, bool log) { return std::isfinite(value) && (!log || value > 0.0); }

// Maps data values to pixels along one axis.
struct Scale {
  double lo, hi, pixel_lo, pixel_hi;
  bool log;
  double operator()(double value) const {
    const double v = log ? std::log10(value) : value;
    const double a = log ? std::log10(lo) : lo, b = log ? std::log10(hi) : hi;
    return pixel_lo + (v - a) / (b - a) * (pixel_hi - pixel_lo);
  }
};

std::string tick_label(double value) { return fmt::format("{:g}", value); }

std::vector<double> axis_ticks(double lo, double hi, bool log) { return log ? decade_ticks(lo, hi) : nice_ticks(lo, hi); }

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!(std::isfinite(lo) && std::isfinite(hi)) || hi < lo || target < 1) {
    throw std::invalid_argument(fmt::format("nice_ticks: need finite lo <= hi and target >= 1, got {}, {}, {}", lo, hi, target));
  }
  if (lo == hi) {
    const double pad = lo == 0.0 ? 1.0 : 0.1 * std::abs(lo);
    lo -= pad;
    hi += pad;
  }
  const double raw = (hi - lo) / target;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  double step = decade;
  for (double multiple : {1.0, 2.0, 5.0, 10.0}) {
    step = multiple * decade;
    if (step >= raw) break;
  }
  std::vector<double> ticks;
  const long first = static_cast<long>(std::floor(lo / step + 1e-9)), last = static_cast<long>(std::ceil(hi / step - 1e-9));
  for (long k = first; k <= last; ++k) ticks.push_back(static_cast<double>(k) * step);
  return ticks;
}

std::vector<double> decade_ticks(double lo, double hi) {
  if (!(lo > 0.0) || !(hi >= lo) || !std::isfinite(hi)) {
    throw std::invalid_argument(fmt::format("decade_ticks: need 0 < lo <= hi, got {}, {}", lo, hi));
  }
  std::vector<double> ticks;
  const int first = static_cast<int>(std::floor(std::log10(lo) + 1e-9));
  int last = static_cast<int>(std::ceil(std::log10(hi) - 1e-9));
  if (last == first) ++last;
  for (int k = first; k <= last; ++k) ticks.push_back(std::pow(10.0, k));
  return ticks;
}

std::string xml_escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string line_chart(const PlotAxes& axes, const std::vector<PlotSeries>& series) {
  double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo, y_lo = x_lo, y_hi = -x_lo;
  for (const PlotSeries& s : series) {
    if (s.x.size() != s.y.size()) {
      throw std::invalid_argument(fmt::format("plot '{}': series '{}' has {} x and {} y values", axes.title, s.name,
                                              s.x.size(), s.y.size()));
    }
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      if (!plottable(s.x[k], axes.log_x) || !plottable(s.y[k], axes.log_y)) continue;
      x_lo = std::min(x_lo, s.x[k]);
      x_hi = std::max(x_hi, s.x[k]);
      y_lo = std::min(y_lo, s.y[k]);
      y_hi = std::max(y_hi, s.y[k]);
    }
  }
  if (!(x_lo <= x_hi)) throw std::invalid_argument(fmt::format("plot '{}': no series has a plottable point", axes.title));
  const std::vector<double> x_ticks = axis_ticks(x_lo, x_hi, axes.log_x), y_ticks = axis_ticks(y_lo, y_hi, axes.log_y);
  const Scale sx{x_ticks.front(), x_ticks.back(), kLeft, kWidth - kRight, axes.log_x};
  const Scale sy{y_ticks.front(), y_ticks.back(), kHeight - kBottom, kTop, axes.log_y};

  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{0}\" height=\"{1}\" fill=\"white\"/>\n"
      "<text x=\"{2}\" y=\"22\" font-size=\"14\">{3}</text>\n",
      kWidth, kHeight, kLeft, xml_escape(axes.title));
  for (double t : x_ticks) {
    svg += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1}\" x2=\"{0:.1f}\" y2=\"{2}\" stroke=\"#ddd\"/>"
                       "<text x=\"{0:.1f}\" y=\"{3}\" text-anchor=\"middle\">{4}</text>\n",
                       sx(t), kTop, kHeight - kBottom, kHeight - kBottom + 16, tick_label(t));
  }
  for (double t : y_ticks) {
    svg += fmt::format("<line x1=\"{0}\" y1=\"{1:.1f}\" x2=\"{2}\" y2=\"{1:.1f}\" stroke=\"#ddd\"/>"
                       "<text x=\"{3}\" y=\"{4:.1f}\" text-anchor=\"end\">{5}</text>\n",
                       kLeft, sy(t), kWidth - kRight, kLeft - 6, sy(t) + 4, tick_label(t));
  }
  svg += fmt::format("<text x=\"{:.1f}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n", 0.5 * (kLeft + kWidth - kRight),
                     kHeight - 18, xml_escape(axes.x_label));
  svg += fmt::format("<text transform=\"translate(18 {:.1f}) rotate(-90)\" text-anchor=\"middle\">{}</text>\n",
                     0.5 * (kTop + kHeight - kBottom), xml_escape(axes.y_label));
  for (std::size_t i = 0; i < series.size(); ++i) {
    const PlotSeries& s = series[i];
    const char* colour = kColours[i % kColours.size()];
    std::string points;
    std::string markers;
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      if (!plottable(s.x[k], axes.log_x) || !plottable(s.y[k], axes.log_y)) continue;
      points += fmt::format("{}{:.1f},{:.1f}", points.empty() ? "" : " ", sx(s.x[k]), sy(s.y[k]));
      markers += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"3\" fill=\"{}\"/>", sx(s.x[k]), sy(s.y[k]), colour);
    }
    svg += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"{}/>{}\n", points,
                       colour, s.dashed ? " stroke-dasharray=\"5,3\"" : "", markers);
    const double legend_y = kTop + 16.0 * static_cast<double>(i);
    svg += fmt::format("<line x1=\"{0}\" y1=\"{1:.1f}\" x2=\"{2}\" y2=\"{1:.1f}\" stroke=\"{3}\" stroke-width=\"2\"{4}/>"
                       "<text x=\"{5}\" y=\"{6:.1f}\">{7}</text>\n",
                       kWidth - kRight + 10, legend_y, kWidth - kRight + 30, colour,
                       s.dashed ? " stroke-dasharray=\"5,3\"" : "", kWidth - kRight + 35, legend_y + 4,
                       xml_escape(s.name));
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace millflow::tasks
