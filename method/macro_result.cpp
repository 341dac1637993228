#include "method/macro_result.hpp"

#include <fmt/format.h>

#include "util/json_fields.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

constexpr const char* kChargeConvention =
    "degrees counter-clockwise from 3 o'clock seen from +z (mill turning counter-clockwise, "
    "gravity -y), in [-90, 270); the arc of liner/lifter contact points holding >= 10% of the "
    "fullest 3-degree bin";

json optional_json(const std::optional<double>& value) {
  return value ? json(*value) : json();
}

EnergyHistogram read_histogram(const util::JsonFields& in, const std::string& at,
                               std::size_t bins) {
  EnergyHistogram h{.counts = in.numbers(at + "/counts"),
                    .underflow = in.number(at + "/underflow"),
                    .overflow = in.number(at + "/overflow")};
  if (h.counts.size() != bins)
    in.refuse(at + "/counts", fmt::format("does not hold {} bins", bins));
  return h;
}

MacroContact read_contact(const util::JsonFields& in, const std::string& at) {
  return {.pair = in.text(at + "/pair"),
          .normal_stiffness_n_m = in.number(at + "/normal_stiffness_n_m"),
          .tangential_stiffness_n_m = in.number(at + "/tangential_stiffness_n_m"),
          .restitution = in.number(at + "/restitution"),
          .friction = in.number(at + "/friction"),
          .reference_mass_kg = in.number(at + "/reference_mass_kg"),
          .collision_time_s = in.number(at + "/collision_time_s")};
}

// The object keys at `pointer` (checked to be an object).
std::vector<std::string> keys_of(const util::JsonFields& in, const std::string& pointer) {
  if (!in.at(pointer).is_object()) in.refuse(pointer, "is not an object");
  std::vector<std::string> keys;
  for (const auto& [key, value] : in.at(pointer).items()) keys.push_back(key);
  return keys;
}

}  // namespace

void to_json(json& out, const MacroResult& r) {
  json contacts = json::object();
  for (const auto& [label, c] : r.contacts) {
    contacts[label] = {{"pair", c.pair},
                       {"normal_stiffness_n_m", c.normal_stiffness_n_m},
                       {"tangential_stiffness_n_m", c.tangential_stiffness_n_m},
                       {"restitution", c.restitution},
                       {"friction", c.friction},
                       {"reference_mass_kg", c.reference_mass_kg},
                       {"collision_time_s", c.collision_time_s}};
  }
  json collisions = json::object(), spectra = json::object();
  if (!r.collisions.empty()) spectra["bin_edges_j"] = r.spectrum_bin_edges_j;
  for (const auto& [label, c] : r.collisions) {
    collisions[label] = {{"category", c.category},
                         {"count", c.count},
                         {"rate_per_s", c.rate_per_s},
                         {"mean_impact_energy_j", c.mean_impact_energy_j},
                         {"mean_dissipated_j", c.mean_dissipated_j},
                         {"dissipated_power_w", c.dissipated_power_w}};
    spectra[label] = {{"impact_energy", c.impact_energy},
                      {"dissipated_energy", c.dissipated_energy}};
  }
  const MacroPower& p = r.power;
  const MacroCorrelations& k = r.correlations;
  const MacroFrameMeans& f = r.frame_means;
  out = {
      {"n_balls", r.n_balls},
      {"ball_mass_kg", r.ball_mass_kg},
      {"media_diameter_m", r.media_diameter_m},
      {"dt_s", r.dt_s},
      {"collision_time_s", r.collision_time_s},
      {"critical_speed_rad_s", r.critical_speed_rad_s},
      {"angular_velocity_rad_s", r.angular_velocity_rad_s},
      {"speed_fraction", r.speed_fraction},
      {"fill", r.fill},
      {"gravity_m_s2", r.gravity_m_s2},
      {"mill",
       {{"radius_m", r.mill.radius_m},
        {"length_m", r.mill.length_m},
        {"axial_ends", r.mill.axial_ends},
        {"lifter_count", r.mill.lifter_count}}},
      {"contacts", contacts},
      {"measure_start_s", r.measure_start_s},
      {"measure_end_s", r.measure_end_s},
      {"measure_revolutions", r.measure_revolutions},
      {"sample_interval_s", r.sample_interval_s},
      {"frame_count", r.frame_count},
      {"segment_count", r.segment_count},
      {"categories", r.categories},
      {"power",
       {{"mean_w", p.mean_w},
        {"std_w", p.std_w},
        {"mean_kw", p.mean_kw},
        {"std_kw", p.std_kw},
        {"kw_per_m", p.kw_per_m},
        {"kw_per_t_balls", p.kw_per_t_balls},
        {"torque_arm_kw", p.torque_arm_kw},
        {"torque_arm_relative_difference", p.torque_arm_relative_difference},
        {"dissipation_kw", p.dissipation_kw},
        {"block_s", p.block_s}}},
      {"charge",
       {{"toe_angle_deg", optional_json(r.charge.toe_angle_deg)},
        {"shoulder_angle_deg", optional_json(r.charge.shoulder_angle_deg)},
        {"convention", kChargeConvention},
        {"contact_angle_bin_deg", r.charge.contact_angle_bin_deg},
        {"contact_angle_counts", r.charge.contact_angle_counts}}},
      {"correlations",
       {{"bond_kw_per_t", k.bond_kw_per_t},
        {"hogg_fuerstenau_kw_per_t", k.hogg_fuerstenau_kw_per_t},
        {"hogg_fuerstenau_repose_deg", k.hogg_fuerstenau_repose_deg},
        {"ratio_to_bond", k.ratio_to_bond},
        {"ratio_to_hogg_fuerstenau", k.ratio_to_hogg_fuerstenau}}},
      {"frame_means",
       {{"frames", f.frames},
        {"kinetic_energy_j",
         {{"translational", f.kinetic_translational_j}, {"rotational", f.kinetic_rotational_j}}},
        {"centre_of_mass_m", {{"x", f.centre_of_mass_x_m}, {"y", f.centre_of_mass_y_m}}},
        {"drive_torque_n_m",
         {{"liner", f.liner_torque_n_m},
          {"lifters", f.lifter_torque_n_m},
          {"end_walls", f.end_wall_torque_n_m},
          {"total", f.drive_torque_n_m}}},
        {"drive_power_w", f.drive_power_w}}},
      {"collisions", collisions},
      {"spectra", spectra},
  };
}

MacroResult read_macro_result(const json& document, const std::string& owner) {
  const util::JsonFields in(owner, document);
  MacroResult r{
      .n_balls = in.count("/n_balls"),
      .ball_mass_kg = in.number("/ball_mass_kg"),
      .media_diameter_m = in.number("/media_diameter_m"),
      .dt_s = in.number("/dt_s"),
      .collision_time_s = in.number("/collision_time_s"),
      .critical_speed_rad_s = in.number("/critical_speed_rad_s"),
      .angular_velocity_rad_s = in.number("/angular_velocity_rad_s"),
      .speed_fraction = in.number("/speed_fraction"),
      .fill = in.number("/fill"),
      .gravity_m_s2 = in.number("/gravity_m_s2"),
      .mill = {.radius_m = in.number("/mill/radius_m"),
               .length_m = in.number("/mill/length_m"),
               .axial_ends = in.text("/mill/axial_ends"),
               .lifter_count = static_cast<int>(in.count("/mill/lifter_count"))},
      .measure_start_s = in.number("/measure_start_s"),
      .measure_end_s = in.number("/measure_end_s"),
      .measure_revolutions = in.number("/measure_revolutions"),
      .sample_interval_s = in.number("/sample_interval_s"),
      .frame_count = in.count("/frame_count"),
      .segment_count = in.count("/segment_count"),
      .categories = in.texts("/categories"),
      .power = {.mean_w = in.number("/power/mean_w"),
                .std_w = in.number("/power/std_w"),
                .mean_kw = in.number("/power/mean_kw"),
                .std_kw = in.number("/power/std_kw"),
                .kw_per_m = in.number("/power/kw_per_m"),
                .kw_per_t_balls = in.number("/power/kw_per_t_balls"),
                .torque_arm_kw = in.number("/power/torque_arm_kw"),
                .torque_arm_relative_difference =
                    in.number("/power/torque_arm_relative_difference"),
                .dissipation_kw = in.number("/power/dissipation_kw"),
                .block_s = in.number("/power/block_s")},
      .correlations =
          {.bond_kw_per_t = in.number("/correlations/bond_kw_per_t"),
           .hogg_fuerstenau_kw_per_t = in.number("/correlations/hogg_fuerstenau_kw_per_t"),
           .hogg_fuerstenau_repose_deg = in.number("/correlations/hogg_fuerstenau_repose_deg"),
           .ratio_to_bond = in.number("/correlations/ratio_to_bond"),
           .ratio_to_hogg_fuerstenau = in.number("/correlations/ratio_to_hogg_fuerstenau")},
      .charge = {.toe_angle_deg = in.number_or_null("/charge/toe_angle_deg"),
                 .shoulder_angle_deg = in.number_or_null("/charge/shoulder_angle_deg"),
                 .contact_angle_bin_deg = in.number("/charge/contact_angle_bin_deg"),
                 .contact_angle_counts = in.numbers("/charge/contact_angle_counts")},
      .frame_means = {
          .frames = in.count("/frame_means/frames"),
          .kinetic_translational_j = in.number("/frame_means/kinetic_energy_j/translational"),
          .kinetic_rotational_j = in.number("/frame_means/kinetic_energy_j/rotational"),
          .centre_of_mass_x_m = in.number("/frame_means/centre_of_mass_m/x"),
          .centre_of_mass_y_m = in.number("/frame_means/centre_of_mass_m/y"),
          .liner_torque_n_m = in.number("/frame_means/drive_torque_n_m/liner"),
          .lifter_torque_n_m = in.number("/frame_means/drive_torque_n_m/lifters"),
          .end_wall_torque_n_m = in.number("/frame_means/drive_torque_n_m/end_walls"),
          .drive_torque_n_m = in.number("/frame_means/drive_torque_n_m/total"),
          .drive_power_w = in.number("/frame_means/drive_power_w")}};
  for (const std::string& label : keys_of(in, "/contacts"))
    r.contacts[label] = read_contact(in, "/contacts/" + label);
  const std::vector<std::string> labels = keys_of(in, "/collisions");
  if (!labels.empty()) {
    r.spectrum_bin_edges_j = in.numbers("/spectra/bin_edges_j");
    if (r.spectrum_bin_edges_j.size() < 2)
      in.refuse("/spectra/bin_edges_j", "holds fewer than 2 edges");
  }
  const std::size_t bins = labels.empty() ? 0 : r.spectrum_bin_edges_j.size() - 1;
  for (const std::string& label : labels) {
    const std::string at = "/collisions/" + label, spectra = "/spectra/" + label;
    r.collisions[label] = {
        .category = in.text(at + "/category"),
        .count = in.count(at + "/count"),
        .rate_per_s = in.number(at + "/rate_per_s"),
        .mean_impact_energy_j = in.number(at + "/mean_impact_energy_j"),
        .mean_dissipated_j = in.number(at + "/mean_dissipated_j"),
        .dissipated_power_w = in.number(at + "/dissipated_power_w"),
        .impact_energy = read_histogram(in, spectra + "/impact_energy", bins),
        .dissipated_energy = read_histogram(in, spectra + "/dissipated_energy", bins)};
  }
  return r;
}

void from_json(const json& in, MacroResult& result) {
  result = read_macro_result(in, "macro result");
}

}  // namespace millflow::method
