#include "method/upscale.hpp"

#include <cmath>
#include <stdexcept>

namespace millflow::method {
namespace {

double sum_from(const std::vector<double>& rates, std::size_t first) {
  double sum = 0.0;
  for (std::size_t k = first; k < rates.size(); ++k) sum += rates[k];
  return sum;
}

}  // namespace

CellFigures cell_figures(const CellResult& cell) {
  constexpr auto media_media = static_cast<std::size_t>(dem::ContactType::MediaMedia);
  constexpr auto wall_media = static_cast<std::size_t>(dem::ContactType::WallMedia);
  const CellCollisions& media = cell.media_collisions;
  const std::optional<CellStandardErrors>& se = cell.standard_errors;
  return {.input = cell.power_density_w_m3,
          .powder = cell.powder_dissipation_w_m3,
          .collisions = cell.dissipation_w_m3[media_media] + cell.dissipation_w_m3[wall_media],
          .collision_rate = media.rate_per_m3_s,
          .input_se = se ? std::optional(se->power_density_w_m3) : std::nullopt,
          .powder_se = se ? std::optional(se->powder_dissipation_w_m3) : std::nullopt,
          .collisions_se = se ? std::optional(se->dissipation_w_m3[media_media] +
                                              se->dissipation_w_m3[wall_media])
                              : std::nullopt,
          .collision_rate_se = media.count > 0.0
                                   ? std::optional(media.rate_per_m3_s / std::sqrt(media.count))
                                   : std::nullopt,
          .media_solid_fraction = cell.media_solid_fraction};
}

CellSpectra cell_spectra(const CellResult& cell) {
  return {.bin_edges_j = cell.spectrum_bin_edges_j,
          .media_counts = cell.media_spectrum.counts,
          .powder_counts = cell.powder_spectrum.counts,
          .volume_m3 = cell.volume_m3,
          .duration_s = cell.duration_s};
}

double site_weight(const Site& site, const CellFigures& cell, WeightBasis basis) {
  if (basis == WeightBasis::volume) return site.weight_m3;
  return site.solid_volume_m3 / cell.media_solid_fraction;
}

void Sum::add(double w, double x, const std::optional<double>& se) {
  value += w * x;
  if (se)
    variance += w * w * *se * *se;
  else
    known = false;
}

void Sum::merge(const Sum& other) {
  value += other.value;
  variance += other.variance;
  known = known && other.known;
}

std::optional<double> Sum::standard_error() const {
  return known ? std::optional(std::sqrt(variance)) : std::nullopt;
}

Ratio ratio(const Sum& a, const Sum& b) {
  return ratio(Ratio{a.value, a.standard_error()}, Ratio{b.value, b.standard_error()});
}

Ratio ratio(const Ratio& a, const Ratio& b) {
  if (!a.value || !b.value || *b.value <= 0.0) return {};
  const double r = *a.value / *b.value;
  if (!a.standard_error || !b.standard_error || *a.value == 0.0) return {r, std::nullopt};
  return {r, std::abs(r) * std::hypot(*a.standard_error / *a.value, *b.standard_error / *b.value)};
}

void PowerSums::add(const Site& site, WeightBasis basis, const CellFigures& loaded,
                    const CellFigures* baseline) {
  ++sites;
  volume += site.weight_m3;
  solid_volume += site.solid_volume_m3;
  const double w = site_weight(site, loaded, basis);
  powder.add(w, loaded.powder, loaded.powder_se);
  input.add(w, loaded.input, loaded.input_se);
  collisions.add(w, loaded.collisions, loaded.collisions_se);
  rate.add(w, loaded.collision_rate, loaded.collision_rate_se);
  if (!baseline) return;
  ++paired_sites;
  const double w0 = site_weight(site, *baseline, basis);
  input_paired.add(w, loaded.input, loaded.input_se);
  input_no_powder.add(w0, baseline->input, baseline->input_se);
  collisions_no_powder.add(w0, baseline->collisions, baseline->collisions_se);
  rate_no_powder.add(w0, baseline->collision_rate, baseline->collision_rate_se);
}

void PowerSums::merge(const PowerSums& r) {
  sites += r.sites;
  paired_sites += r.paired_sites;
  volume += r.volume;
  solid_volume += r.solid_volume;
  for (auto [mine, theirs] : {std::pair{&powder, &r.powder},
                              {&input, &r.input},
                              {&collisions, &r.collisions},
                              {&rate, &r.rate},
                              {&input_paired, &r.input_paired},
                              {&input_no_powder, &r.input_no_powder},
                              {&collisions_no_powder, &r.collisions_no_powder},
                              {&rate_no_powder, &r.rate_no_powder}}) {
    mine->merge(*theirs);
  }
}

std::pair<double, double> PowerSums::anchor_factors(double macro_dissipation) const {
  return {input.value > 0.0 ? macro_dissipation / input.value : 0.0,
          input_no_powder.value > 0.0 ? macro_dissipation / input_no_powder.value : 0.0};
}

PowerSums PowerSums::anchored(double macro_dissipation) const {
  PowerSums a = *this;
  const auto [k, k0] = anchor_factors(macro_dissipation);
  for (Sum* loaded : {&a.powder, &a.input, &a.collisions, &a.rate, &a.input_paired})
    *loaded = loaded->scaled(k);
  for (Sum* reference : {&a.input_no_powder, &a.collisions_no_powder, &a.rate_no_powder})
    *reference = reference->scaled(k0);
  return a;
}

void StiffnessSums::add(const Site& site, WeightBasis basis, const CellFigures& loaded,
                        const CellFigures& stiff_loaded, const CellFigures& baseline) {
  normal.add(site, basis, loaded, &baseline);
  stiff.add(site, basis, stiff_loaded, &baseline);
}

void StiffnessSums::merge(const StiffnessSums& other) {
  normal.merge(other.normal);
  stiff.merge(other.stiff);
}

void SpectrumSum::add(double weight, const CellSpectra& cell) {
  accumulate(cell, cell.media_counts, weight, media_);
  accumulate(cell, cell.powder_counts, weight, powder_);
}

void SpectrumSum::add_baseline(double weight, const CellSpectra& cell) {
  accumulate(cell, cell.media_counts, weight, media_no_powder_);
}

void SpectrumSum::add_scaled(const SpectrumSum& other, double k, double k0) {
  if (other.edges_.empty()) return;
  use_edges(other.edges_);
  for (std::size_t b = 0; b < media_.size(); ++b) {
    media_[b] += k * other.media_[b];
    powder_[b] += k * other.powder_[b];
    media_no_powder_[b] += k0 * other.media_no_powder_[b];
  }
}

std::optional<SpectrumShift> SpectrumSum::media_shift() const {
  const double total = sum_from(media_no_powder_, 0);
  if (total <= 0.0) return std::nullopt;
  std::size_t median = 0;
  double below = 0.0;
  while (median + 1 < media_no_powder_.size() && below + media_no_powder_[median] < 0.5 * total)
    below += media_no_powder_[median++];
  const double loaded = sum_from(media_, 0);
  return SpectrumShift{.threshold_j = edges_[median],
                       .fraction_above = loaded > 0.0
                                             ? std::optional(sum_from(media_, median) / loaded)
                                             : std::nullopt,
                       .fraction_above_no_powder = sum_from(media_no_powder_, median) / total};
}

void SpectrumSum::use_edges(const std::vector<double>& edges) {
  if (edges_.empty()) {
    edges_ = edges;
    for (auto* r : {&media_, &powder_, &media_no_powder_}) r->assign(edges.size() - 1, 0.0);
  } else if (edges != edges_) {
    throw std::invalid_argument(
        "upscale: shear cells with different spectrum bins: re-run them with one version");
  }
}

void SpectrumSum::accumulate(const CellSpectra& cell, const std::vector<double>& counts,
                             double weight, std::vector<double>& rates) {
  use_edges(cell.bin_edges_j);
  const double scale = weight / (cell.volume_m3 * cell.duration_s);
  for (std::size_t k = 0; k < rates.size(); ++k) rates[k] += scale * counts.at(k);
}

}  // namespace millflow::method
