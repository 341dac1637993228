#include "tasks/upscale.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "tasks/kinds.hpp"
#include "tasks/sites.hpp"

namespace millflow::tasks {
namespace {

using nlohmann::json;

const engine::TaskInput& only_input(const engine::TaskContext& context, const std::string& kind) {
  const engine::TaskInput* found = nullptr;
  for (const auto& input : context.inputs) {
    if (input.kind != kind) continue;
    if (found)
      throw std::invalid_argument(
          fmt::format("upscale {}: more than one {} input", context.key, kind));
    found = &input;
  }
  if (!found)
    throw std::invalid_argument(fmt::format("upscale {}: no {} input", context.key, kind));
  return *found;
}

// Finished (not skipped) cells at one powder load, by site id.
std::map<std::string, const json*> cells_at_load(const engine::TaskContext& context, double load) {
  std::map<std::string, const json*> cells;
  for (const auto& input : context.inputs) {
    if (input.kind != "shear_cell" || input.result.contains("skipped")) continue;
    if (input.result.at("powder_load").get<double>() != load) continue;
    cells[input.result.at("site").at("site_id").get<std::string>()] = &input.result;
  }
  return cells;
}

const json* cell_of(const std::map<std::string, const json*>& cells, const std::string& site_id) {
  const auto found = cells.find(site_id);
  return found == cells.end() ? nullptr : found->second;
}

double powder_dissipation(const json& cell) {
  return cell.at("powder_dissipation_w_m3").get<double>();
}
double power_input(const json& cell) {
  return cell.at("power_density_w_m3").get<double>();
}
double media_collision_dissipation(const json& cell) {
  const json& d = cell.at("dissipation_w_m3");
  return d.at("media-media").get<double>() + d.at("wall-media").get<double>();
}

json ratio_or_null(double numerator, double denominator) {
  return denominator > 0.0 ? json(numerator / denominator) : json(nullptr);
}

// Sums over the sites of one region (or of all), W in the simulated slice.
struct PowerSums {
  int sites = 0;
  double volume = 0.0, powder = 0.0, media = 0.0, collisions = 0.0, collisions_no_powder = 0.0;
  double input = 0.0, input_no_powder = 0.0;  // over the sites with both cells

  void add(double weight, const json& loaded, const json* baseline) {
    ++sites;
    volume += weight;
    powder += weight * powder_dissipation(loaded);
    media += weight * (power_input(loaded) - powder_dissipation(loaded));
    collisions += weight * media_collision_dissipation(loaded);
    if (!baseline) return;
    collisions_no_powder += weight * media_collision_dissipation(*baseline);
    input += weight * power_input(loaded);
    input_no_powder += weight * power_input(*baseline);
  }
};

json region_json(const std::string& name, const PowerSums& r, double total_powder) {
  return {{"region", name},
          {"sites", r.sites},
          {"volume_m3", r.volume},
          {"powder_power_w", r.powder},
          {"powder_power_share", ratio_or_null(r.powder, total_powder)},
          {"media_power_w", r.media},
          {"media_collision_power_w", r.collisions},
          {"media_collision_power_no_powder_w", r.collisions_no_powder},
          {"cushioning", ratio_or_null(r.collisions, r.collisions_no_powder)}};
}

// Collision rates per energy bin in the slice, for the "media" and "powder" spectra of the cells.
class SpectrumSum {
 public:
  void add(double weight, const json& cell) {
    const json& spectra = cell.at("spectra");
    const auto edges = spectra.at("bin_edges_j").get<std::vector<double>>();
    if (edges_.empty()) {
      edges_ = edges;
      media_.assign(edges.size() - 1, 0.0);
      powder_.assign(edges.size() - 1, 0.0);
    } else if (edges != edges_) {
      throw std::invalid_argument(
          "upscale: shear cells with different spectrum bins: re-run them with one version");
    }
    const double scale =
        weight / (cell.at("volume_m3").get<double>() * cell.at("duration_s").get<double>());
    accumulate(spectra.at("media").at("counts"), scale, media_);
    accumulate(spectra.at("powder").at("counts"), scale, powder_);
  }

  json to_json() const {
    return {{"bin_edges_j", edges_}, {"powder_rate_per_s", powder_}, {"media_rate_per_s", media_}};
  }

 private:
  static void accumulate(const json& counts, double scale, std::vector<double>& rates) {
    for (std::size_t k = 0; k < rates.size(); ++k) rates[k] += scale * counts.at(k).get<double>();
  }

  std::vector<double> edges_, media_, powder_;
};

json site_row(const json& site, const json* loaded, const json* baseline) {
  const double macro_tau = site.at("shear_stress_pa").get<double>();
  const json cell_tau = baseline ? baseline->at("shear_stress_pa") : json(nullptr);
  return {
      {"site_id", site.at("site_id")},
      {"region", site.at("region")},
      {"x_m", site.at("position_m").at(0)},
      {"y_m", site.at("position_m").at(1)},
      {"weight_m3", site.at("weight_m3")},
      {"shear_rate_per_s", site.at("shear_rate_per_s")},
      {"normal_stress_pa", site.at("normal_stress_pa")},
      {"macro_shear_stress_pa", macro_tau},
      {"cell_shear_stress_pa", cell_tau},
      {"coupling_ratio",
       baseline ? ratio_or_null(cell_tau.get<double>(), macro_tau) : json(nullptr)},
      {"power_density_w_m3", loaded ? loaded->at("power_density_w_m3") : json(nullptr)},
      {"powder_dissipation_w_m3", loaded ? loaded->at("powder_dissipation_w_m3") : json(nullptr)},
      {"skipped", loaded ? json(nullptr) : json("no shear cell ran at this site")}};
}

json coupling_summary(const json& sites) {
  std::vector<double> ratios;
  for (const json& site : sites) {
    if (site.at("coupling_ratio").is_number())
      ratios.push_back(site.at("coupling_ratio").get<double>());
  }
  const auto within = std::count_if(ratios.begin(), ratios.end(), [](double r) {
    return std::abs(r - 1.0) <= kCouplingTolerance;
  });
  json median = nullptr;
  if (!ratios.empty()) {
    std::sort(ratios.begin(), ratios.end());
    const std::size_t n = ratios.size();
    median = n % 2 ? ratios[n / 2] : 0.5 * (ratios[n / 2 - 1] + ratios[n / 2]);
  }
  return {{"sites", ratios.size()},
          {"median_ratio", median},
          {"tolerance", kCouplingTolerance},
          {"within_tolerance", within}};
}

json mill_json(const json& macro) {
  return {{"diameter_m", 2.0 * macro.at("mill").at("radius_m").get<double>()},
          {"slice_length_m", macro.at("mill").at("length_m")},
          {"ball_mass_kg", macro.at("ball_mass_kg")},
          {"power_draw_w", macro.at("power").at("mean_w")},
          {"specific_power_kw_per_t", macro.at("power").at("kw_per_t_balls")}};
}

}  // namespace

engine::TaskOutcome run_upscale(engine::TaskContext& context) {
  const double load = context.params.at("powder_load").get<double>();
  const json& macro = only_input(context, "macro").result;
  const json& sites = only_input(context, "sites").result.at("sites");
  const auto loaded = cells_at_load(context, load), baseline = cells_at_load(context, 0.0);

  std::map<std::string, PowerSums> by_region;
  PowerSums all;
  SpectrumSum spectra;
  json site_rows = json::array();
  for (const json& site : sites) {
    const std::string id = site.at("site_id").get<std::string>();
    const json* cell = cell_of(loaded, id);
    const json* reference = cell_of(baseline, id);
    site_rows.push_back(site_row(site, cell, reference));
    if (!cell) continue;
    const double weight = site.at("weight_m3").get<double>();
    by_region[site.at("region").get<std::string>()].add(weight, *cell, reference);
    all.add(weight, *cell, reference);
    spectra.add(weight, *cell);
  }

  json regions = json::array();
  std::string dominant;
  double dominant_power = -1.0;
  for (const std::string& name : region_names()) {
    const auto found = by_region.find(name);
    if (found == by_region.end()) continue;
    regions.push_back(region_json(name, found->second, all.powder));
    if (found->second.powder > dominant_power) {
      dominant_power = found->second.powder;
      dominant = name;
    }
  }
  const double power_draw = macro.at("power").at("mean_w").get<double>();
  json result = {
      {"fill", macro.at("fill")},
      {"speed_fraction", macro.at("speed_fraction")},
      {"powder_load", load},
      {"average_task", only_input(context, "average").key},
      {"mill", mill_json(macro)},
      {"power_draw_with_powder_w", all.input_no_powder > 0.0
                                       ? json(power_draw * all.input / all.input_no_powder)
                                       : json(nullptr)},
      {"powder_power_w", all.powder},
      {"media_power_w", all.media},
      {"media_collision_power_w", all.collisions},
      {"media_collision_power_no_powder_w", all.collisions_no_powder},
      {"cushioning", ratio_or_null(all.collisions, all.collisions_no_powder)},
      {"regions", regions},
      {"dominant_region", all.sites > 0 && all.powder > 0.0 ? json(dominant) : json(nullptr)},
      {"spectra", spectra.to_json()},
      {"sites", site_rows},
      {"coupling", coupling_summary(site_rows)},
  };
  context.log(fmt::format(
      "upscale U = {}: powder {:.4g} W ({} dominates), cushioning {}, {} of {} sites couple "
      "within {:.0f}%",
      load, all.powder, dominant.empty() ? "no region" : dominant, result["cushioning"].dump(),
      result["coupling"]["within_tolerance"].dump(), result["coupling"]["sites"].dump(),
      100 * kCouplingTolerance));
  return engine::TaskOutcome::with_result(std::move(result));
}

engine::ViewDefinition upscaled_results_view() {
  return {"upscaled_results", R"sql(
SELECT c.name AS campaign,
       json_extract(r.result, '$.fill') AS fill,
       json_extract(r.result, '$.speed_fraction') AS speed_fraction,
       json_extract(r.result, '$.powder_load') AS powder_load,
       up.key AS task_key,
       json_extract(region.value, '$.region') AS region,
       json_extract(region.value, '$.sites') AS sites,
       json_extract(region.value, '$.volume_m3') AS volume_m3,
       json_extract(region.value, '$.powder_power_w') AS powder_power_w,
       json_extract(region.value, '$.powder_power_share') AS powder_power_share,
       json_extract(region.value, '$.media_power_w') AS media_power_w,
       json_extract(region.value, '$.media_collision_power_w') AS media_collision_power_w,
       json_extract(region.value, '$.cushioning') AS cushioning,
       json_extract(r.result, '$.mill.power_draw_w') AS power_draw_w,
       json_extract(r.result, '$.power_draw_with_powder_w') AS power_draw_with_powder_w,
       json_extract(r.result, '$.powder_power_w') AS mill_powder_power_w,
       json_extract(r.result, '$.dominant_region') AS dominant_region,
       json_extract(r.result, '$.coupling.median_ratio') AS coupling_median_ratio
FROM campaign_tasks ct
JOIN campaigns c ON c.id = ct.campaign_id
JOIN tasks up ON up.key = ct.task_key AND up.kind = 'upscale' AND up.status = 'done'
JOIN results r ON r.task_key = up.key
JOIN json_each(r.result, '$.regions') region
)sql"};
}

void register_upscale(engine::Registry& registry) {
  registry.kinds.add(
      engine::TaskKind{.name = "upscale", .version = kUpscaleVersion, .run = run_upscale});
  registry.views.push_back(upscaled_results_view());
}

}  // namespace millflow::tasks
