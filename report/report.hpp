#pragma once
// The campaign report: a directory of SVG figures, CSV tables and an index.md page over every
// upscale point of a campaign (the `report` task kind, tasks/report.hpp, reads its inputs).
//
// Parameters: {"campaign": name} (the page's title). Inputs, found by kind (never by position):
// every "upscale" task of the campaign, the "average" tasks they name (their fields.json), the
// "sites" tasks of the same points (their regions) and the "macro" tasks (charge shape and
// collision spectra), see report/report_inputs.hpp. Files, written into the work directory and
// returned as artifacts of the same names:
//   power_draw.svg           macro power draw vs speed fraction per fill (solid), and the draw
//                            with powder per fill and powder load > 0 (dashed);
//   powder_power_shares.svg  each region's share of the powder power vs powder load, a panel per
//                            fill (row) and speed (column), with +- one standard error bars
//                            where the upscale gives one (powder_power_share_se);
//   cushioning.svg           media-media collision power with / without powder vs powder load,
//                            per region, the same panels and bars (cushioning_se);
//   powder_spectra.svg       powder collision rate per energy bin (log-log), a panel per fill and
//                            speed, a step line per powder load;
//   charge_shape.svg         each macro run's toe and shoulder angles vs speed fraction, a colour
//                            per fill (from the macro inputs, none without);
//   macro_spectra.svg        each macro run's ball-ball and ball-liner collisions per second per
//                            bin of impact and dissipated energy (log-log), a panel per run
//                            (from the macro inputs, none without);
//   maps_<fill>_<speed>.svg  shear rate, normal stress and dissipation over the cross-section with
//                            the sites marked (from the average task of that fill and speed);
//   regions_<fill>_<speed>.svg  the flow regions over the cross-section with the charge outline,
//                            toe and shoulder, and index.md's region, sensitivity and
//                            both-upscalings tables and its list of the cells left out of the
//                            upscaling (report/report_regions.hpp; from the sites inputs, none
//                            without);
//   coupling.svg             media-only cell vs macro shear stress per site, with the 1:1 line;
//   upscaled.csv             one row per point x region (with powder_power_share_se and
//                            cushioning_se);  sites.csv  one row per point x site;
//   spectra.csv              one row per point x energy bin;
//   index.md                 the page: what each figure shows, the points with their dominant
//                            region, the coupling agreement, links to the tables and figures;
//                            with stiff cells (/shear_cell/stiffness/sensitivity) a section with
//                            a sentence per point and a table per point and region of how far
//                            cushioning and the powder share move with the powder's stiffness.
// Points are ordered by fill, speed fraction, powder load; numbers are written with fixed formats
// (CSV: the shortest text that reads back to the same double), so the same inputs give the same
// bytes. Result: {campaign, files, points, slices, dominant_regions: [{fill, speed_fraction,
// powder_load, region}], coupling: {sites, within_tolerance}}.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "report/report_inputs.hpp"
#include "report/report_regions.hpp"

namespace millflow::report {

struct ReportFiles {
  nlohmann::json result;           // the report task's result (above)
  std::vector<std::string> names;  // the files written, in order, relative to the directory
  std::size_t slices = 0;          // fill/speed slices
};

// Writes every file into `dir` (created if missing), durably.
ReportFiles write_report(const std::filesystem::path& dir, const std::string& campaign,
                         const ReportInputs& inputs, const RegionSection& regions);

}  // namespace millflow::report
