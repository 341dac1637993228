#pragma once
// The `macro` task kind: one DEM run of the balls in a rotating mill slice (method/macro_run.hpp
// says what it runs, measures and leaves). Parameters: tasks::macro_params (materials,
// interactions, dem, mill, media, macro); their translation into method::MacroSettings is
// tasks/macro_setup.hpp.
//
// Interruption: the stop token is polled every kStepsBetweenPolls steps; on a stop, and every
// macro.checkpoint_interval_s of wall time, the run is saved in the work directory
// (method::MacroRun::save); the next attempt continues from there, or starts again when the
// checkpoint cannot be used.
#include "engine/campaign.hpp"
#include "method/macro_result.hpp"

namespace millflow::tasks {

// Bump whenever the results of the same parameters change.
inline constexpr const char* kMacroVersion = "8";

engine::TaskOutcome run_macro(engine::TaskContext& context);

// A macro task input's result, read and checked (errors name "macro task <key>").
method::MacroResult macro_result_of(const engine::TaskInput& macro);

// macro_results: one row per (campaign, macro task).
// View macro_lineage: each task with the macro run of its sweep point (macro_key, fill,
// speed_fraction). Views of later stages join it; it must be installed before them.
engine::ViewDefinition macro_lineage_view();
engine::ViewDefinition macro_results_view();

}  // namespace millflow::tasks
