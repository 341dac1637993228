#pragma once
// The `upscale` task kind (DESIGN.md section 1, step 4): mill-scale answers of one sweep point
// (fill, speed, powder load) from its shear cells.
//
// Parameters: {"powder_load": U}. Inputs, told apart by kind: the point's macro, average and
// sites tasks, and its shear_cell tasks at load U and at load 0 (the same tasks when U = 0).
// Cells that were skipped (tasks/shear_cell.hpp) count nowhere. With w_s the weight (m^3 of the
// simulated slice) of site s and the cell quantities per unit volume:
//   powder power        P_powder = sum_s w_s d_powder,s(U)   (d_powder: dissipation in every
//                       contact involving powder, W/m^3), per region and its share of the total;
//   media power         P_media = sum_s w_s (p_in,s(U) - d_powder,s(U)): the rest of the power
//                       put into the cells (p_in: the walls' power input per volume);
//   media collision power  C(U) = sum_s w_s (d_media-media,s + d_wall-media,s)(U): the rate of
//                       energy the media lose in collisions with each other (the wall balls of a
//                       cell are media balls too); cushioning = C(U) / C(0) per region and in all;
//   power draw with powder  P_macro x sum_s w_s p_in,s(U) / sum_s w_s p_in,s(0) over the sites
//                       with both cells: the macro run's draw (balls only) scaled by how much
//                       harder (or easier) the charge at the sites is to shear with powder;
//   spectra             collisions per second in the slice per energy bin, sum_s w_s n_s,k /
//                       (V_s T_s) (n: the cell's histogram counts of dissipated energy per
//                       collision, V its volume, T its measuring time), for powder and media;
//   coupling check      per site, the media-only cell's shear stress over the macro flow's
//                       shear stress on the shear plane at the site (tasks/coarse_grain.hpp);
//                       within tolerance when |ratio - 1| <= kCouplingTolerance.
// Result: fill, speed_fraction, powder_load,
// average_task, mill {diameter_m, slice_length_m, ball_mass_kg, power_draw_w,
// specific_power_kw_per_t}, power_draw_with_powder_w, powder_power_w, media_power_w,
// media_collision_power_w, media_collision_power_no_powder_w, cushioning, regions [{region, sites,
// volume_m3, powder_power_w, powder_power_share, media_power_w, media_collision_power_w,
// media_collision_power_no_powder_w, cushioning}], dominant_region, spectra {bin_edges_j,
// powder_rate_per_s, media_rate_per_s}, sites [...], coupling {sites, median_ratio, tolerance,
// within_tolerance}. A ratio with a zero denominator is null.
#include "engine/campaign.hpp"
#include "engine/task.hpp"

namespace millflow::tasks {

inline constexpr const char* kUpscaleVersion = "1";
inline constexpr double kCouplingTolerance = 0.5;

engine::TaskOutcome run_upscale(engine::TaskContext& context);

// upscaled_results: one row per (campaign, upscale task, region).
engine::ViewDefinition upscaled_results_view();

}  // namespace millflow::tasks
