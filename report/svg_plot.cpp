#include "report/svg_plot.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

namespace millflow::report::svg {
namespace {

// Exact for |exponent| <= 22 (every such power of ten is a double).
double power_of_ten(int exponent) {
  double value = 1.0;
  for (int k = 0; k < std::abs(exponent); ++k) value *= 10.0;
  return exponent < 0 ? 1.0 / value : value;
}

// k x m x 10^e, divided rather than multiplied for e < 0 so that 0.1-steps come out exact.
double tick_value(long long k, int m, int e) {
  const double units = static_cast<double>(k * m);
  return e < 0 ? units / power_of_ten(-e) : units * power_of_ten(e);
}

// value / (m x 10^e) the same way.
double in_steps(double value, int m, int e) {
  return e < 0 ? value * power_of_ten(-e) / m : value / (m * power_of_ten(e));
}

// Absorbs rounding in the step counts (a tick that lands on the data's end stays the end).
constexpr double kStepSlack = 1e-9;

std::string px(double value) {
  return fmt::format("{:.2f}", value);
}

std::string tick_label(double value) {
  return fmt::format("{:g}", value);
}

constexpr std::array<const char*, kPaletteSize> kPalette = {
    "#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
    "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"};

const char* palette(int colour, std::size_t index) {
  const std::size_t slot = colour >= 0 ? static_cast<std::size_t>(colour) : index;
  return kPalette[slot % kPalette.size()];
}

std::string svg_open(double width, double height) {
  return fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} "
      "{1}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{0}\" height=\"{1}\" "
      "fill=\"white\"/>\n",
      px(width), px(height));
}

std::string text(double x, double y, std::string_view content, std::string_view attributes = "") {
  return fmt::format("<text x=\"{}\" y=\"{}\"{}{}>{}</text>\n", px(x), px(y),
                     attributes.empty() ? "" : " ", attributes, escape_xml(content));
}

std::string line(double x1, double y1, double x2, double y2, std::string_view stroke) {
  return fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\"/>\n", px(x1),
                     px(y1), px(x2), px(y2), stroke);
}

bool plottable(double value, Scale scale) {
  return std::isfinite(value) && (scale == Scale::linear || value > 0.0);
}

// The smallest and largest plottable values seen.
struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double value) {
    lo = std::min(lo, value);
    hi = std::max(hi, value);
  }
  bool empty() const { return lo > hi; }
};

// Maps data to pixels on one axis over its tick range.
class AxisMap {
 public:
  AxisMap(Scale scale, const Range& range, double from_px, double to_px)
      : scale_(scale), ticks_(axis_ticks(scale, range.lo, range.hi)), from_(from_px), to_(to_px) {}

  double operator()(double value) const {
    const double lo = transform(ticks_.front()), hi = transform(ticks_.back());
    return from_ + (transform(value) - lo) / (hi - lo) * (to_ - from_);
  }
  const std::vector<double>& ticks() const { return ticks_; }
  Scale scale() const { return scale_; }

 private:
  double transform(double value) const { return scale_ == Scale::log ? std::log10(value) : value; }

  Scale scale_;
  std::vector<double> ticks_;
  double from_, to_;
};

// The frame of a chart: plot area, axes with ticks and labels, title, legend.
struct ChartFrame {
  static constexpr double kWidth = 660, kHeight = 420;
  static constexpr double kLeft = 78, kRight = 480, kTop = 36, kBottom = 360;
};

struct LegendEntry {
  std::string name;
  const char* colour;
  bool dashed;
  bool marker;
  bool has_data;
};

std::string dash_attribute(bool dashed) {
  return dashed ? " stroke-dasharray=\"6 4\"" : "";
}

constexpr double kLegendFont = 11;

std::string legend_name(const LegendEntry& entry) {
  return entry.has_data ? entry.name : entry.name + " (no data)";
}

// The chart's width: the frame's, or wider where the legend's longest name needs it.
double chart_width(const std::vector<LegendEntry>& entries) {
  double widest = 0.0;
  for (const LegendEntry& entry : entries)
    widest = std::max(widest, text_width(legend_name(entry), kLegendFont));
  return std::max(ChartFrame::kWidth, std::ceil(ChartFrame::kRight + 14 + 28 + widest + 8));
}

std::string legend(const std::vector<LegendEntry>& entries, std::size_t limit) {
  std::string out;
  const double x = ChartFrame::kRight + 14;
  double y = ChartFrame::kTop + 10;
  const std::size_t shown = entries.size() > limit ? limit - 1 : entries.size();
  for (std::size_t i = 0; i < shown; ++i) {
    const LegendEntry& entry = entries[i];
    out += fmt::format(
        "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\" stroke-width=\"2\"{}/>\n",
        px(x), px(y), px(x + 22), px(y), entry.colour, dash_attribute(entry.dashed));
    if (entry.marker) {
      out += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"6\" height=\"6\" fill=\"{}\"/>\n",
                         px(x + 8), px(y - 3), entry.colour);
    }
    out += text(x + 28, y + 4, legend_name(entry), "font-size=\"11\"");
    y += 18;
  }
  if (shown < entries.size())
    out += text(x, y + 4, fmt::format("+ {} more", entries.size() - shown), "font-size=\"11\"");
  return out;
}

std::string axes(const std::string& title, const Axis& x_axis, const Axis& y_axis, const AxisMap& x,
                 const AxisMap& y) {
  using F = ChartFrame;
  std::string out =
      text((F::kLeft + F::kRight) / 2, 22, title, "text-anchor=\"middle\" font-size=\"14\"");
  for (double tick : x.ticks()) {
    out += line(x(tick), F::kTop, x(tick), F::kBottom, "#dddddd");
    out += text(x(tick), F::kBottom + 16, tick_label(tick), "text-anchor=\"middle\"");
  }
  for (double tick : y.ticks()) {
    out += line(F::kLeft, y(tick), F::kRight, y(tick), "#dddddd");
    out += text(F::kLeft - 6, y(tick) + 4, tick_label(tick), "text-anchor=\"end\"");
  }
  out += fmt::format(
      "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>\n",
      px(F::kLeft), px(F::kTop), px(F::kRight - F::kLeft), px(F::kBottom - F::kTop));
  out += text((F::kLeft + F::kRight) / 2, F::kBottom + 40, x_axis.label, "text-anchor=\"middle\"");
  const double mid_y = (F::kTop + F::kBottom) / 2;
  out += text(18, mid_y, y_axis.label,
              fmt::format("text-anchor=\"middle\" transform=\"rotate(-90 18 {})\"", px(mid_y)));
  return out;
}

std::string no_data_chart(const std::string& title) {
  using F = ChartFrame;
  std::string out = svg_open(F::kWidth, F::kHeight);
  out += text(F::kWidth / 2, 22, title, "text-anchor=\"middle\" font-size=\"14\"");
  out += text((F::kLeft + F::kRight) / 2, (F::kTop + F::kBottom) / 2, "no data",
              "text-anchor=\"middle\"");
  return out + "</svg>\n";
}

std::string path_element(const std::string& d, const char* colour, bool dashed) {
  return fmt::format("<path d=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"{}/>\n", d,
                     colour, dash_attribute(dashed));
}

// Builds a path's d attribute, starting a new subpath after a break.
class PathBuilder {
 public:
  void to(double x, double y) {
    d_ += fmt::format("{}{} {} ", broken_ ? "M" : "L", px(x), px(y));
    broken_ = false;
  }
  void lift() { broken_ = true; }
  std::string d() const { return d_.empty() ? d_ : d_.substr(0, d_.size() - 1); }

 private:
  std::string d_;
  bool broken_ = true;
};

void check_sizes(std::size_t a, std::size_t b, const std::string& name, const char* what) {
  if (a != b) {
    throw std::invalid_argument(
        fmt::format("series \"{}\": {} ({} vs {}): give one value per point", name, what, a, b));
  }
}

// Colour map: linear interpolation between five samples of viridis.
std::string colour_at(double t) {
  static constexpr std::array<std::array<double, 3>, 5> kStops = {
      {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}}};
  const double position = std::clamp(t, 0.0, 1.0) * (kStops.size() - 1);
  const std::size_t k = std::min(static_cast<std::size_t>(position), kStops.size() - 2);
  const double f = position - static_cast<double>(k);
  std::array<int, 3> rgb{};
  for (std::size_t c = 0; c < 3; ++c)
    rgb[c] = static_cast<int>(std::lround(kStops[k][c] + f * (kStops[k + 1][c] - kStops[k][c])));
  return fmt::format("#{:02x}{:02x}{:02x}", rgb[0], rgb[1], rgb[2]);
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int max_intervals) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi || max_intervals < 1) {
    throw std::invalid_argument(
        fmt::format("axis range [{}, {}] with at most {} intervals: give finite lo <= hi and "
                    "at least one interval",
                    lo, hi, max_intervals));
  }
  if (lo == hi) {
    const double pad = lo == 0.0 ? 1.0 : 0.1 * std::abs(lo);
    lo -= pad;
    hi += pad;
  }
  int e = static_cast<int>(std::floor(std::log10((hi - lo) / max_intervals)));
  for (int m_index = 0;; ++m_index) {
    static constexpr std::array<int, 3> kMantissas = {1, 2, 5};
    const int m = kMantissas[static_cast<std::size_t>(m_index) % 3];
    if (m_index > 0 && m == 1) ++e;
    const auto first = static_cast<long long>(std::floor(in_steps(lo, m, e) + kStepSlack));
    const auto last = static_cast<long long>(std::ceil(in_steps(hi, m, e) - kStepSlack));
    if (last - first > max_intervals) continue;
    std::vector<double> ticks;
    for (long long k = first; k <= last; ++k) ticks.push_back(tick_value(k, m, e));
    return ticks;
  }
}

std::vector<double> log_ticks(double lo, double hi, int max_intervals) {
  if (!(lo > 0.0) || !std::isfinite(hi) || lo > hi || max_intervals < 1) {
    throw std::invalid_argument(
        fmt::format("log axis range [{}, {}]: give 0 < lo <= hi (finite)", lo, hi));
  }
  const int first = static_cast<int>(std::floor(std::log10(lo) + kStepSlack));
  const int last = std::max(first + 1, static_cast<int>(std::ceil(std::log10(hi) - kStepSlack)));
  const int stride = (last - first + max_intervals - 1) / max_intervals;
  std::vector<double> ticks;
  for (int decade = first;; decade += stride) {
    ticks.push_back(power_of_ten(decade));
    if (decade >= last) return ticks;
  }
}

std::vector<double> axis_ticks(Scale scale, double lo, double hi) {
  return scale == Scale::log ? log_ticks(lo, hi) : nice_ticks(lo, hi);
}

double text_width(std::string_view content, double font_size) {
  return static_cast<double>(content.size()) * kCharWidthEm * font_size;
}

std::string escape_xml(std::string_view raw) {
  std::string out;
  out.reserve(raw.size());
  for (const char c : raw) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

namespace {

// The standard error of point i of a series, when it has one to draw.
std::optional<double> error_of(const Series& series, std::size_t i) {
  if (series.y_error.empty() || !std::isfinite(series.y_error[i]) || series.y_error[i] <= 0.0)
    return std::nullopt;
  return series.y_error[i];
}

// A vertical bar from y_low to y_high (pixels) at x with caps, in the series' colour.
std::string error_bar(double x, double y_low, double y_high, const char* colour) {
  constexpr double kCap = 4;
  std::string out;
  for (const auto& [x1, y1, x2, y2] :
       {std::array{x, y_low, x, y_high}, std::array{x - kCap, y_low, x + kCap, y_low},
        std::array{x - kCap, y_high, x + kCap, y_high}}) {
    out += fmt::format(
        "<line class=\"error-bar\" x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\"/>\n",
        px(x1), px(y1), px(x2), px(y2), colour);
  }
  return out;
}

// A chart being drawn: its axes over the data's ranges, its width (the legend's) and its SVG so
// far.
struct ChartCanvas {
  AxisMap x, y;
  double width;
  std::string svg;
};

// The canvas with the frame, axes and title drawn.
ChartCanvas open_chart(const std::string& title, const Axis& x_axis, const Axis& y_axis,
                       const Range& x_range, const Range& y_range,
                       const std::vector<LegendEntry>& entries) {
  using F = ChartFrame;
  ChartCanvas canvas{.x = AxisMap(x_axis.scale, x_range, F::kLeft, F::kRight),
                     .y = AxisMap(y_axis.scale, y_range, F::kBottom, F::kTop),
                     .width = chart_width(entries),
                     .svg = {}};
  canvas.svg = svg_open(canvas.width, F::kHeight) + axes(title, x_axis, y_axis, canvas.x, canvas.y);
  return canvas;
}

// The figure: the canvas with its legend, closed.
Figure close_chart(const ChartCanvas& canvas, const std::vector<LegendEntry>& entries,
                   std::size_t legend_limit) {
  return {canvas.width, ChartFrame::kHeight,
          canvas.svg + legend(entries, legend_limit) + "</svg>\n"};
}

}  // namespace

Figure line_chart(const LineChart& chart) {
  using F = ChartFrame;
  Range x_range, y_range;
  std::vector<LegendEntry> entries;
  for (std::size_t s = 0; s < chart.series.size(); ++s) {
    const Series& series = chart.series[s];
    check_sizes(series.x.size(), series.y.size(), series.name, "x and y differ in size");
    if (!series.y_error.empty()) {
      check_sizes(series.y_error.size(), series.y.size(), series.name,
                  "y_error and y differ in size");
    }
    bool has_data = false;
    for (std::size_t i = 0; i < series.x.size(); ++i) {
      if (!plottable(series.x[i], chart.x.scale) || !plottable(series.y[i], chart.y.scale))
        continue;
      x_range.add(series.x[i]);
      y_range.add(series.y[i]);
      if (const auto error = error_of(series, i)) {
        for (double end : {series.y[i] - *error, series.y[i] + *error}) {
          if (plottable(end, chart.y.scale)) y_range.add(end);
        }
      }
      has_data = true;
    }
    entries.push_back({series.name, palette(series.colour, s), series.dashed && series.line,
                       series.markers, has_data});
  }
  if (x_range.empty()) return {F::kWidth, F::kHeight, no_data_chart(chart.title)};

  ChartCanvas canvas = open_chart(chart.title, chart.x, chart.y, x_range, y_range, entries);
  const AxisMap &x = canvas.x, &y = canvas.y;
  std::string& out = canvas.svg;
  for (std::size_t s = 0; s < chart.series.size(); ++s) {
    const Series& series = chart.series[s];
    PathBuilder path;
    std::string markers;
    for (std::size_t i = 0; i < series.x.size(); ++i) {
      if (!plottable(series.x[i], chart.x.scale) || !plottable(series.y[i], chart.y.scale)) {
        path.lift();
        continue;
      }
      path.to(x(series.x[i]), y(series.y[i]));
      if (const auto error = error_of(series, i)) {
        const double low = series.y[i] - *error;
        out += error_bar(x(series.x[i]), plottable(low, chart.y.scale) ? y(low) : F::kBottom,
                         y(series.y[i] + *error), entries[s].colour);
      }
      if (series.markers) {
        markers += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"3\" fill=\"{}\"/>\n",
                               px(x(series.x[i])), px(y(series.y[i])), entries[s].colour);
      }
    }
    if (series.line && entries[s].has_data)
      out += path_element(path.d(), entries[s].colour, series.dashed);
    out += markers;
  }
  return close_chart(canvas, entries, chart.legend_limit);
}

Figure histogram_chart(const HistogramChart& chart) {
  using F = ChartFrame;
  auto bin_plottable = [&](const Histogram& h, std::size_t i) {
    return plottable(h.edges[i], chart.x.scale) && plottable(h.edges[i + 1], chart.x.scale) &&
           plottable(h.values[i], chart.y.scale);
  };
  Range x_range, y_range;
  std::vector<LegendEntry> entries;
  for (std::size_t s = 0; s < chart.series.size(); ++s) {
    const Histogram& h = chart.series[s];
    // A series without bins (a sweep point where no cell was counted) is listed, without data.
    if (!h.edges.empty() || !h.values.empty())
      check_sizes(h.edges.size(), h.values.size() + 1, h.name,
                  "edges must be one more than values");
    bool has_data = false;
    for (std::size_t i = 0; i < h.values.size(); ++i) {
      if (!bin_plottable(h, i)) continue;
      x_range.add(h.edges[i]);
      x_range.add(h.edges[i + 1]);
      y_range.add(h.values[i]);
      has_data = true;
    }
    entries.push_back({h.name, palette(h.colour, s), h.dashed, false, has_data});
  }
  if (x_range.empty()) return {F::kWidth, F::kHeight, no_data_chart(chart.title)};

  ChartCanvas canvas = open_chart(chart.title, chart.x, chart.y, x_range, y_range, entries);
  const AxisMap &x = canvas.x, &y = canvas.y;
  std::string& out = canvas.svg;
  for (std::size_t s = 0; s < chart.series.size(); ++s) {
    const Histogram& h = chart.series[s];
    if (!entries[s].has_data) continue;
    PathBuilder path;
    for (std::size_t i = 0; i < h.values.size(); ++i) {
      if (!bin_plottable(h, i)) {
        path.lift();
        continue;
      }
      path.to(x(h.edges[i]), y(h.values[i]));
      path.to(x(h.edges[i + 1]), y(h.values[i]));
    }
    out += path_element(path.d(), entries[s].colour, h.dashed);
  }
  return close_chart(canvas, entries, chart.legend_limit);
}

namespace {

// A label's box on the canvas (x0, y0 top left).
struct Box {
  double x0, y0, x1, y1;
  bool overlaps(const Box& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
};

Box text_box(double x, double baseline, std::string_view content, double font_size) {
  return {x, baseline - kAscentEm * font_size, x + text_width(content, font_size),
          baseline + kDescentEm * font_size};
}

// Site labels beside their markers: the first of a few spots, farther out in steps, where the
// label covers no marker or label placed before it and stays inside `area`.
std::string site_labels(const std::vector<std::pair<double, double>>& at,
                        const std::vector<MapMarker>& markers, const Box& area) {
  constexpr double kFont = 9, kMarker = 4;
  std::vector<Box> taken;
  for (const auto& [x, y] : at)
    taken.push_back({x - kMarker, y - kMarker, x + kMarker, y + kMarker});
  std::string out;
  for (std::size_t k = 0; k < markers.size(); ++k) {
    const auto [x, y] = at[k];
    const double w = text_width(markers[k].label, kFont);
    std::optional<Box> chosen;
    for (double reach = 5; reach <= 60 && !chosen; reach += 7) {
      const double below = reach + kAscentEm * kFont;
      for (const auto& [dx, dy] : {std::pair{reach, -reach},
                                   {reach, below},
                                   {-reach - w, -reach},
                                   {-reach - w, below},
                                   {-w / 2, -reach - kMarker},
                                   {-w / 2, below + kMarker}}) {
        const Box box = text_box(x + dx, y + dy, markers[k].label, kFont);
        const bool inside =
            box.x0 >= area.x0 && box.x1 <= area.x1 && box.y0 >= area.y0 && box.y1 <= area.y1;
        if (!inside || std::any_of(taken.begin(), taken.end(),
                                   [&](const Box& other) { return box.overlaps(other); }))
          continue;
        chosen = box;
        break;
      }
    }
    if (!chosen) chosen = text_box(x + 5, y - 5, markers[k].label, kFont);  // crowded: beside it
    taken.push_back(*chosen);
    if (std::hypot(chosen->x0 - x, chosen->y1 - y) > 16) {  // far out: a leader to its marker
      const double lx = std::clamp(x, chosen->x0, chosen->x1),
                   ly = std::clamp(y, chosen->y0, chosen->y1);
      out += line(x, y, lx, ly, "#555555");
    }
    out += text(chosen->x0, chosen->y1 - kDescentEm * kFont, markers[k].label, "font-size=\"9\"");
  }
  return out;
}

}  // namespace

Figure heat_map(const HeatMap& map) {
  constexpr double kSide = 300, kLeft = 60, kTop = 36, kBarX = kLeft + kSide + 20, kBarWidth = 16;
  constexpr double kTickFont = 10, kHeight = kTop + kSide + 46;
  constexpr int kBarSteps = 32;
  const method::CrossSectionGrid& grid = map.grid;
  if (grid.nx < 1 || grid.ny < 1 || !(grid.half_width > 0.0) || map.values.size() != grid.size() ||
      (!map.blank.empty() && map.blank.size() != grid.size())) {
    throw std::invalid_argument(fmt::format(
        "heat map \"{}\": {} values ({} blank flags) for a {} x {} grid of half width "
        "{}: give one value (and none or one flag) per cell over a grid of positive "
        "size",
        map.title, map.values.size(), map.blank.size(), grid.nx, grid.ny, grid.half_width));
  }
  const double scale = kSide / (2.0 * grid.half_width);
  auto to_x = [&](double x) { return kLeft + (x + grid.half_width) * scale; };
  auto to_y = [&](double y) { return kTop + (grid.half_width - y) * scale; };
  auto shown = [&](std::size_t c) {
    return grid.inside_mill(c) && (map.blank.empty() || !map.blank[c]) &&
           plottable(map.values[c], map.scale);
  };

  Range range;
  for (std::size_t c = 0; c < grid.size(); ++c) {
    if (shown(c)) range.add(map.values[c]);
  }
  std::string body;
  double width = kBarX + 8;
  if (range.empty()) {
    body += text(kLeft + kSide / 2, kTop + kSide / 2, "no data", "text-anchor=\"middle\"");
  } else {
    const AxisMap colour(map.scale, range, 0.0, 1.0);
    body += "<g shape-rendering=\"crispEdges\">\n";
    for (std::size_t c = 0; c < grid.size(); ++c) {
      if (!shown(c)) continue;
      body += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>\n",
                          px(to_x(grid.x_of(c) - grid.dx() / 2)),
                          px(to_y(grid.y_of(c) + grid.dy() / 2)), px(grid.dx() * scale),
                          px(grid.dy() * scale), colour_at(colour(map.values[c])));
    }
    const double step = kSide / kBarSteps;
    for (int k = 0; k < kBarSteps; ++k) {
      body += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>\n",
                          px(kBarX), px(kTop + kSide - (k + 1) * step), px(kBarWidth), px(step),
                          colour_at((k + 0.5) / kBarSteps));
    }
    body += "</g>\n";
    double widest_tick = 0.0;
    for (double tick : colour.ticks()) {
      const double y = kTop + kSide * (1.0 - colour(tick));
      body += line(kBarX + kBarWidth, y, kBarX + kBarWidth + 4, y, "black");
      body += text(kBarX + kBarWidth + 6, y + 4, tick_label(tick), "font-size=\"10\"");
      widest_tick = std::max(widest_tick, text_width(tick_label(tick), kTickFont));
    }
    // The colour bar's title right of its tick labels, reading upwards.
    const double mid_y = kTop + kSide / 2, label_x = kBarX + kBarWidth + 6 + widest_tick + 14;
    body += text(label_x, mid_y, map.quantity,
                 fmt::format("text-anchor=\"middle\" transform=\"rotate(-90 {} {})\"", px(label_x),
                             px(mid_y)));
    width = label_x + 6;
  }
  // Axes in metres along the bottom and the left of the map.
  for (double tick : nice_ticks(-grid.half_width, grid.half_width, 4)) {
    if (std::abs(tick) > grid.half_width * (1 + 1e-9)) continue;
    body += line(to_x(tick), kTop + kSide, to_x(tick), kTop + kSide + 4, "black");
    body += text(to_x(tick), kTop + kSide + 15, tick_label(tick),
                 "text-anchor=\"middle\" font-size=\"10\"");
    body += line(kLeft - 4, to_y(tick), kLeft, to_y(tick), "black");
    body +=
        text(kLeft - 6, to_y(tick) + 4, tick_label(tick), "text-anchor=\"end\" font-size=\"10\"");
  }
  body += fmt::format(
      "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#999999\"/>\n",
      px(kLeft), px(kTop), px(kSide), px(kSide));
  body += text(kLeft + kSide / 2, kTop + kSide + 36, "x (m)", "text-anchor=\"middle\"");
  body += text(
      16, kTop + kSide / 2, "y (m)",
      fmt::format("text-anchor=\"middle\" transform=\"rotate(-90 16 {})\"", px(kTop + kSide / 2)));
  body += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"none\" stroke=\"black\"/>\n",
                      px(to_x(0)), px(to_y(0)), px(kSide / 2));
  std::vector<std::pair<double, double>> at;
  for (const MapMarker& marker : map.markers) {
    at.emplace_back(to_x(marker.x), to_y(marker.y));
    body += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"4\" fill=\"white\" stroke=\"black\"/>\n",
                        px(at.back().first), px(at.back().second));
  }
  body += site_labels(at, map.markers, {kLeft, kTop, kLeft + kSide, kTop + kSide});
  std::string out = svg_open(width, kHeight);
  out += text(kLeft + kSide / 2, 22, map.title, "text-anchor=\"middle\" font-size=\"14\"");
  return {width, kHeight, out + body + "</svg>\n"};
}

Figure category_map(const CategoryMap& map) {
  constexpr double kSide = 300, kLeft = 16, kTop = 36, kLegendX = kLeft + kSide + 24;
  constexpr double kWidth = kLegendX + 130, kHeight = kTop + kSide + 24;
  const method::CrossSectionGrid& grid = map.grid;
  const auto categories = static_cast<int>(map.names.size());
  if (grid.nx < 1 || grid.ny < 1 || !(grid.half_width > 0.0) ||
      map.category.size() != grid.size() ||
      std::any_of(map.category.begin(), map.category.end(),
                  [&](int c) { return c < -1 || c >= categories; })) {
    throw std::invalid_argument(fmt::format(
        "category map \"{}\": {} categories for a {} x {} grid, {} names: give one category per "
        "cell, -1 or an index into the names",
        map.title, map.category.size(), grid.nx, grid.ny, map.names.size()));
  }
  const double scale = kSide / (2.0 * grid.half_width);
  auto to_x = [&](double x) { return kLeft + (x + grid.half_width) * scale; };
  auto to_y = [&](double y) { return kTop + (grid.half_width - y) * scale; };
  auto categorised = [&](int i, int j) {
    return i >= 0 && j >= 0 && i < grid.nx && j < grid.ny && map.category[grid.index(i, j)] >= 0;
  };
  std::string out = svg_open(kWidth, kHeight);
  out += text(kWidth / 2, 22, map.title, "text-anchor=\"middle\" font-size=\"14\"");
  out += "<g shape-rendering=\"crispEdges\">\n";
  std::string outline;
  for (int j = 0; j < grid.ny; ++j) {
    for (int i = 0; i < grid.nx; ++i) {
      if (!categorised(i, j)) continue;
      const double x0 = to_x(grid.x(i) - grid.dx() / 2), x1 = to_x(grid.x(i) + grid.dx() / 2);
      const double y0 = to_y(grid.y(j) - grid.dy() / 2), y1 = to_y(grid.y(j) + grid.dy() / 2);
      out +=
          fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>\n", px(x0),
                      px(y1), px(x1 - x0), px(y0 - y1), palette(map.category[grid.index(i, j)], 0));
      // An edge of the outline wherever the neighbour across it has no category.
      const std::array<std::array<double, 4>, 4> edges = {
          {{x0, y0, x0, y1}, {x1, y0, x1, y1}, {x0, y0, x1, y0}, {x0, y1, x1, y1}}};
      const std::array<bool, 4> open = {!categorised(i - 1, j), !categorised(i + 1, j),
                                        !categorised(i, j - 1), !categorised(i, j + 1)};
      for (std::size_t e = 0; e < edges.size(); ++e) {
        if (!open[e]) continue;
        outline += fmt::format("M{} {}L{} {}", px(edges[e][0]), px(edges[e][1]), px(edges[e][2]),
                               px(edges[e][3]));
      }
    }
  }
  for (int c = 0; c < categories; ++c) {
    const double y = kTop + 8 + 18 * c;
    out += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"12\" height=\"12\" fill=\"{}\"/>\n",
                       px(kLegendX), px(y), palette(c, 0));
  }
  out += "</g>\n";
  for (int c = 0; c < categories; ++c)
    out += text(kLegendX + 18, kTop + 18 + 18 * c, map.names[static_cast<std::size_t>(c)]);
  if (!outline.empty()) {
    out += fmt::format("<path d=\"{}\" fill=\"none\" stroke=\"black\" stroke-width=\"1.5\"/>\n",
                       outline);
  }
  out += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"none\" stroke=\"black\"/>\n",
                     px(to_x(0)), px(to_y(0)), px(kSide / 2));
  for (const MapDisc& disc : map.discs) {
    out += fmt::format(
        "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"none\" stroke=\"black\" "
        "stroke-dasharray=\"4 3\"/>\n",
        px(to_x(disc.x)), px(to_y(disc.y)), px(disc.radius * scale));
    out += text(to_x(disc.x), to_y(disc.y), disc.label,
                "text-anchor=\"middle\" font-size=\"11\" font-weight=\"bold\"");
  }
  for (const MapMarker& marker : map.markers) {
    out += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"4\" fill=\"black\"/>\n", px(to_x(marker.x)),
                       px(to_y(marker.y)));
    out += text(to_x(marker.x) + 6, to_y(marker.y) - 6, marker.label,
                "font-size=\"11\" font-weight=\"bold\"");
  }
  return {kWidth, kHeight, out + "</svg>\n"};
}

Figure panel_grid(const std::vector<Figure>& panels, int columns, const std::string& title) {
  if (columns < 1)
    throw std::invalid_argument(fmt::format("{} panel columns: give at least 1", columns));
  constexpr double kTitle = 32;
  double cell_width = 0.0, cell_height = 0.0;
  for (const Figure& panel : panels) {
    cell_width = std::max(cell_width, panel.width);
    cell_height = std::max(cell_height, panel.height);
  }
  cell_width += kPanelGap;
  const auto count = static_cast<int>(panels.size());
  const int used_columns = std::max(1, std::min(columns, count));
  const int rows = (count + columns - 1) / columns;
  const double width = std::max(used_columns * cell_width, 320.0),
               height = kTitle + rows * cell_height;
  std::string out = svg_open(width, height);
  out += text(width / 2, 22, title, "text-anchor=\"middle\" font-size=\"16\"");
  for (int k = 0; k < count; ++k) {
    out += fmt::format("<g transform=\"translate({} {})\">\n", px((k % columns) * cell_width),
                       px(kTitle + (k / columns) * cell_height));
    out += panels[static_cast<std::size_t>(k)].svg;
    out += "</g>\n";
  }
  return {width, height, out + "</svg>\n"};
}

}  // namespace millflow::report::svg
