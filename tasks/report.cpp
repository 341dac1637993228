#include "tasks/report.hpp"

#include <algorithm>
#include <fstream>
#include <map>
#include <tuple>

#include <fmt/format.h>

#include "tasks/kinds.hpp"
#include "tasks/svg_plot.hpp"
#include "tasks/upscale.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

struct Point {
  double fill, speed, load;
  const json* result;
};

std::string point_name(double fill, double speed) { return fmt::format("J{:g}_N{:g}", fill, speed); }

double number_or_nan(const json& value) { return value.is_number() ? value.get<double>() : std::nan(""); }

std::string cell(const json& value) {
  if (value.is_null()) return "";
  if (value.is_number()) return fmt::format("{:.6g}", value.get<double>());
  return value.is_string() ? value.get<std::string>() : value.dump();
}

std::vector<Point> sorted_points(const engine::TaskContext& context) {
  std::vector<Point> points;
  for (const auto& input : context.inputs) {
    if (input.kind != "upscale") continue;
    const json& r = input.result;
    points.push_back({r.at("fill").get<double>(), r.at("speed_fraction").get<double>(), r.at("powder_load").get<double>(), &r});
  }
  if (points.empty()) throw std::invalid_argument(fmt::format("report {}: no upscale inputs", context.key));
  std::sort(points.begin(), points.end(), [](const Point& a, const Point& b) {
    return std::tie(a.fill, a.speed, a.load) < std::tie(b.fill, b.speed, b.load);
  });
  return points;
}

// Points grouped by (fill, speed), loads ascending.
std::map<std::pair<double, double>, std::vector<Point>> by_fill_and_speed(const std::vector<Point>& points) {
  std::map<std::pair<double, double>, std::vector<Point>> groups;
  for (const Point& p : points) groups[{p.fill, p.speed}].push_back(p);
  return groups;
}

class ReportWriter {
 public:
  explicit ReportWriter(std::filesystem::path dir) : dir_(std::move(dir)) { std::filesystem::create_directories(dir_); }

  void write(const std::string& name, const std::string& text) {
    const auto file = dir_ / name;
    const auto temporary = dir_ / (name + ".tmp");
    {
      std::ofstream out(temporary, std::ios::binary);
      out << text;
      if (!out.flush()) throw std::runtime_error("could not write " + temporary.string());
    }
    std::filesystem::rename(temporary, file);
    files_.push_back({name, file});
  }

  const std::vector<engine::ProducedArtifact>& files() const { return files_; }

 private:
  std::filesystem::path dir_;
  std::vector<engine::ProducedArtifact> files_;
};

std::string power_draw_chart(const std::vector<Point>& points) {
  std::map<double, PlotSeries> macro;
  std::map<std::pair<double, double>, PlotSeries> with_powder;
  for (const Point& p : points) {
    PlotSeries& balls = macro[p.fill];
    if (balls.x.empty() || balls.x.back() != p.speed) {
      balls.name = fmt::format("J = {:g}, balls only", p.fill);
      balls.x.push_back(p.speed);
      balls.y.push_back(p.result->at("mill").at("power_draw_w").get<double>());
    }
    if (p.load == 0.0) continue;
    PlotSeries& powder = with_powder[{p.fill, p.load}];
    powder.name = fmt::format("J = {:g}, U = {:g}", p.fill, p.load);
    powder.dashed = true;
    powder.x.push_back(p.speed);
    powder.y.push_back(number_or_nan(p.result->at("power_draw_with_powder_w")));
  }
  std::vector<PlotSeries> series;
  for (auto& [fill, s] : macro) series.push_back(std::move(s));
  for (auto& [key, s] : with_powder) series.push_back(std::move(s));
  return line_chart({"Power draw of the mill slice", "speed, fraction of critical", "power draw (W)"}, series);
}

// One series per region of `field` of the point's regions against powder load.
std::string region_chart(const std::vector<Point>& loads, const std::string& field, const PlotAxes& axes) {
  std::map<std::string, PlotSeries> regions;
  for (const Point& p : loads) {
    for (const json& region : p.result->at("regions")) {
      PlotSeries& s = regions[region.at("region").get<std::string>()];
      s.name = region.at("region").get<std::string>();
      s.x.push_back(p.load);
      s.y.push_back(number_or_nan(region.at(field)));
    }
  }
  std::vector<PlotSeries> series;
  for (auto& [name, s] : regions) series.push_back(std::move(s));
  return line_chart(axes, series);
}

std::string spectra_chart(const std::vector<Point>& loads, const std::string& title) {
  std::vector<PlotSeries> series;
  for (const Point& p : loads) {
    const json& spectra = p.result->at("spectra");
    const auto edges = spectra.at("bin_edges_j").get<std::vector<double>>();
    const auto rates = spectra.at("powder_rate_per_s").get<std::vector<double>>();
    PlotSeries s{.name = fmt::format("U = {:g}", p.load), .x = {}, .y = {}};
    for (std::size_t k = 0; k < rates.size(); ++k) {
      s.x.push_back(std::sqrt(edges[k] * edges[k + 1]));  // the bin's geometric centre
      s.y.push_back(rates[k]);
    }
    series.push_back(std::move(s));
  }
  return line_chart({title, "energy dissipated per collision (J)", "powder collisions per second", true, true}, series);
}

std::string upscaled_csv(const std::vector<Point>& points) {
  std::string csv =
      "fill,speed_fraction,powder_load,region,sites,volume_m3,powder_power_w,powder_power_share,media_power_w,"
      "media_collision_power_w,media_collision_power_no_powder_w,cushioning,power_draw_w,power_draw_with_powder_w\n";
  for (const Point& p : points) {
    for (const json& r : p.result->at("regions")) {
      csv += fmt::format("{:g},{:g},{:g},{},{},{},{},{},{},{},{},{},{},{}\n", p.fill, p.speed, p.load,
                         cell(r.at("region")), cell(r.at("sites")), cell(r.at("volume_m3")), cell(r.at("powder_power_w")),
                         cell(r.at("powder_power_share")), cell(r.at("media_power_w")),
                         cell(r.at("media_collision_power_w")), cell(r.at("media_collision_power_no_powder_w")),
                         cell(r.at("cushioning")), cell(p.result->at("mill").at("power_draw_w")),
                         cell(p.result->at("power_draw_with_powder_w")));
    }
  }
  return csv;
}

std::string sites_csv(const std::vector<Point>& points) {
  const std::vector<std::string> columns = {"site_id",          "region",           "x_m",
                                            "y_m",              "weight_m3",        "shear_rate_per_s",
                                            "normal_stress_pa", "macro_shear_stress_pa", "cell_shear_stress_pa",
                                            "coupling_ratio",   "power_density_w_m3", "powder_dissipation_w_m3",
                                            "skipped"};
  std::string csv = "fill,speed_fraction,powder_load," + fmt::format("{}\n", fmt::join(columns, ","));
  for (const Point& p : points) {
    for (const json& site : p.result->at("sites")) {
      std::vector<std::string> row;
      for (const auto& column : columns) row.push_back(cell(site.at(column)));
      csv += fmt::format("{:g},{:g},{:g},{}\n", p.fill, p.speed, p.load, fmt::join(row, ","));
    }
  }
  return csv;
}

std::string spectra_csv(const std::vector<Point>& points) {
  std::string csv = "fill,speed_fraction,powder_load,bin_low_j,bin_high_j,powder_rate_per_s,media_rate_per_s\n";
  for (const Point& p : points) {
    const json& s = p.result->at("spectra");
    const json& edges = s.at("bin_edges_j");
    for (std::size_t k = 0; k + 1 < edges.size(); ++k) {
      csv += fmt::format("{:g},{:g},{:g},{},{},{},{}\n", p.fill, p.speed, p.load, cell(edges.at(k)), cell(edges.at(k + 1)),
                         cell(s.at("powder_rate_per_s").at(k)), cell(s.at("media_rate_per_s").at(k)));
    }
  }
  return csv;
}

std::string summary_table(const std::vector<Point>& points) {
  std::string table =
      "| fill | speed | powder load | power draw (W) | with powder (W) | powder power (W) | dominant region | "
      "cushioning | coupling: median cell/macro shear stress (sites within tolerance) |\n"
      "|---|---|---|---|---|---|---|---|---|\n";
  for (const Point& p : points) {
    const json& r = *p.result;
    table += fmt::format("| {:g} | {:g} | {:g} | {} | {} | {} | {} | {} | {} ({} of {}) |\n", p.fill, p.speed, p.load,
                         cell(r.at("mill").at("power_draw_w")), cell(r.at("power_draw_with_powder_w")),
                         cell(r.at("powder_power_w")), r.at("dominant_region").is_null() ? "-" : cell(r.at("dominant_region")),
                         cell(r.at("cushioning")), cell(r.at("coupling").at("median_ratio")),
                         cell(r.at("coupling").at("within_tolerance")), cell(r.at("coupling").at("sites")));
  }
  return table;
}

}  // namespace

engine::TaskOutcome run_report(engine::TaskContext& context) {
  const std::string campaign = context.params.at("campaign").get<std::string>();
  const std::vector<Point> points = sorted_points(context);
  ReportWriter out(context.work_dir);
  out.write("power_draw.svg", power_draw_chart(points));
  std::string figures;
  for (const auto& [fill_speed, loads] : by_fill_and_speed(points)) {
    const auto [fill, speed] = fill_speed;
    const std::string name = point_name(fill, speed);
    const std::string where = fmt::format("J = {:g}, {:g} of critical speed", fill, speed);
    out.write("shares_" + name + ".svg",
              region_chart(loads, "powder_power_share",
                           {"Share of the powder power by region, " + where, "powder load U", "share of powder power"}));
    out.write("cushioning_" + name + ".svg",
              region_chart(loads, "cushioning",
                           {"Cushioning by region, " + where, "powder load U", "media collision power / without powder"}));
    out.write("spectra_" + name + ".svg", spectra_chart(loads, "Powder collision energy spectra, " + where));
    figures += fmt::format("### {}\n\n![shares](shares_{}.svg)\n![cushioning](cushioning_{}.svg)\n![spectra](spectra_{}.svg)\n\n",
                           where, name, name, name);
  }
  out.write("upscaled.csv", upscaled_csv(points));
  out.write("sites.csv", sites_csv(points));
  out.write("spectra.csv", spectra_csv(points));
  out.write("index.md",
            fmt::format(
                "# millflow report: {}\n\n"
                "{} points (fill x speed x powder load). Formulas: tasks/upscale.hpp. Tables: "
                "[upscaled.csv](upscaled.csv) (point x region), [sites.csv](sites.csv) (point x site, with the "
                "coupling check), [spectra.csv](spectra.csv).\n\n"
                "## Summary\n\n"
                "Power draw: the macro DEM run (balls only) and the same scaled by the shear cells' power input "
                "with / without powder. Cushioning: media-media collision power with powder over without (below 1: "
                "the powder cushions the balls). Coupling: a media-only shear cell at each site's shear rate and "
                "normal stress against the macro flow's shear stress there (tolerance {:g} relative).\n\n{}\n"
                "## Power draw\n\n![power draw](power_draw.svg)\n\n"
                "## Per fill and speed: powder power by region, cushioning, powder collision spectra\n\n{}",
                campaign, points.size(), kCouplingTolerance, summary_table(points), figures));
  engine::TaskOutcome outcome;
  json files = json::array();
  for (const auto& file : out.files()) files.push_back(file.name);
  outcome.result = {{"campaign", campaign}, {"points", points.size()}, {"files", files}};
  outcome.artifacts = out.files();
  context.log(fmt::format("report of {}: {} points, {} files", campaign, points.size(), files.size()));
  return outcome;
}

void register_report(engine::Registry& registry) {
  registry.kinds.add(engine::TaskKind{.name = "report", .version = kReportVersion, .run = run_report});
}

}  // namespace millflow::tasks
