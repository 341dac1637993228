#include "method/sites_result.hpp"

#include <fmt/format.h>

#include "util/json_fields.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

json optional_json(const std::optional<double>& value) {
  return value ? json(*value) : json(nullptr);
}

const char* weight_basis_name(WeightBasis basis) {
  return basis == WeightBasis::solid_volume ? "solid_volume" : "volume";
}

json regions_json(const std::vector<RegionSummary>& regions) {
  json rows = json::array();
  for (const RegionSummary& r : regions) {
    rows.push_back({{"name", r.name},
                    {"cells", r.cells},
                    {"volume_m3", r.volume_m3},
                    {"solid_volume_m3", r.solid_volume_m3},
                    {"dissipation_w", r.dissipation_w},
                    {"dissipation_share", r.dissipation_share},
                    {"mean_shear_rate_per_s", r.mean_shear_rate},
                    {"sites", r.sites}});
  }
  return rows;
}

json toe_json(const std::optional<Toe>& toe, const std::optional<double>& angle) {
  if (!toe) return nullptr;
  return {{"angle_deg", optional_json(angle)},
          {"position_m", {toe->x, toe->y}},
          {"radius_m", toe->radius_m},
          {"impact_cells", toe->impact_cells},
          {"impact_angle_deg", optional_json(toe->impact_angle_deg)}};
}

json rule_set_json(const RuleSet& set) {
  json regions = json::array();
  for (const RuleSetRegion& r : set.regions) {
    regions.push_back({{"name", r.name},
                       {"volume_m3", r.volume_m3},
                       {"solid_volume_m3", r.solid_volume_m3},
                       {"dissipation_w", r.dissipation_w},
                       {"dissipation_share", r.dissipation_share}});
  }
  return {{"name", set.name}, {"rules", json(set.rules)}, {"regions", regions}};
}

// The rules at `at`: a number per RegionRules field (their names are method/sites.cpp's).
RegionRules read_rules(const util::JsonFields& in, const std::string& at) {
  const json& rules = in.at(at);
  try {
    return rules.get<RegionRules>();
  } catch (const nlohmann::json::exception& error) {
    in.refuse(at, fmt::format("is not a set of region rules ({})", error.what()));
  }
}

std::optional<Toe> read_toe(const util::JsonFields& in) {
  if (in.at("/toe").is_null()) return std::nullopt;
  return Toe{.x = in.number("/toe/position_m/0"),
             .y = in.number("/toe/position_m/1"),
             .radius_m = in.number("/toe/radius_m"),
             .impact_cells = in.count("/toe/impact_cells"),
             .impact_angle_deg = in.number_or_null("/toe/impact_angle_deg")};
}

}  // namespace

RuleSet rule_set_of(const std::string& name, const RegionRules& rules,
                    const Classification& classification) {
  RuleSet set{.name = name, .rules = rules};
  for (const RegionSummary& r : classification.regions) {
    set.regions.push_back({.name = r.name,
                           .volume_m3 = r.volume_m3,
                           .solid_volume_m3 = r.solid_volume_m3,
                           .dissipation_w = r.dissipation_w,
                           .dissipation_share = r.dissipation_share});
  }
  return set;
}

SitesResult sites_result_of(const SiteSelection& selection, const RegionRules& rules) {
  SitesResult result{.rules = rules,
                     .weight_by = selection.weight_by,
                     .regions = selection.regions,
                     .charge_volume_m3 = selection.charge_volume_m3,
                     .charge_solid_volume_m3 = selection.charge_solid_volume_m3,
                     .total_dissipation_w = selection.total_dissipation_w,
                     .toe_angle_deg = selection.toe_angle_deg,
                     .shoulder_angle_deg = selection.shoulder_angle_deg,
                     .toe = selection.toe,
                     .sites = selection.sites,
                     .region_index = region_names()};
  for (const RegionSummary& r : selection.regions) {
    if (r.cells == 0) result.empty_regions.push_back(r.name);
  }
  for (const Site& s : selection.sites) {
    result.sites_volume_m3 += s.weight_m3;
    result.sites_solid_volume_m3 += s.solid_volume_m3;
  }
  return result;
}

void to_json(json& out, const SitesResult& r) {
  json rule_sets = json::array();
  for (const RuleSet& set : r.rule_sets) rule_sets.push_back(rule_set_json(set));
  out = {{"rules", json(r.rules)},
         {"weight_by", weight_basis_name(r.weight_by)},
         {"regions", regions_json(r.regions)},
         {"empty_regions", r.empty_regions},
         {"charge_volume_m3", r.charge_volume_m3},
         {"charge_solid_volume_m3", r.charge_solid_volume_m3},
         {"sites_volume_m3", r.sites_volume_m3},
         {"sites_solid_volume_m3", r.sites_solid_volume_m3},
         {"total_dissipation_w", r.total_dissipation_w},
         {"toe_angle_deg", optional_json(r.toe_angle_deg)},
         {"shoulder_angle_deg", optional_json(r.shoulder_angle_deg)},
         {"toe", toe_json(r.toe, r.toe_angle_deg)},
         {"sites", r.sites},
         {"fill", r.fill},
         {"speed_fraction", r.speed_fraction},
         {"average_task", r.average_task},
         {"region_index", r.region_index},
         {"rule_sets", std::move(rule_sets)}};
}

std::optional<json> find_site_json(const json& sites_result, const std::string& site_id) {
  for (const json& site : sites_result.at("sites")) {
    if (site_id_of(site) == site_id) return site;
  }
  return std::nullopt;
}

json sites_json_of(const std::vector<json>& sites) {
  return {{"sites", sites}};
}

SitesResult read_sites_result(const json& document, const std::string& owner,
                              const std::string& fix) {
  const util::JsonFields in(owner, document, fix);
  SitesResult r{.rules = read_rules(in, "/rules"),
                .empty_regions = in.texts("/empty_regions"),
                .charge_volume_m3 = in.number("/charge_volume_m3"),
                .charge_solid_volume_m3 = in.number("/charge_solid_volume_m3"),
                .sites_volume_m3 = in.number("/sites_volume_m3"),
                .sites_solid_volume_m3 = in.number("/sites_solid_volume_m3"),
                .total_dissipation_w = in.number("/total_dissipation_w"),
                .toe_angle_deg = in.number_or_null("/toe_angle_deg"),
                .shoulder_angle_deg = in.number_or_null("/shoulder_angle_deg"),
                .toe = read_toe(in),
                .fill = in.number("/fill"),
                .speed_fraction = in.number("/speed_fraction"),
                .average_task = in.text("/average_task"),
                .region_index = in.texts("/region_index")};
  const std::string weight_by = in.text("/weight_by");
  if (weight_by != weight_basis_name(WeightBasis::solid_volume) &&
      weight_by != weight_basis_name(WeightBasis::volume))
    in.refuse("/weight_by", "is '" + weight_by + "', not 'solid_volume' or 'volume'");
  r.weight_by = weight_by == weight_basis_name(WeightBasis::volume) ? WeightBasis::volume
                                                                    : WeightBasis::solid_volume;
  for (std::size_t i = 0; i < in.array_size("/regions"); ++i) {
    const std::string at = fmt::format("/regions/{}", i);
    r.regions.push_back({.name = in.text(at + "/name"),
                         .cells = in.count(at + "/cells"),
                         .volume_m3 = in.number(at + "/volume_m3"),
                         .solid_volume_m3 = in.number(at + "/solid_volume_m3"),
                         .dissipation_w = in.number(at + "/dissipation_w"),
                         .dissipation_share = in.number(at + "/dissipation_share"),
                         .mean_shear_rate = in.number(at + "/mean_shear_rate_per_s"),
                         .sites = in.count(at + "/sites")});
  }
  for (std::size_t i = 0; i < in.array_size("/sites"); ++i) {
    const std::string at = fmt::format("/sites/{}", i);
    try {
      r.sites.push_back(in.at(at).get<Site>());
    } catch (const nlohmann::json::exception& error) {
      in.refuse(at, fmt::format("is not a site ({})", error.what()));
    }
  }
  for (std::size_t i = 0; i < in.array_size("/rule_sets"); ++i) {
    const std::string at = fmt::format("/rule_sets/{}", i);
    RuleSet& set = r.rule_sets.emplace_back(
        RuleSet{.name = in.text(at + "/name"), .rules = read_rules(in, at + "/rules")});
    for (std::size_t j = 0; j < in.array_size(at + "/regions"); ++j) {
      const std::string row = fmt::format("{}/regions/{}", at, j);
      set.regions.push_back({.name = in.text(row + "/name"),
                             .volume_m3 = in.number(row + "/volume_m3"),
                             .solid_volume_m3 = in.number(row + "/solid_volume_m3"),
                             .dissipation_w = in.number(row + "/dissipation_w"),
                             .dissipation_share = in.number(row + "/dissipation_share")});
    }
  }
  return r;
}

void from_json(const json& in, SitesResult& result) {
  result = read_sites_result(in, "sites result");
}

}  // namespace millflow::method
