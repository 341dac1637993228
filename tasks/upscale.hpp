#pragma once
// The `upscale` task kind: mill-scale answers of one sweep point (fill, speed, powder load) from
// its shear cells. The sums themselves (weights, standard errors, the macro-anchored scaling,
// spectra) are method/upscale.hpp; this kind reads the inputs and writes the result.
//
// Parameters: {"powder_load": U, "upscale": {"include_unsteady"}, "media_density_kg_m3",
// "powder_density_kg_m3"}. Inputs, told apart by kind: the point's macro, average and sites
// tasks, and its shear_cell tasks at load U and at load 0 (the same tasks when U = 0), and the
// stiff cells at load U (those whose result has stiffness_factor).
//
// Cells that count. Cells that were skipped (tasks/shear_cell.hpp) count nowhere. A cell that is
// not steady (`steady`, else `steady_state.steady`) or not converged (`converged`; a cell without
// it counts as converged when steady) is left out unless /upscale/include_unsteady, and listed in
// `left_out_cells` {site_id, powder_load, reason} either way.
//
// Weights. The cell quantities are per unit volume of the cell. With the sites' /sites/weight_by
//   volume:        a cell at site s counts w_s = the site's volume (weight_m3);
//   solid_volume:  w_s = the site's solid volume / the cell's media solid fraction: the cell's
//                  power per volume of media times the media's volume at the site (so a dilute
//                  region is not weighted as if it were as dense as the cell at its stress).
//
// Method "cells" (the top-level fields and `regions`), per region and in all:
//   powder power        P_powder = sum_s w_s d_powder,s(U)   (d_powder: dissipation in every
//                       contact involving powder, W/m^3) and its share of the total;
//   media power         P_media = sum_s w_s (p_in,s(U) - d_powder,s(U)): the rest of the power
//                       put into the cells (p_in: the power input per volume);
//   media collision power  C(U) = sum_s w_s (d_media-media,s + d_wall-media,s)(U) (the wall
//                       balls of a cell are media too); cushioning = C(U) / C(0), split into
//                       cushioning_rate_factor = R(U) / R(0), R = sum_s w_s r_s the media
//                       collisions per second (collisions.media.rate_per_m3_s), and
//                       cushioning_energy_factor = (C/R)(U) / (C/R)(0), the energy per media
//                       collision; their product is the cushioning;
//   cell_to_macro_power_ratio  sum_s w_s p_in,s(0) / D_r: the media-only cells' power over the
//                       macro run's dissipation D_r in the region (sites' regions), beside the
//                       coupling check; below 1 where impacts carried in by the stream dissipate
//                       energy that local shear does not.
// Method "macro_anchored" (`macro_anchored`, same fields per region): each region's power is the
// macro run's dissipation D_r there, split as its cells split theirs: every cell sum of the region
// at load U is scaled by D_r / sum_s w_s p_in,s(U), and at load 0 by D_r / sum_s w_s p_in,s(0).
// So powder + media power = D_r in every region with cells: the method conserves the macro
// dissipation of the regions it covers (`macro_dissipation_w`; the regions without cells are
// `uncovered_macro_dissipation_w`). Its spectra and media spectrum shift are the regions' cell
// spectra scaled by the same factors.
//
// Power draw with powder = P_macro (1 + M) sum_s w_s p_in,s(U) / sum_s w_s p_in,s(0) over the
// sites with both cells. P_macro is the balls-only run's draw; the ratio is how much harder the
// charge is to shear with powder at the site's stress; (1 + M) accounts for the powder's mass:
// M = sum_s V_s m_s / sum_s V_s (V_s the site's solid volume, m_s = rho_powder nu_powder /
// (rho_media nu_media) of the loaded cell) is the powder's mass over the media's. The cells are
// driven at the balls-only normal stress, while in the mill the normal stress is the weight of
// the charge above, (1 + M) times larger with powder. In the dense frictional flow of a mill
// (inertial number well below 0.1) the stress ratio mu(I) does not depend on the pressure, so
// the shear stress, and the power at a given shear rate, scale with the normal stress: the cell
// power at (1 + M) sigma is (1 + M) times the power at sigma. The same factor is the torque-arm
// view: the draw is M_charge g x_com omega, and powder in the voids adds mass without moving the
// centre of mass. Not re-running the cells at the heavier stress keeps the baseline and loaded
// cells at one stress, so the ratio stays a like-for-like comparison.
//
// Spectra: collisions per second in the slice per energy bin, sum_s w_s n_s,k / (V_s T_s) (n:
// the cell's histogram counts of dissipated energy per collision, V its volume, T its measuring
// time), for powder, media and media without powder. The media spectrum's shift:
// threshold_j = the lower edge of the bin holding the rate-weighted median of the media-only
// spectrum, and the fraction of media collisions at or above it with and without powder (0.5 or
// so without; lower when powder takes the high-energy collisions).
//
// Standard errors (`*_se`) from the cells' standard_errors (batch means, issue "Shear cells a
// researcher can trust"): sums of independent cells add variances, sum_s w_s^2 se_s^2; the media
// collision dissipation's error is the sum of its two contact types' (their correlation unknown,
// so the larger bound); ratios add relative errors in quadrature (the two taken as
// independent); a collision rate's relative error is 1/sqrt(count) (a Poisson count). Any cell
// without the standard error it needs makes the figure null.
//
// Stiffness sensitivity (only with the stiff cells of /shear_cell/stiffness/sensitivity, whose
// powder pairs' k_n are F x the policy's, tasks/shear_cell.hpp): the stiff cells count in none of
// the figures above. Per region with them and over all, at the sites that have a default and a
// stiff cell at load U and a default cell at load 0 (the stiff cells' reference: without powder
// they would be the default ones), the same sums as the cells method (the stiff cells with their
// own weights) give
//   cushioning(_stiff)    C(U) / C(0), with the default and the stiff loaded cells;
//   cushioning_shift      cushioning_stiff / cushioning - 1 = C_stiff(U) / C(U) - 1: the
//                         baselines cancel, so its error is the loaded cells' alone;
//   powder_share(_stiff)  P_powder / P_in at load U: the powder's share of the power put into the
//                         cells (what the macro-anchored method multiplies the macro dissipation
//                         by), not a region's share of the powder power;
//   powder_share_shift    powder_share_stiff / powder_share - 1;
// each with its standard error as above (the default and stiff cells independent). Comparing
// the same sites keeps the sites' scatter out of the shift: it is the systematic error of the
// policy's stiffness, which the error bars above do not carry (docs/method.md). Stiff cells left
// out by the rule above are listed in stiffness_sensitivity.left_out_cells, not left_out_cells.
//
// Sensitivity: for each rule set of the sites task (default and alternatives), each region's
// powder power with the macro-anchored method, D_r(rule set) x the powder fraction of the default
// regions' cells, with the dominant region and the toe's share (regions without cells: none).
//
// Result (method/upscale_result.hpp, the one spelling of its keys): fill, speed_fraction,
// powder_load, average_task, sites_task, mill {diameter_m, slice_length_m, ball_mass_kg,
// power_draw_w, specific_power_kw_per_t}, the cells method's totals and regions (above),
// powder_to_media_mass_ratio, power_draw_with_powder_w, macro_anchored, sensitivity, spectra,
// media_spectrum_shift, left_out_cells, sites (per site: position, weight, macro state, cell
// results, coupling ratio), coupling {sites, median_ratio, tolerance, within_tolerance},
// stiffness_sensitivity {factor, regions {<region>: figures}, totals, left_out_cells} (absent
// without stiff cells).
//
// Coupling check: per site, the media-only cell's shear stress over the macro flow's shear stress
// on the shear plane at the site (method/coarse_grain.hpp); within tolerance when |ratio - 1| <=
// kCouplingTolerance. A ratio with a zero denominator is null.
#include "engine/campaign.hpp"
#include "engine/task.hpp"

namespace millflow::tasks {

// 5: the powers and the powder-to-media mass ratio are null where no cell was counted (they read
// 0 W), and a site whose cell was left out says so in `skipped`.
inline constexpr const char* kUpscaleVersion = "5";
inline constexpr double kCouplingTolerance = 0.5;

engine::TaskOutcome run_upscale(engine::TaskContext& context);

// upscaled_results: one row per (campaign, upscale task, method, region); a point without a
// counted cell (no region) has one row per method, its region and powers null.
engine::ViewDefinition upscaled_results_view();

}  // namespace millflow::tasks
