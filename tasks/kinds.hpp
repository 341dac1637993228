#pragma once
// The task kinds of the multiscale method (docs/method.md, "The four steps"), each in its own file,
// and the slices of a campaign point that each kind's parameters are made of.
//
// A kind's parameters hold exactly what its result depends on, so that changing a micro-scale
// setting re-keys the shear cells but reuses the macro runs (the keys form a Merkle chain).
#include <nlohmann/json.hpp>

#include "engine/campaign.hpp"

namespace millflow::tasks {

// macro: one DEM run of the balls in the mill per (fill, speed, ...). Upstream: none.
void register_macro(engine::Registry& registry);
// average: coarse-grained fields of one macro run. Upstream: the macro task.
void register_average(engine::Registry& registry);
// sites: flow regions and representative sites of one average. Upstream: the average and macro
// tasks.
void register_sites(engine::Registry& registry);
// shear_cell: one microscale shear cell per site slot and powder load (tasks/shear_cell.hpp).
// Upstream: the sites task.
void register_shear_cells(engine::Registry& registry);
// upscale: mill-scale answers of one fill x speed x powder load (tasks/upscale.hpp). Upstream:
// the macro, average and sites tasks, the cells at that load and at load 0.
void register_upscale(engine::Registry& registry);
// report: plots, tables and a page over every upscale of a campaign (tasks/report.hpp).
// Upstream: the upscale tasks.
void register_report(engine::Registry& registry);

// Parameter slices of a campaign point (a validated document with the sweep applied).
nlohmann::json macro_params(const nlohmann::json& point);    // materials and interactions of media
                                                             // and liner, dem, mill, media, macro
nlohmann::json average_params(const nlohmann::json& point);  // average
nlohmann::json sites_params(const nlohmann::json& point);    // sites
nlohmann::json upscale_params(const nlohmann::json& point);  // powder load, upscale, and the
                                                             // media's and powder's densities
nlohmann::json shear_cells_params(const nlohmann::json& point);  // shear_cell, dem.seed, media, and
                                                                 // the materials and interactions
                                                                 // of media and powder
// The shear_cell tasks of a point, one per slot (region in /sites/regions x index below
// /sites/per_region), below its sites task; returns their keys.
std::vector<std::string> plan_shear_cells(engine::Plan& plan, const nlohmann::json& point,
                                          const std::string& sites);
// The stiff cells of /shear_cell/stiffness/sensitivity at the point's load (none without it): the
// point's cell parameters with stiffness_factor F, one per slot of its regions (all of
// /sites/regions when it names none) x index below its sites_per_region; returns their keys.
std::vector<std::string> plan_stiff_cells(engine::Plan& plan, const nlohmann::json& point,
                                          const std::string& sites);

}  // namespace millflow::tasks
