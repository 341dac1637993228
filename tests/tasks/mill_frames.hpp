#pragma once
// Flow-sample frames of a small, slowly turning mill (tests/dem/scenes.hpp's 0.2 m slice, J = 0.4,
// 20% of critical speed) for the analysis tests, and a macro-like result describing them.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "dem/flow_sample.hpp"

namespace millflow::tasks::testing {

struct MillSample {
  std::vector<std::filesystem::path> segments;  // flow/segment_NNNN.mfs, in order
  nlohmann::json macro_result;                  // what the macro task reports about the run
};

// Built once per build directory (cached under MILLFLOW_BINARY_DIR/test_data; deterministic).
const MillSample& small_mill_sample();

}  // namespace millflow::tasks::testing
