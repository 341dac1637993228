#pragma once
// Whether a shear cell is stationary (docs/shear_cells.md, "Compaction and stationarity"): a
// statistical test of the last warm-up windows' means. The windows are the batches: their means
// scatter (by ~10% in a small collisional cell, and the samples inside a window stay correlated
// for longer than a window, so a window's own standard error is far too small), and a drift
// counts only when it stands out of that scatter. Over the last n >= 3 windows k = 0..n-1, each
// quantity x gets a least-squares line x_k = a + b k; s_b is the standard error of the slope
// from the residuals (n - 2 degrees of freedom) and m the mean, se_m = sd / sqrt(n):
//   shear stress:   |b| (n - 1) <= z s_b (n - 1) + shear_floor |m|
//   solid fraction: |b| (n - 1) <= max(solid_fraction_drift, z s_b (n - 1))
//   normal stress:  |m - p_target| <= max(tolerance p_target, z se_m), and every window's mean
//                   at least contact_fraction p_target (a bed still closing after compaction
//                   carries far less, and its scatter would hide that)
//   bulk shear rate (walls only, target > 0): |m - g_target| <= max(tolerance g_target, z se_m),
//                   and |b| (n - 1) <= z s_b (n - 1) + rate_floor |m| (a rough-wall bed follows
//                   its walls over 5-10 strains, and its rate then still rises through windows
//                   whose mean is on target: docs/cell_validation.md, table 4 a fifth time)
// A cell still compacting drifts in solid fraction (and stress) by more than its scatter allows
// and fails; a stationary one fails the drift tests only by chance (Student's t with n - 2
// degrees of freedom beyond z: 12% of windows at n = 4 and z = 2.5, and the next window is
// tested again).
#include <span>

namespace millflow::dem {

// One warm-up window's means over its samples.
struct WindowMeans {
  double shear_stress = 0.0, normal_stress = 0.0, solid_fraction = 0.0, bulk_shear_rate = 0.0;
};

struct StationarityCriterion {
  double z = 2.5;                      // standard errors a drift or an offset may reach
  double shear_floor = 0.02;           // relative drift of shear stress always allowed
  double rate_floor = 0.05;            // relative drift of the bulk shear rate always allowed
  double solid_fraction_drift = 0.01;  // absolute drift of solid fraction always allowed
  double tolerance = 0.1;              // relative offset of normal stress and rate allowed
  double contact_fraction = 0.5;       // of the target normal stress, in every window
};

struct StationarityVerdict {
  bool shear_stress = false, solid_fraction = false, normal_stress = false, bulk_shear_rate = false;
  bool stationary() const {
    return shear_stress && solid_fraction && normal_stress && bulk_shear_rate;
  }
};

// The least-squares line x_k = a + b k through a series k = 0..n-1 (n >= 3): its mean m and
// se_m, its drift b (n - 1) and the drift's standard error s_b (n - 1). Also the wall-speed
// controller's test of a steady bulk fraction (dem/wall_speed_controller.hpp).
struct SeriesFit {
  double mean = 0.0, mean_error = 0.0;    // mean and its standard error (scatter / sqrt(n))
  double drift = 0.0, drift_error = 0.0;  // slope x (n - 1) and its standard error
};
SeriesFit fit_series(std::span<const double> x);

// The test above over `windows` (oldest first, at least 3; fewer fail); target_shear_rate <= 0
// skips the rate (Lees-Edwards imposes it).
StationarityVerdict test_stationarity(std::span<const WindowMeans> windows,
                                      double target_normal_stress, double target_shear_rate,
                                      const StationarityCriterion& criterion = {});

}  // namespace millflow::dem
