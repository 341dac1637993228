#include "method/cell_result.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

constexpr std::array<const char*, 6> kStressKeys = {"xx", "yy", "zz", "xy", "xz", "yz"};

bool involves_powder(dem::ContactType type) {
  return type == dem::ContactType::MediaPowder || type == dem::ContactType::PowderPowder ||
         type == dem::ContactType::WallPowder;
}

std::string type_name(std::size_t t) {
  return dem::contact_type_name(static_cast<dem::ContactType>(t));
}

CellCollisions collisions_of(const dem::CollisionStats& stats) {
  return {.count = stats.count, .rate_per_m3_s = stats.rate_per_volume};
}

json collisions_json(const CellCollisions& c) {
  return {{"count", c.count}, {"rate_per_m3_s", c.rate_per_m3_s}};
}

CellCollisions collisions_from(const json& in) {
  return {.count = in.at("count").get<double>(),
          .rate_per_m3_s = in.at("rate_per_m3_s").get<double>()};
}

EnergyHistogram histogram_from(const json& in) {
  return {.counts = in.at("counts").get<std::vector<double>>(),
          .underflow = in.at("underflow").get<double>(),
          .overflow = in.at("overflow").get<double>()};
}

// A value per contact type, and `total` when given.
template <class T, class Write>
json by_type_json(const ByContactType<T>& values, Write write) {
  json out = json::object();
  for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) out[type_name(t)] = write(values[t]);
  return out;
}

ByContactType<double> numbers_by_type(const json& in) {
  ByContactType<double> out{};
  for (std::size_t t = 0; t < dem::kContactTypeCount; ++t)
    out[t] = in.at(type_name(t)).get<double>();
  return out;
}

json standard_errors_json(const CellStandardErrors& se) {
  json dissipation = by_type_json(se.dissipation_w_m3, [](double x) { return x; });
  dissipation["total"] = se.dissipation_total_w_m3;
  return {{"friction", se.friction},
          {"friction_mean_pressure", se.friction_mean_pressure},
          {"shear_stress_pa", se.shear_stress_pa},
          {"normal_stress_pa", se.normal_stress_pa},
          {"power_density_w_m3", se.power_density_w_m3},
          {"powder_dissipation_w_m3", se.powder_dissipation_w_m3},
          {"dissipation_w_m3", dissipation},
          {"blocks", se.blocks},
          {"batch_blocks", se.batch_blocks}};
}

CellStandardErrors standard_errors_from(const json& in) {
  return {.friction = in.at("friction").get<double>(),
          .friction_mean_pressure = in.at("friction_mean_pressure").get<double>(),
          .shear_stress_pa = in.at("shear_stress_pa").get<double>(),
          .normal_stress_pa = in.at("normal_stress_pa").get<double>(),
          .power_density_w_m3 = in.at("power_density_w_m3").get<double>(),
          .powder_dissipation_w_m3 = in.at("powder_dissipation_w_m3").get<double>(),
          .dissipation_w_m3 = numbers_by_type(in.at("dissipation_w_m3")),
          .dissipation_total_w_m3 = in.at("dissipation_w_m3").at("total").get<double>(),
          .blocks = in.at("blocks").get<std::size_t>(),
          .batch_blocks = in.at("batch_blocks").get<std::size_t>()};
}

json stiffness_json(const std::vector<dem::PairStiffness>& pairs) {
  json out = json::object();
  for (const dem::PairStiffness& p : pairs) {
    out[p.pair] = {{"k_n_n_m", p.chosen},
                   {"kappa", p.kappa},
                   {"given_n_m", p.given},
                   {"static_bound_n_m", p.static_bound},
                   {"impact_bound_n_m", p.impact_bound}};
    // Cells of kind version 6 and older did not say which bound governs.
    if (!p.governing.empty()) out[p.pair]["governing"] = p.governing;
  }
  return out;
}

std::vector<dem::PairStiffness> stiffness_from(const json& in) {
  std::vector<dem::PairStiffness> pairs;
  for (const auto& [pair, k] : in.items()) {
    pairs.push_back({.pair = pair,
                     .given = k.at("given_n_m").get<double>(),
                     .static_bound = k.at("static_bound_n_m").get<double>(),
                     .impact_bound = k.at("impact_bound_n_m").get<double>(),
                     .chosen = k.at("k_n_n_m").get<double>(),
                     .kappa = k.at("kappa").get<double>(),
                     .governing = k.value("governing", std::string())});
  }
  return pairs;
}

}  // namespace

CellOverlap CellResult::worst_overlap() const {
  const CellOverlap* worst = nullptr;
  for (const std::optional<CellOverlap>& o : overlaps) {
    if (o && (worst == nullptr || o->p95_fraction > worst->p95_fraction)) worst = &*o;
  }
  return worst ? *worst : CellOverlap{};
}

CellResult cell_result(const dem::ShearCellMeasurements& m) {
  CellResult r{
      .strain = m.strain,
      .duration_s = m.duration,
      .steps = m.steps,
      .target_shear_rate_per_s = m.target_shear_rate,
      .bulk_shear_rate_per_s = m.bulk_shear_rate,
      .nominal_shear_rate_per_s = m.nominal_shear_rate,
      .wall_speed_m_s = m.wall_speed,
      .wall_slip_m_s = m.wall_slip,
      .gap_m = m.gap,
      .volume_m3 = m.volume,
      .shear_stress_pa = m.shear_stress,
      .normal_stress_pa = m.normal_stress,
      .friction = m.friction,
      .friction_mean_pressure = m.friction_mean_pressure,
      .stresses_pa = m.stress_tensor,
      .mean_pressure_pa = m.mean_pressure,
      .inertial_number = m.inertial_number,
      .inertial_number_measured_rate = m.inertial_number_measured_rate,
      .media_solid_fraction = m.media_solid_fraction,
      .powder_solid_fraction = m.powder_solid_fraction,
      .power_density_w_m3 = m.power_density,
      .dissipation_w_m3 = m.dissipation_density,
      .dissipation_total_w_m3 = m.dissipation_density_total,
      .media_collisions = collisions_of(m.media_collisions),
      .powder_collisions = collisions_of(m.powder_collisions),
      .media_spectrum = energy_histogram(m.media_collisions.dissipated_energy),
      .powder_spectrum = energy_histogram(m.powder_collisions.dissipated_energy),
      .work_in_j = m.work_in,
      .kinetic_change_j = m.kinetic_change,
      .elastic_change_j = m.elastic_change,
      .dissipated_j = m.dissipated,
      .stress_control_work_j = m.stress_control_work,
      .energy_balance_error = m.energy_balance_error,
      .shear_stress_first_half_pa = m.shear_stress_first_half,
      .shear_stress_second_half_pa = m.shear_stress_second_half,
      .steady_deviation = m.steady_state_deviation,
      .steady = m.steady,
      .stationary_strain = m.stationary ? std::optional(m.stationary_strain) : std::nullopt,
      .converged = m.converged,
      .standard_errors =
          CellStandardErrors{
              .friction = m.friction_error.standard_error,
              .friction_mean_pressure = m.friction_mean_pressure_error.standard_error,
              .shear_stress_pa = m.shear_stress_error.standard_error,
              .normal_stress_pa = m.normal_stress_error.standard_error,
              .power_density_w_m3 = m.power_density_error.standard_error,
              .powder_dissipation_w_m3 = m.powder_dissipation_error.standard_error,
              .dissipation_w_m3 = m.dissipation_standard_error,
              .dissipation_total_w_m3 = m.dissipation_total_error.standard_error,
              .blocks = m.blocks,
              .batch_blocks = m.batch_blocks},
      .overlap_ok = m.overlap_ok};
  for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) {
    if (involves_powder(static_cast<dem::ContactType>(t)))
      r.powder_dissipation_w_m3 += m.dissipation_density[t];
    r.collisions[t] = collisions_of(m.collisions[t]);
    const dem::OverlapStats& o = m.overlaps[t];
    if (o.contacts == 0.0) continue;
    r.overlaps[t] = CellOverlap{.mean_fraction = o.mean_fraction,
                                .p95_fraction = o.p95_fraction,
                                .max_fraction = o.max_fraction,
                                .contact_samples = o.contacts};
  }
  r.spectrum_bin_edges_j = bin_edges(m.media_collisions.dissipated_energy);
  return r;
}

namespace {

// Only a stiff cell has it: the default cells' results stay as they were.
void write_stiffness_factor(json& out, const CellResult& c) {
  if (c.stiffness_factor) out["stiffness_factor"] = *c.stiffness_factor;
}

}  // namespace

void to_json(json& out, const CellResult& c) {
  if (!c.skipped.empty()) {
    out = {{"skipped", c.skipped}, {"slot", c.slot}, {"powder_load", c.powder_load}};
    write_stiffness_factor(out, c);
    return;
  }
  json dissipation = by_type_json(c.dissipation_w_m3, [](double x) { return x; });
  dissipation["total"] = c.dissipation_total_w_m3;
  json collisions = by_type_json(c.collisions, collisions_json);
  collisions["media"] = collisions_json(c.media_collisions);
  collisions["powder"] = collisions_json(c.powder_collisions);
  json overlap = json::object();
  for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) {
    if (!c.overlaps[t]) continue;
    const CellOverlap& o = *c.overlaps[t];
    overlap[type_name(t)] = {{"mean_fraction", o.mean_fraction},
                             {"p95_fraction", o.p95_fraction},
                             {"max_fraction", o.max_fraction},
                             {"contact_samples", o.contact_samples}};
  }
  json stresses = json::object();
  for (std::size_t k = 0; k < kStressKeys.size(); ++k) stresses[kStressKeys[k]] = c.stresses_pa[k];
  stresses["mean_pressure_pa"] = c.mean_pressure_pa;
  stresses["p_yy_pa"] = c.normal_stress_pa;
  const CellOverlap worst = c.worst_overlap();
  out = {
      {"site", c.site},
      {"slot", c.slot},
      {"powder_load", c.powder_load},
      {"media_count", c.media_count},
      {"powder_count", c.powder_count},
      {"wall_ball_count", c.wall_ball_count},
      {"stiffness", stiffness_json(c.stiffness)},
      {"strain", c.strain},
      {"duration_s", c.duration_s},
      {"steps", c.steps},
      {"target_shear_rate_per_s", c.target_shear_rate_per_s},
      {"bulk_shear_rate_per_s", c.bulk_shear_rate_per_s},
      {"nominal_shear_rate_per_s", c.nominal_shear_rate_per_s},
      {"wall_speed_m_s", c.wall_speed_m_s},
      {"wall_slip_m_s", c.wall_slip_m_s},
      {"gap_m", c.gap_m},
      {"volume_m3", c.volume_m3},
      {"shear_stress_pa", c.shear_stress_pa},
      {"normal_stress_pa", c.normal_stress_pa},
      {"friction", c.friction},
      {"friction_mean_pressure", c.friction_mean_pressure},
      {"stresses", stresses},
      {"inertial_number", c.inertial_number},
      {"inertial_number_measured_rate", c.inertial_number_measured_rate},
      {"media_solid_fraction", c.media_solid_fraction},
      {"powder_solid_fraction", c.powder_solid_fraction},
      {"solid_fraction", c.media_solid_fraction + c.powder_solid_fraction},
      {"power_density_w_m3", c.power_density_w_m3},
      {"dissipation_w_m3", dissipation},
      {"powder_dissipation_w_m3", c.powder_dissipation_w_m3},
      {"collisions", collisions},
      {"spectra",
       {{"bin_edges_j", c.spectrum_bin_edges_j},
        {"media", c.media_spectrum},
        {"powder", c.powder_spectrum}}},
      {"energy",
       {{"work_in_j", c.work_in_j},
        {"kinetic_change_j", c.kinetic_change_j},
        {"elastic_change_j", c.elastic_change_j},
        {"dissipated_j", c.dissipated_j},
        {"stress_control_work_j", c.stress_control_work_j},
        {"balance_error", c.energy_balance_error}}},
      {"steady_state",
       {{"shear_stress_first_half_pa", c.shear_stress_first_half_pa},
        {"shear_stress_second_half_pa", c.shear_stress_second_half_pa},
        {"deviation", c.steady_deviation},
        {"steady", c.steady}}},
      {"steady", c.steady},
      {"stationary_strain", c.stationary_strain ? json(*c.stationary_strain) : json()},
      {"converged", c.converged},
      {"overlap", overlap},
      {"overlap_mean_fraction", worst.mean_fraction},
      {"overlap_p95_fraction", worst.p95_fraction},
      {"overlap_max_fraction", worst.max_fraction},
      {"overlap_ok", c.overlap_ok},
      {"neighbor_skin_fraction",
       c.neighbor_skin_fraction ? json(*c.neighbor_skin_fraction) : json()},
  };
  if (c.standard_errors) out["standard_errors"] = standard_errors_json(*c.standard_errors);
  write_stiffness_factor(out, c);
}

void from_json(const json& in, CellResult& c) {
  c = CellResult{};
  c.slot = in.at("slot");
  c.powder_load = in.at("powder_load");
  if (const auto factor = in.find("stiffness_factor"); factor != in.end())
    c.stiffness_factor = factor->get<double>();
  if (in.contains("skipped")) {
    c.skipped = in.at("skipped").get<std::string>();
    return;
  }
  c.site = in.at("site");
  c.media_count = in.at("media_count").get<std::size_t>();
  c.powder_count = in.at("powder_count").get<std::size_t>();
  c.wall_ball_count = in.at("wall_ball_count").get<std::size_t>();
  c.stiffness = stiffness_from(in.at("stiffness"));
  c.strain = in.at("strain").get<double>();
  c.duration_s = in.at("duration_s").get<double>();
  c.steps = in.at("steps").get<std::uint64_t>();
  c.target_shear_rate_per_s = in.at("target_shear_rate_per_s").get<double>();
  c.bulk_shear_rate_per_s = in.at("bulk_shear_rate_per_s").get<double>();
  c.nominal_shear_rate_per_s = in.at("nominal_shear_rate_per_s").get<double>();
  c.wall_speed_m_s = in.at("wall_speed_m_s").get<double>();
  c.wall_slip_m_s = in.at("wall_slip_m_s").get<double>();
  c.gap_m = in.at("gap_m").get<double>();
  c.volume_m3 = in.at("volume_m3").get<double>();
  c.shear_stress_pa = in.at("shear_stress_pa").get<double>();
  c.normal_stress_pa = in.at("normal_stress_pa").get<double>();
  c.friction = in.at("friction").get<double>();
  c.friction_mean_pressure = in.at("friction_mean_pressure").get<double>();
  const json& stresses = in.at("stresses");
  for (std::size_t k = 0; k < kStressKeys.size(); ++k)
    c.stresses_pa[k] = stresses.at(kStressKeys[k]).get<double>();
  c.mean_pressure_pa = stresses.at("mean_pressure_pa").get<double>();
  c.inertial_number = in.at("inertial_number").get<double>();
  c.inertial_number_measured_rate = in.at("inertial_number_measured_rate").get<double>();
  c.media_solid_fraction = in.at("media_solid_fraction").get<double>();
  c.powder_solid_fraction = in.at("powder_solid_fraction").get<double>();
  c.power_density_w_m3 = in.at("power_density_w_m3").get<double>();
  c.dissipation_w_m3 = numbers_by_type(in.at("dissipation_w_m3"));
  c.dissipation_total_w_m3 = in.at("dissipation_w_m3").at("total").get<double>();
  c.powder_dissipation_w_m3 = in.at("powder_dissipation_w_m3").get<double>();
  const json& collisions = in.at("collisions");
  for (std::size_t t = 0; t < dem::kContactTypeCount; ++t)
    c.collisions[t] = collisions_from(collisions.at(type_name(t)));
  c.media_collisions = collisions_from(collisions.at("media"));
  c.powder_collisions = collisions_from(collisions.at("powder"));
  const json& spectra = in.at("spectra");
  c.spectrum_bin_edges_j = spectra.at("bin_edges_j").get<std::vector<double>>();
  c.media_spectrum = histogram_from(spectra.at("media"));
  c.powder_spectrum = histogram_from(spectra.at("powder"));
  const json& energy = in.at("energy");
  c.work_in_j = energy.at("work_in_j").get<double>();
  c.kinetic_change_j = energy.at("kinetic_change_j").get<double>();
  c.elastic_change_j = energy.at("elastic_change_j").get<double>();
  c.dissipated_j = energy.at("dissipated_j").get<double>();
  c.stress_control_work_j = energy.at("stress_control_work_j").get<double>();
  c.energy_balance_error = energy.at("balance_error").get<double>();
  const json& steady_state = in.at("steady_state");
  c.shear_stress_first_half_pa = steady_state.at("shear_stress_first_half_pa").get<double>();
  c.shear_stress_second_half_pa = steady_state.at("shear_stress_second_half_pa").get<double>();
  c.steady_deviation = steady_state.at("deviation").get<double>();
  c.steady =
      in.contains("steady") ? in.at("steady").get<bool>() : steady_state.at("steady").get<bool>();
  if (const json& strain = in.at("stationary_strain"); !strain.is_null())
    c.stationary_strain = strain.get<double>();
  c.converged = in.contains("converged") ? in.at("converged").get<bool>() : c.steady;
  if (in.contains("standard_errors"))
    c.standard_errors = standard_errors_from(in.at("standard_errors"));
  for (const auto& [name, o] : in.at("overlap").items()) {
    for (std::size_t t = 0; t < dem::kContactTypeCount; ++t) {
      if (type_name(t) != name) continue;
      c.overlaps[t] = CellOverlap{.mean_fraction = o.at("mean_fraction").get<double>(),
                                  .p95_fraction = o.at("p95_fraction").get<double>(),
                                  .max_fraction = o.at("max_fraction").get<double>(),
                                  .contact_samples = o.at("contact_samples").get<double>()};
    }
  }
  c.overlap_ok = in.at("overlap_ok").get<bool>();
  if (const auto skin = in.find("neighbor_skin_fraction"); skin != in.end() && !skin->is_null())
    c.neighbor_skin_fraction = skin->get<double>();
}

}  // namespace millflow::method
