#include "report/report.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <stdexcept>

#include "dem/stationarity.hpp"
#include "method/sites.hpp"
#include "report/report_inputs.hpp"
#include "report/report_regions.hpp"
#include "report/svg_plot.hpp"
#include "util/durable_file.hpp"

namespace millflow::report {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The points of one fill and speed (one macro run), by powder load.
struct Slice {
  double fill = 0.0, speed_fraction = 0.0;
  std::vector<const UpscalePoint*> points;

  // The lowest load's point: its sites, macro power draw and coupling check (the media-only cell)
  // are those of every load of the slice.
  const UpscalePoint& first() const { return *points.front(); }
  const UpscalePoint* at_load(double load) const {
    for (const UpscalePoint* point : points) {
      if (point->upscale.powder_load == load) return point;
    }
    return nullptr;
  }
};

std::vector<Slice> slices_of(const std::vector<UpscalePoint>& points) {
  std::vector<Slice> slices;
  for (const UpscalePoint& point : points) {
    const method::UpscaleResult& u = point.upscale;
    if (slices.empty() || slices.back().fill != u.fill ||
        slices.back().speed_fraction != u.speed_fraction) {
      slices.push_back({u.fill, u.speed_fraction, {}});
    }
    slices.back().points.push_back(&point);
  }
  return slices;
}

std::string g(double value) {
  return fmt::format("{:g}", value);
}
std::string slice_label(const Slice& slice) {
  return fmt::format("J = {:g}, phi = {:g}", slice.fill, slice.speed_fraction);
}
std::string maps_file(const Slice& slice) {
  return fmt::format("maps_{:g}_{:g}.svg", slice.fill, slice.speed_fraction);
}

std::vector<double> distinct(const std::vector<UpscalePoint>& points,
                             double method::UpscaleResult::*member) {
  std::set<double> values;
  for (const UpscalePoint& point : points) values.insert(point.upscale.*member);
  return {values.begin(), values.end()};
}

// Panels in rows of fills and columns of speeds.
int speed_columns(const std::vector<UpscalePoint>& points) {
  return static_cast<int>(distinct(points, &method::UpscaleResult::speed_fraction).size());
}

// ---- figures ----

svg::Figure power_draw_figure(const std::vector<UpscalePoint>& points,
                              const std::vector<Slice>& slices) {
  svg::LineChart chart{.title = "Mill power draw",
                       .x = {"speed fraction of critical (-)"},
                       .y = {"power draw of the slice (W)"}};
  // One colour per fill (macro solid, with powder dashed), so the fills tell apart.
  const auto fills = distinct(points, &method::UpscaleResult::fill);
  for (std::size_t f = 0; f < fills.size(); ++f) {
    const double fill = fills[f];
    const int colour = static_cast<int>(f);
    svg::Series macro{.name = fmt::format("J = {:g} macro", fill), .colour = colour};
    std::map<double, svg::Series> with_powder;
    for (const Slice& slice : slices) {
      if (slice.fill != fill) continue;
      macro.x.push_back(slice.speed_fraction);
      macro.y.push_back(slice.first().upscale.mill.power_draw_w);
      for (const UpscalePoint* point : slice.points) {
        if (point->upscale.powder_load <= 0.0) continue;
        svg::Series& series = with_powder[point->upscale.powder_load];
        series.name =
            fmt::format("J = {:g}, U = {:g} with powder", fill, point->upscale.powder_load);
        series.colour = colour;
        series.dashed = true;
        series.x.push_back(slice.speed_fraction);
        series.y.push_back(point->upscale.power_draw_with_powder_w.value_or(kNaN));
      }
    }
    chart.series.push_back(std::move(macro));
    for (auto& [load, series] : with_powder) chart.series.push_back(std::move(series));
  }
  return svg::line_chart(chart);
}

// Index of a region in region_names(), so that a region keeps its colour in every panel.
int region_colour(const std::string& region) {
  const auto& names = method::region_names();
  return static_cast<int>(std::find(names.begin(), names.end(), region) - names.begin());
}

// A region's figure and its standard error (NaN where unknown: no error bar).
struct ValueAndError {
  double value, error;
};

// A region's figure and its standard error, two fields of its figures.
std::function<ValueAndError(const method::UpscaleRegion&)> figure_and_error(
    std::optional<double> method::UpscaleFigures::*value,
    std::optional<double> method::UpscaleFigures::*error) {
  return [value, error](const method::UpscaleRegion& r) {
    return ValueAndError{(r.figures.*value).value_or(kNaN), (r.figures.*error).value_or(kNaN)};
  };
}

// One panel per slice: a quantity of each region vs powder load, with error bars (NaN where a
// point lacks it).
svg::Figure region_panels(const std::vector<UpscalePoint>& points, const std::vector<Slice>& slices,
                          const std::string& title, const std::string& y_label,
                          const std::function<ValueAndError(const method::UpscaleRegion&)>& value) {
  std::vector<svg::Figure> panels;
  for (const Slice& slice : slices) {
    svg::LineChart chart{.title = slice_label(slice), .x = {"powder load U (-)"}, .y = {y_label}};
    for (const std::string& region : method::region_names()) {
      svg::Series series{.name = region, .colour = region_colour(region)};
      bool present = false;
      for (const UpscalePoint* point : slice.points) {
        const auto found =
            std::find_if(point->upscale.cells.regions.begin(), point->upscale.cells.regions.end(),
                         [&](const method::UpscaleRegion& r) { return r.region == region; });
        present = present || found != point->upscale.cells.regions.end();
        const ValueAndError v =
            found == point->upscale.cells.regions.end() ? ValueAndError{kNaN, kNaN} : value(*found);
        series.x.push_back(point->upscale.powder_load);
        series.y.push_back(v.value);
        series.y_error.push_back(v.error);
      }
      if (present) chart.series.push_back(std::move(series));
    }
    panels.push_back(svg::line_chart(chart));
  }
  return svg::panel_grid(panels, speed_columns(points), title);
}

svg::Figure spectra_figure(const std::vector<UpscalePoint>& points,
                           const std::vector<Slice>& slices) {
  std::vector<svg::Figure> panels;
  for (const Slice& slice : slices) {
    svg::HistogramChart chart{
        .title = slice_label(slice),
        .x = {"dissipated energy per collision (J)", svg::Scale::log},
        .y = {"powder collisions per bin in the slice (1/s)", svg::Scale::log}};
    for (const UpscalePoint* point : slice.points) {
      chart.series.push_back({.name = fmt::format("U = {:g}", point->upscale.powder_load),
                              .edges = point->upscale.spectra.bin_edges_j,
                              .values = point->upscale.spectra.powder_rate_per_s});
    }
    panels.push_back(svg::histogram_chart(chart));
  }
  return svg::panel_grid(panels, speed_columns(points), "Powder collision energy spectra");
}

// Toe and shoulder angles of the macro runs vs speed, a colour per fill (toe solid, shoulder
// dashed).
svg::Figure charge_shape_figure(const std::vector<MacroRun>& runs) {
  svg::LineChart chart{.title = "Charge shape: toe and shoulder",
                       .x = {"speed fraction of critical (-)"},
                       .y = {"angle from 3 o'clock, counter-clockwise (deg)"}};
  std::set<double> fills;
  for (const MacroRun& run : runs) fills.insert(run.fill);
  int colour = 0;
  for (const double fill : fills) {
    svg::Series toe{.name = fmt::format("J = {:g} toe", fill), .colour = colour},
        shoulder{.name = fmt::format("J = {:g} shoulder", fill), .colour = colour, .dashed = true};
    for (const MacroRun& run : runs) {
      if (run.fill != fill) continue;
      toe.x.push_back(run.speed_fraction);
      toe.y.push_back(run.toe_angle_deg.value_or(kNaN));
      shoulder.x.push_back(run.speed_fraction);
      shoulder.y.push_back(run.shoulder_angle_deg.value_or(kNaN));
    }
    chart.series.push_back(std::move(toe));
    chart.series.push_back(std::move(shoulder));
    ++colour;
  }
  return svg::line_chart(chart);
}

// Each macro run's collision spectra, a panel per run in rows of fills and columns of speeds;
// a colour per contact type, impact energy solid and dissipated energy dashed.
svg::Figure macro_spectra_figure(const std::vector<MacroRun>& runs) {
  std::vector<svg::Figure> panels;
  std::set<double> speeds;
  for (const MacroRun& run : runs) {
    speeds.insert(run.speed_fraction);
    svg::HistogramChart chart{
        .title = fmt::format("J = {:g}, phi = {:g}", run.fill, run.speed_fraction),
        .x = {"energy per collision (J)", svg::Scale::log},
        .y = {"collisions per bin in the slice (1/s)", svg::Scale::log}};
    for (std::size_t k = 0; k < run.spectra.size(); ++k) {
      chart.series.push_back({.name = run.spectra[k].label,
                              .edges = run.bin_edges_j,
                              .values = run.spectra[k].rate_per_s,
                              .colour = static_cast<int>(k / 2),
                              .dashed = k % 2 == 1});
    }
    panels.push_back(svg::histogram_chart(chart));
  }
  return svg::panel_grid(panels, static_cast<int>(speeds.size()), "Macro collision energy spectra");
}

svg::Figure maps_figure(const Slice& slice, const method::FlowMap& map) {
  std::vector<svg::MapMarker> sites;
  for (const method::UpscaleSite& site : slice.first().upscale.sites)
    sites.push_back({site.x_m, site.y_m, site.site_id});
  // Cells outside the charge (the sites task's rule) hold averages of a few balls in flight.
  std::vector<bool> outside_charge;
  for (double nu : map.solid_fraction)
    outside_charge.push_back(!(nu >= method::RegionRules{}.charge_solid_fraction));
  auto panel = [&](const char* title, const char* quantity, const std::vector<double>& values,
                   svg::Scale scale) {
    return svg::heat_map({.title = title,
                          .quantity = quantity,
                          .grid = map.grid,
                          .values = values,
                          .scale = scale,
                          .markers = sites,
                          .blank = outside_charge});
  };
  return svg::panel_grid(
      {panel("Shear rate", "shear rate (1/s)", map.shear_rate, svg::Scale::linear),
       panel("Normal stress", "normal stress on the shear plane (Pa)", map.normal_stress,
             svg::Scale::linear),
       panel("Dissipation", "dissipation (W/m^3)", map.dissipation, svg::Scale::log)},
      3, "Macro flow, " + slice_label(slice) + ", with the sites");
}

svg::Figure coupling_figure(const std::vector<Slice>& slices) {
  svg::LineChart chart{.title = "Coupling check: media-only cell vs macro shear stress",
                       .x = {"macro shear stress at the site (Pa)", svg::Scale::log},
                       .y = {"media-only cell shear stress (Pa)", svg::Scale::log}};
  // One series per region (its colour in every figure), over every fill and speed.
  double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
  for (const std::string& region : method::region_names()) {
    svg::Series series{.name = region, .colour = region_colour(region), .line = false};
    for (const Slice& slice : slices) {
      for (const method::UpscaleSite& site : slice.first().upscale.sites) {
        if (site.region != region) continue;
        series.x.push_back(site.macro_shear_stress_pa);
        series.y.push_back(site.cell_shear_stress_pa.value_or(kNaN));
        for (double value :
             {site.macro_shear_stress_pa, site.cell_shear_stress_pa.value_or(kNaN)}) {
          if (!std::isfinite(value) || value <= 0.0) continue;
          lo = std::min(lo, value);
          hi = std::max(hi, value);
        }
      }
    }
    if (!series.x.empty()) chart.series.push_back(std::move(series));
  }
  if (lo <= hi) {
    chart.series.push_back({.name = "cell = macro",
                            .x = {lo, hi},
                            .y = {lo, hi},
                            .colour = svg::kPaletteSize - 1,
                            .dashed = true,
                            .markers = false});
  }
  return svg::line_chart(chart);
}

// ---- tables ----

std::string number(double value) {
  return fmt::format("{}", value);
}
std::string number(const std::optional<double>& value) {
  return value ? number(*value) : std::string();
}

std::string csv_text(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string csv_row(const std::vector<std::string>& cells) {
  std::string row;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    if (i > 0) row += ',';
    row += csv_text(cells[i]);
  }
  return row + "\n";
}

std::vector<std::string> point_cells(const UpscalePoint& p) {
  return {number(p.upscale.fill), number(p.upscale.speed_fraction), number(p.upscale.powder_load)};
}

template <class Rows>
std::string csv_table(const std::vector<std::string>& header,
                      const std::vector<UpscalePoint>& points, Rows rows_of) {
  std::string out = csv_row(header);
  for (const UpscalePoint& point : points) {
    for (std::vector<std::string> cells : rows_of(point)) {
      const auto head = point_cells(point);
      cells.insert(cells.begin(), head.begin(), head.end());
      cells.push_back(point.task_key);
      out += csv_row(cells);
    }
  }
  return out;
}

std::string upscaled_csv(const std::vector<UpscalePoint>& points) {
  return csv_table(
      {"fill", "speed_fraction", "powder_load", "region", "sites", "volume_m3", "powder_power_w",
       "powder_power_share", "powder_power_share_se", "media_power_w", "media_collision_power_w",
       "media_collision_power_no_powder_w", "cushioning", "cushioning_se", "power_draw_w",
       "power_draw_with_powder_w", "dominant_region", "upscale_task"},
      points, [](const UpscalePoint& p) {
        std::vector<std::vector<std::string>> rows;
        for (const method::UpscaleRegion& r : p.upscale.cells.regions) {
          const method::UpscaleFigures& f = r.figures;
          rows.push_back({r.region, fmt::format("{}", f.sites), number(f.volume_m3),
                          number(f.powder_power_w), number(f.powder_power_share),
                          number(f.powder_power_share_se), number(f.media_power_w),
                          number(f.media_collision_power_w),
                          number(f.media_collision_power_no_powder_w), number(f.cushioning),
                          number(f.cushioning_se), number(p.upscale.mill.power_draw_w),
                          number(p.upscale.power_draw_with_powder_w),
                          p.upscale.cells.dominant_region.value_or("")});
        }
        return rows;
      });
}

std::string sites_csv(const std::vector<UpscalePoint>& points) {
  return csv_table(
      {"fill", "speed_fraction", "powder_load", "site_id", "region", "x_m", "y_m", "weight_m3",
       "shear_rate_per_s", "normal_stress_pa", "macro_shear_stress_pa", "cell_shear_stress_pa",
       "coupling_ratio", "power_density_w_m3", "powder_dissipation_w_m3", "cell_normal_stress_pa",
       "skipped", "upscale_task"},
      points, [](const UpscalePoint& p) {
        std::vector<std::vector<std::string>> rows;
        for (const method::UpscaleSite& s : p.upscale.sites) {
          rows.push_back({s.site_id, s.region, number(s.x_m), number(s.y_m), number(s.weight_m3),
                          number(s.shear_rate_per_s), number(s.normal_stress_pa),
                          number(s.macro_shear_stress_pa), number(s.cell_shear_stress_pa),
                          number(s.coupling_ratio), number(s.power_density_w_m3),
                          number(s.powder_dissipation_w_m3), number(s.cell_normal_stress_pa),
                          s.skipped.value_or("")});
        }
        return rows;
      });
}

std::string spectra_csv(const std::vector<UpscalePoint>& points) {
  return csv_table({"fill", "speed_fraction", "powder_load", "bin", "energy_low_j", "energy_high_j",
                    "powder_rate_per_s", "media_rate_per_s", "upscale_task"},
                   points, [](const UpscalePoint& p) {
                     std::vector<std::vector<std::string>> rows;
                     const method::UpscaleSpectra& s = p.upscale.spectra;
                     for (std::size_t b = 0; b < s.powder_rate_per_s.size(); ++b) {
                       rows.push_back({fmt::format("{}", b), number(s.bin_edges_j[b]),
                                       number(s.bin_edges_j[b + 1]), number(s.powder_rate_per_s[b]),
                                       number(s.media_rate_per_s[b])});
                     }
                     return rows;
                   });
}

// ---- the page ----

std::string md(double value) {
  return fmt::format("{:.4g}", value);
}

std::string md(const std::optional<double>& value) {
  return value ? md(*value) : std::string("-");
}

std::string points_table(const std::vector<UpscalePoint>& points) {
  std::string out =
      "| fill J | speed phi | powder load U | power draw (W) | with powder (W) | powder power (W) "
      "| media power (W) | "
      "dominant region |\n|---|---|---|---|---|---|---|---|\n";
  for (const UpscalePoint& point : points) {
    const method::UpscaleResult& p = point.upscale;
    out += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} |\n", g(p.fill),
                       g(p.speed_fraction), g(p.powder_load), md(p.mill.power_draw_w),
                       md(p.power_draw_with_powder_w), md(p.cells.totals.powder_power_w),
                       md(p.cells.totals.media_power_w), p.cells.dominant_region.value_or("-"));
  }
  return out;
}

// The points whose every cell was left out (or never ran): their powers are unknown ("-" above)
// and their plots hold no data.
std::string uncounted_points_paragraph(const std::vector<UpscalePoint>& points) {
  std::vector<std::string> uncounted;
  for (const UpscalePoint& point : points) {
    const method::UpscaleResult& p = point.upscale;
    if (p.cells.totals.powder_power_w) continue;
    uncounted.push_back(fmt::format("J = {}, phi = {}, U = {} ({} cells left out)", g(p.fill),
                                    g(p.speed_fraction), g(p.powder_load),
                                    p.left_out_cells.size()));
  }
  if (uncounted.empty()) return {};
  return fmt::format(
      "No cell was counted at {}: every cell there was left out as unsteady or unconverged, or "
      "none ran (sites.csv's `skipped` says which), so their powder power, shares and spectra "
      "are unknown. Longer warm-up or measurement strains "
      "(`/shear_cell/max_warmup_strain`, `/shear_cell/convergence/max_strain`) or "
      "`/upscale/include_unsteady` count them.\n\n",
      fmt::join(uncounted, "; "));
}

// How far a cell's held normal stress (its measured p_yy) may sit from its site's before the
// report names it: the stationarity test's own tolerance for each warm-up window
// (docs/shear_cells.md).
constexpr double kHeldStressTolerance = dem::StationarityCriterion{}.tolerance;

// The cells (one per point and site) whose measured normal stress missed their site's by more
// than kHeldStressTolerance: their friction and powder figures are of another state
// (docs/cell_validation.md, "Found on the way").
std::string held_stress_paragraph(const std::vector<UpscalePoint>& points) {
  std::size_t cells = 0;
  std::vector<std::string> missed;
  for (const UpscalePoint& point : points) {
    for (const method::UpscaleSite& site : point.upscale.sites) {
      if (!site.cell_normal_stress_pa || !(site.normal_stress_pa > 0.0)) continue;
      ++cells;
      const double held = *site.cell_normal_stress_pa / site.normal_stress_pa;
      if (std::abs(held - 1.0) <= kHeldStressTolerance) continue;
      missed.push_back(fmt::format("{} at J = {}, phi = {}, U = {} ({:+.0f}%)", site.site_id,
                                   g(point.upscale.fill), g(point.upscale.speed_fraction),
                                   g(point.upscale.powder_load), 100.0 * (held - 1.0)));
    }
  }
  if (cells == 0) return {};
  std::string out = fmt::format(
      "Normal stress held: {} of {} cells held their site's normal stress within {:g}% over the "
      "measured window (sites.csv, cell_normal_stress_pa against normal_stress_pa)",
      cells - missed.size(), cells, 100.0 * kHeldStressTolerance);
  if (missed.empty()) return out + ".\n";
  return out + fmt::format(
                   "; the others measured a state of another stress, their friction and powder "
                   "figures with it: {}.\n",
                   fmt::join(missed, "; "));
}

std::string coupling_table(const std::vector<Slice>& slices) {
  std::string out =
      "| fill J | speed phi | sites compared | within tolerance | median cell/macro | tolerance |\n"
      "|---|---|---|---|---|---|\n";
  for (const Slice& slice : slices) {
    const method::UpscaleCoupling& c = slice.first().upscale.coupling;
    out += fmt::format("| {} | {} | {} | {} | {} | {} |\n", g(slice.fill), g(slice.speed_fraction),
                       c.sites, c.within_tolerance, c.median_ratio ? md(*c.median_ratio) : "n/a",
                       md(c.tolerance));
  }
  return out;
}

// A relative shift as a signed percentage with its standard error, "-" without one.
std::string percent(const std::optional<double>& value, const std::optional<double>& se) {
  if (!value) return "-";
  return fmt::format("{:+.1f}% ({})", 100.0 * *value,
                     se ? fmt::format("+- {:.1f}%", 100.0 * *se) : "no standard error");
}

// What a shift says about the default cells (docs/method.md, "Stiffness sensitivity"): beyond
// twice its standard error it is a systematic error the error bars do not carry; within, the
// stiffness is not resolved at this precision, which is not to say it does not matter.
std::string shift_reading(const std::optional<double>& value, const std::optional<double>& se) {
  if (!value) return "not measured";
  if (!se) return "without a standard error to judge it by";
  return std::abs(*value) > 2.0 * *se
             ? "beyond twice its standard error: a systematic error the error bars do not carry"
             : "within twice its standard error: not resolved at this precision";
}

std::string stiffness_row(const method::UpscaleResult& p, const std::string& region,
                          const method::StiffnessFigures& f) {
  return fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", g(p.fill),
                     g(p.speed_fraction), g(p.powder_load), region, f.sites, md(f.cushioning),
                     md(f.cushioning_stiff), percent(f.cushioning_shift, f.cushioning_shift_se),
                     md(f.powder_share), md(f.powder_share_stiff),
                     percent(f.powder_share_shift, f.powder_share_shift_se));
}

// Per point with stiff cells a sentence, and a table by region (empty without stiff cells).
std::string stiffness_section(const std::vector<UpscalePoint>& points) {
  std::string sentences, rows;
  for (const UpscalePoint& point : points) {
    const method::UpscaleResult& p = point.upscale;
    if (!p.stiffness_sensitivity) continue;
    const method::StiffnessSensitivity& s = *p.stiffness_sensitivity;
    const std::string point_label = fmt::format("- J = {}, phi = {}, U = {}: ", g(p.fill),
                                                g(p.speed_fraction), g(p.powder_load));
    if (s.totals.sites == 0) {
      sentences +=
          point_label + fmt::format(
                            "no site has both a default and a {:g} x stiffer cell that count "
                            "({} stiff cells left out as unsteady or unconverged).\n",
                            s.factor, s.left_out_cells.size());
      continue;
    }
    const method::StiffnessFigures& t = s.totals;
    sentences +=
        point_label +
        fmt::format(
            "with the powder pairs {:g} x stiffer, cushioning moves by {} and the powder "
            "share by {} (over {} site{}); the cushioning's shift is {}, the share's {}.\n",
            s.factor, percent(t.cushioning_shift, t.cushioning_shift_se),
            percent(t.powder_share_shift, t.powder_share_shift_se), t.sites,
            t.sites == 1 ? "" : "s", shift_reading(t.cushioning_shift, t.cushioning_shift_se),
            shift_reading(t.powder_share_shift, t.powder_share_shift_se));
    for (const auto& [region, figures] : s.regions) rows += stiffness_row(p, region, figures);
    rows += stiffness_row(p, "all", s.totals);
  }
  if (sentences.empty()) return {};
  return "## Stiffness sensitivity\n\n"
         "The shear cells' powder contacts are only as stiff as the stiffness policy makes them, "
         "and cushioning and the powder's share of the cells' power move with that stiffness "
         "(docs/shear_cells.md, \"Stiffness policy\"). Extra cells at the first sites of some "
         "regions ran with the powder pairs stiffer; comparing them with the default cells at "
         "the same sites gives the shift below, stiff / default - 1 with its standard error. "
         "Beyond twice its standard error a shift is a systematic error of the figures above "
         "that their error bars do not carry; within it the stiffness is not resolved at this "
         "precision, which is not to say it does not matter (docs/method.md, \"Stiffness "
         "sensitivity\"). The powder share here is the powder's share of the power put into the "
         "cells.\n\n" +
         sentences +
         "\n| fill J | speed phi | powder load U | region | sites | cushioning | stiff | shift | "
         "powder share | stiff | shift |\n|---|---|---|---|---|---|---|---|---|---|---|\n" +
         rows + "\n";
}

std::string index_page(const std::string& campaign, const std::vector<UpscalePoint>& points,
                       const std::vector<Slice>& slices, bool with_macro_runs) {
  std::string out = fmt::format("# Campaign report: {}\n\n", campaign);
  out += fmt::format(
      "{} upscaled points: fills J = {}; speed fractions phi = {}; powder loads U = {}.\n\n",
      points.size(), fmt::join(distinct(points, &method::UpscaleResult::fill), ", "),
      fmt::join(distinct(points, &method::UpscaleResult::speed_fraction), ", "),
      fmt::join(distinct(points, &method::UpscaleResult::powder_load), ", "));
  out +=
      "## Power draw\n\n![power draw vs speed](power_draw.svg)\n\n"
      "Power draw of the mill slice vs the speed as a fraction of the critical speed, one solid "
      "line per fill "
      "(the macro DEM run, balls only) and one dashed line per fill and powder load (the draw "
      "including the "
      "powder's effect, from the upscaled shear cells).\n\n";
  out +=
      "## Points\n\nThe dominant region is the region taking the largest share of the powder "
      "power; it is computed from the shear cells, not assumed: each cell's powder dissipation per "
      "volume times the volume its site stands for, summed per region. The macro-anchored "
      "upscaling, which takes each region's "
      "dissipation from the macro run and only its split from the cells, may name another "
      "(\"Flow regions\" below gives both).\n\n" +
      points_table(points) + "\n" + uncounted_points_paragraph(points);
  out +=
      "## Powder power by region\n\n![powder power shares](powder_power_shares.svg)\n\n"
      "Each region's share of the power going into the powder (site power densities x site "
      "weights), vs the "
      "powder load; one panel per fill (rows) and speed (columns). Error bars: +- one standard "
      "error from the cells' batch means (none where a cell has no standard error).\n\n";
  out +=
      "## Cushioning\n\n![cushioning](cushioning.svg)\n\n"
      "Media-media collision power with powder divided by the same without powder, per region: "
      "below 1 the powder "
      "cushions the ball collisions; error bars as above.\n\n";
  out += stiffness_section(points);
  out +=
      "## Powder collision energy spectra\n\n![powder spectra](powder_spectra.svg)\n\n"
      "Powder collisions per second in the mill slice in each bin of dissipated energy per "
      "collision (log-log), one "
      "step line per powder load.\n\n";
  if (with_macro_runs) {
    out +=
        "## Charge shape\n\n![charge shape](charge_shape.svg)\n\n"
        "Toe and shoulder of the charge in each macro run (the ends of the arc where the balls "
        "touch the shell), in degrees counter-clockwise from 3 o'clock, vs the speed fraction; "
        "one colour per fill, the toe solid and the shoulder dashed.\n\n"
        "## Macro collision energy spectra\n\n![macro spectra](macro_spectra.svg)\n\n"
        "Ball-ball and ball-liner collisions per second in the mill slice in each bin of impact "
        "energy (solid) and dissipated energy (dashed) per collision, log-log, one panel per "
        "macro run.\n\n";
  }
  out +=
      "## Flow maps\n\nShear rate, normal stress on the shear plane and energy dissipation density "
      "of the averaged "
      "macro flow over the mill cross-section; the circles are the sites where the shear cells "
      "ran.\n\n";
  for (const Slice& slice : slices)
    out += fmt::format("### {}\n\n![flow maps]({})\n\n", slice_label(slice), maps_file(slice));
  out +=
      "## Coupling check\n\n![coupling](coupling.svg)\n\n"
      "A media-only shear cell driven by a site's shear rate and normal stress should reproduce "
      "the macro run's "
      "shear stress there; the points should lie near the dashed 1:1 line.\n\n" +
      coupling_table(slices) + "\n" + held_stress_paragraph(points) + "\n";
  out +=
      "## Tables\n\n"
      "- [upscaled.csv](upscaled.csv): one row per point and region (powers, shares, cushioning).\n"
      "- [sites.csv](sites.csv): one row per point and site (macro state, cell results, coupling "
      "ratio).\n"
      "- [spectra.csv](spectra.csv): one row per point and energy bin (powder and media collision "
      "rates).\n";
  return out;
}

json result_of(const std::string& campaign, const std::vector<UpscalePoint>& points,
               const std::vector<Slice>& slices, const std::vector<std::string>& files) {
  json dominant = json::array();
  for (const UpscalePoint& point : points) {
    const method::UpscaleResult& p = point.upscale;
    dominant.push_back(
        {{"fill", p.fill},
         {"speed_fraction", p.speed_fraction},
         {"powder_load", p.powder_load},
         {"region", p.cells.dominant_region ? json(*p.cells.dominant_region) : json(nullptr)}});
  }
  std::size_t sites = 0, within = 0;
  for (const Slice& slice : slices) {
    sites += slice.first().upscale.coupling.sites;
    within += slice.first().upscale.coupling.within_tolerance;
  }
  return {{"campaign", campaign},
          {"files", files},
          {"points", points.size()},
          {"slices", slices.size()},
          {"dominant_regions", dominant},
          {"coupling", {{"sites", sites}, {"within_tolerance", within}}}};
}

// Writes files into one directory and remembers them in order.
class ReportWriter {
 public:
  explicit ReportWriter(fs::path dir) : dir_(std::move(dir)) { fs::create_directories(dir_); }

  void write(const std::string& name, const std::string& text) {
    const fs::path file = dir_ / name;
    util::write_file_durably(file, text);
    names_.push_back(name);
  }
  const std::vector<std::string>& names() const { return names_; }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
  std::vector<std::string> names_;
};

}  // namespace

ReportFiles write_report(const std::filesystem::path& dir, const std::string& campaign,
                         const ReportInputs& inputs, const RegionSection& regions) {
  const std::vector<UpscalePoint>& points = inputs.points;
  const std::vector<Slice> slices = slices_of(points);

  ReportWriter out(dir);
  out.write("power_draw.svg", power_draw_figure(points, slices).svg);
  out.write("powder_power_shares.svg",
            region_panels(points, slices, "Share of the powder power by region",
                          "share of the powder power (-)",
                          figure_and_error(&method::UpscaleFigures::powder_power_share,
                                           &method::UpscaleFigures::powder_power_share_se))
                .svg);
  out.write("cushioning.svg",
            region_panels(points, slices, "Cushioning of media collisions by the powder",
                          "media collision power with / without powder (-)",
                          figure_and_error(&method::UpscaleFigures::cushioning,
                                           &method::UpscaleFigures::cushioning_se))
                .svg);
  out.write("powder_spectra.svg", spectra_figure(points, slices).svg);
  const bool with_macro_runs = !inputs.macro_runs.empty();
  if (with_macro_runs) {
    out.write("charge_shape.svg", charge_shape_figure(inputs.macro_runs).svg);
    out.write("macro_spectra.svg", macro_spectra_figure(inputs.macro_runs).svg);
  }
  for (const Slice& slice : slices)
    out.write(maps_file(slice),
              maps_figure(slice, inputs.flow_maps.at(slice.first().upscale.average_task)).svg);
  for (const auto& [name, svg] : regions.files) out.write(name, svg);
  out.write("coupling.svg", coupling_figure(slices).svg);
  out.write("upscaled.csv", upscaled_csv(points));
  out.write("sites.csv", sites_csv(points));
  out.write("spectra.csv", spectra_csv(points));
  out.write("index.md",
            index_page(campaign, points, slices, with_macro_runs) + "\n" + regions.markdown);
  return {.result = result_of(campaign, points, slices, out.names()),
          .names = out.names(),
          .slices = slices.size()};
}

}  // namespace millflow::report
