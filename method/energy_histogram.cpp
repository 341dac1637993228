#include "method/energy_histogram.hpp"

namespace millflow::method {

EnergyHistogram energy_histogram(const dem::LogHistogram& h) {
  EnergyHistogram out{.counts = std::vector<double>(h.bin_count()),
                      .underflow = h.underflow(),
                      .overflow = h.overflow()};
  for (std::size_t k = 0; k < out.counts.size(); ++k) out.counts[k] = h.count(k);
  return out;
}

std::vector<double> bin_edges(const dem::LogHistogram& grid) {
  std::vector<double> edges;
  for (std::size_t k = 0; k < grid.bin_count(); ++k) edges.push_back(grid.bin_lower(k));
  if (grid.bin_count() > 0) edges.push_back(grid.bin_upper(grid.bin_count() - 1));
  return edges;
}

void to_json(nlohmann::json& out, const EnergyHistogram& h) {
  out = {{"counts", h.counts}, {"underflow", h.underflow}, {"overflow", h.overflow}};
}

}  // namespace millflow::method
