#pragma once
// The sums that carry shear-cell figures up to the mill (docs/method.md, step 4): weighted sums
// over sites with their standard errors, the macro-anchored scaling and the collision spectra.
// The `upscale` task kind (tasks/upscale.hpp) says what it reports from them and why.
#include <optional>
#include <utility>
#include <vector>

#include "method/cell_result.hpp"
#include "method/sites.hpp"

namespace millflow::method {

// The figures of one shear cell that the upscaling sums, per unit cell volume, with their
// standard errors (none when the cell does not report one).
struct CellFigures {
  double input = 0.0;           // power input, W/m^3
  double powder = 0.0;          // dissipation in contacts involving powder, W/m^3
  double collisions = 0.0;      // media-media + wall-media dissipation, W/m^3
  double collision_rate = 0.0;  // media collisions per m^3 per s
  std::optional<double> input_se, powder_se, collisions_se, collision_rate_se;
  double media_solid_fraction = 0.0;
};

// A cell's collision spectra: counts per dissipated-energy bin over its measurement.
struct CellSpectra {
  std::vector<double> bin_edges_j, media_counts, powder_counts;
  double volume_m3 = 0.0, duration_s = 0.0;
};

// The figures and the spectra of a cell that ran (a media collision rate's standard error is
// rate / sqrt(count), a Poisson count's; tasks/upscale.hpp).
CellFigures cell_figures(const CellResult& cell);
CellSpectra cell_spectra(const CellResult& cell);

// What a cell at `site` counts for (tasks/upscale.hpp, Weights).
double site_weight(const Site& site, const CellFigures& cell, WeightBasis basis);

// A weighted sum of cells' figures and its variance; unknown once a cell lacks its error.
struct Sum {
  double value = 0.0, variance = 0.0;
  bool known = true;

  void add(double w, double x, const std::optional<double>& se);
  void merge(const Sum& other);
  Sum scaled(double k) const { return {k * value, k * k * variance, known}; }
  std::optional<double> standard_error() const;
};

// a / b with its standard error (relative errors in quadrature); none when b is not positive.
struct Ratio {
  std::optional<double> value, standard_error;
};
Ratio ratio(const Sum& a, const Sum& b);
// The same for two ratios; none when either has no value or b is not positive.
Ratio ratio(const Ratio& a, const Ratio& b);

// Sums over the sites of one region (or of all), W or collisions per second in the slice: at
// load U over the sites with a loaded cell; at load 0 (and `input_paired`, at load U) over those
// that also have a baseline cell.
struct PowerSums {
  int sites = 0, paired_sites = 0;
  double volume = 0.0, solid_volume = 0.0;
  Sum powder, input, collisions, rate;
  Sum input_paired, input_no_powder, collisions_no_powder, rate_no_powder;

  void add(const Site& site, WeightBasis basis, const CellFigures& loaded,
           const CellFigures* baseline);
  void merge(const PowerSums& r);
  // The factors that set the cells' power input at load U and at load 0 to the macro
  // dissipation D (tasks/upscale.hpp, macro_anchored).
  std::pair<double, double> anchor_factors(double macro_dissipation) const;
  // The sums with the cells' power at each load set to D (the scaling taken as exact in the
  // errors).
  PowerSums anchored(double macro_dissipation) const;
};

// The stiffness sensitivity's sums over the sites of one region (or of all) that have a default
// and a stiff cell at load U and a default cell at load 0 (tasks/upscale.hpp, Stiffness
// sensitivity): the default cells' and the stiff cells' sums, each over the same baselines.
struct StiffnessSums {
  PowerSums normal, stiff;

  void add(const Site& site, WeightBasis basis, const CellFigures& loaded,
           const CellFigures& stiff_loaded, const CellFigures& baseline);
  void merge(const StiffnessSums& other);
};

// The media spectrum's shift (tasks/upscale.hpp, Spectra).
struct SpectrumShift {
  double threshold_j = 0.0;
  std::optional<double> fraction_above;
  double fraction_above_no_powder = 0.0;
};

// Collision rates per energy bin in the slice: the media and powder spectra of the loaded cells
// and the media spectrum of the baseline cells. Throws std::invalid_argument for cells with
// different bins.
class SpectrumSum {
 public:
  void add(double weight, const CellSpectra& cell);
  void add_baseline(double weight, const CellSpectra& cell);
  // Another sum, its loaded spectra scaled by k and its baseline spectrum by k0.
  void add_scaled(const SpectrumSum& other, double k, double k0);

  const std::vector<double>& bin_edges_j() const { return edges_; }
  const std::vector<double>& media() const { return media_; }
  const std::vector<double>& powder() const { return powder_; }
  const std::vector<double>& media_no_powder() const { return media_no_powder_; }
  // The media spectrum above the media-only median's bin; none without media-only collisions.
  std::optional<SpectrumShift> media_shift() const;

 private:
  void use_edges(const std::vector<double>& edges);
  void accumulate(const CellSpectra& cell, const std::vector<double>& counts, double weight,
                  std::vector<double>& rates);

  std::vector<double> edges_, media_, powder_, media_no_powder_;
};

}  // namespace millflow::method
