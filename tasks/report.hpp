#pragma once
// The `report` task kind: one per campaign, over all its upscale tasks (tasks/upscale.hpp; other
// inputs are ignored). Parameters: {"campaign": name}. Writes into its work directory, and
// returns as artifacts:
//   index.md                  the page: what each figure shows, the dominant region and the
//                             coupling check per point, links to everything below;
//   power_draw.svg            power draw vs speed fraction per fill (macro run, balls only) and,
//                             dashed, with each powder load;
//   shares_<point>.svg        each region's share of the powder power vs powder load;
//   cushioning_<point>.svg    media-media collision power with / without powder vs powder load;
//   spectra_<point>.svg       powder collisions per second per energy bin, one line per load;
//   upscaled.csv              one row per point x region (the upscaled_results columns);
//   sites.csv                 one row per point x site (coupling check, cell power densities);
//   spectra.csv               one row per point x energy bin.
// <point> is J<fill>_N<speed fraction>. Points are sorted by fill, speed, load; numbers are
// printed with fixed formats, so the same inputs give the same bytes.
#include "engine/campaign.hpp"
#include "engine/task.hpp"

namespace millflow::tasks {

inline constexpr const char* kReportVersion = "1";

engine::TaskOutcome run_report(engine::TaskContext& context);

}  // namespace millflow::tasks
