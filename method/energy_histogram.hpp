#pragma once
// A histogram of energy per collision (dem::LogHistogram) as results store it: the counts per
// bin, underflow and overflow; the bin edges are shared by a result's histograms and written once.
#include <vector>

#include <nlohmann/json.hpp>

#include "dem/spectrum.hpp"

namespace millflow::method {

struct EnergyHistogram {
  std::vector<double> counts{};
  double underflow = 0.0, overflow = 0.0;
};

EnergyHistogram energy_histogram(const dem::LogHistogram& h);
// The bin edges of `grid` (bin count + 1 values, none for an empty grid).
std::vector<double> bin_edges(const dem::LogHistogram& grid);

// {counts, underflow, overflow}
void to_json(nlohmann::json& out, const EnergyHistogram& h);

}  // namespace millflow::method
