#pragma once
// The `average` task kind: coarse-grained fields (method/coarse_grain.hpp) of one macro run.
//
// Parameters: {"average": {"grid_cells": [nx, ny], "kernel_width_diameters": k}}; the kernel
// width is k x the media diameter. Input 0: the macro task, whose result gives the mill
// ("mill": radius_m, length_m), media_diameter_m, ball_mass_kg (all balls together; with the
// balls' volume in the first frame it gives the media density), categories, frame_count,
// sample_interval_s (each frame carries the collisions of the interval before it, so the events
// span frame_count x sample_interval_s) and angular_velocity_rad_s, and whose artifacts
// flow/segment_NNNN.mfs hold the frames.
//
// Artifacts: fields.vti (every field as VTK cell data, for ParaView) and fields.json (the same
// arrays with the grid and the mill, method/fields_file.hpp, read by `sites` and the report).
// Result: the grid, the kernel width, the mass-conservation check (integral of the solid fraction x
// slice length vs the media volume), the maximum and the mean over the charge of every scalar
// field, and the mill-wide collision rate and dissipated power per contact category.
#include <nlohmann/json.hpp>

#include "engine/task.hpp"
#include "method/coarse_grain.hpp"

namespace millflow::tasks {

// Bump whenever the results change (tests/tasks/golden/average.json guards it).
inline constexpr const char* kAverageVersion = "2";

engine::TaskOutcome run_average(engine::TaskContext& context);

}  // namespace millflow::tasks
