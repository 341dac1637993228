// ShearCellRun: compaction, warm-up windows until stationary, then the measured window, in pieces
// that can stop between any two steps.
#include "dem/shear_cell.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dem/shear_cell_geometry.hpp"

namespace millflow::dem {

using namespace shear_cell_detail;

ShearCellRun::ShearCellRun(const ShearCellSetup& setup, const ShearCellProtocol& protocol)
    : ShearCellRun(ShearCell(setup), protocol) {}

ShearCellRun::ShearCellRun(ShearCell cell, const ShearCellProtocol& protocol)
    : cell_(std::move(cell)), protocol_(protocol) {
  if (protocol_.warmup_windows < 1 || !(protocol_.warmup_strain >= 0.0)) {
    throw std::invalid_argument(
        fmt::format("shear cell: warm-up of {} strain in {} windows; need strain >= 0 and "
                    "windows >= 1",
                    protocol_.warmup_strain, protocol_.warmup_windows));
  }
  if (!(protocol_.max_warmup_strain >= protocol_.warmup_strain)) {
    throw std::invalid_argument(
        fmt::format("shear cell: the warm-up's cap of {} strain is below its {} strain; raise the "
                    "cap to at least the warm-up",
                    protocol_.max_warmup_strain, protocol_.warmup_strain));
  }
  const double window_strain = protocol_.warmup_strain / protocol_.warmup_windows;
  window_steps_ = protocol_.warmup_strain > 0.0 ? cell_.steps_for_strain(window_strain) : 0;
  max_windows_ =
      protocol_.warmup_strain > 0.0
          ? std::max(
                protocol_.warmup_windows,
                static_cast<int>(std::floor(protocol_.max_warmup_strain / window_strain + 1e-9)))
          : 0;
  measure_steps_ =
      cell_.steps_for_strain(std::max(protocol_.measure_strain, protocol_.measure.max_strain));
}

bool ShearCellRun::advance(std::uint64_t max_steps) {
  std::uint64_t left = max_steps;
  while (!done()) {
    const std::uint64_t before = cell_.system().step_count();
    if (phase_ == Phase::Compacting) {
      cell_.compact(left);
    } else if (phase_ == Phase::WarmUp) {
      cell_.advance_window(window_, left);
    } else {
      cell_.advance_measurement(measurement_, left);
    }
    left -= std::min(left, cell_.system().step_count() - before);
    const bool piece_finished = (phase_ == Phase::Compacting && cell_.compacted()) ||
                                (phase_ == Phase::WarmUp && window_.finished()) ||
                                (phase_ == Phase::Measuring && measurement_.finished());
    if (!piece_finished) break;
    start_next_piece();
    if (left == 0) break;
  }
  return done();
}

void ShearCellRun::start_next_piece() {
  if (phase_ == Phase::WarmUp) {
    const WindowMeans* previous = windows_.empty() ? nullptr : &windows_.back();
    windows_.push_back(cell_.finish_window(window_, window_index_++, previous));
    // The last warmup_windows windows (at least 3) are the batches of the test.
    const std::size_t tested = std::max<std::size_t>(3, protocol_.warmup_windows);
    stationary_ = windows_.size() >= tested && cell_.stationary(std::span(windows_).last(tested));
    if (stationary_) {
      stationary_strain_ = cell_.setup().shear_rate * cell_.system().time();
      spdlog::debug("shear cell: stationary after {} warm-up windows, strain {:.3g}", window_index_,
                    stationary_strain_);
    }
  }
  if (phase_ == Phase::Measuring) {
    result_ = cell_.finish_measurement(measurement_);
    result_.stationary = stationary_;
    result_.stationary_strain = stationary_strain_;
    result_.steady = result_.steady && stationary_;
    phase_ = Phase::Done;
    return;
  }
  if (window_steps_ > 0 && !stationary_ && window_index_ < max_windows_) {
    phase_ = Phase::WarmUp;
    window_ = cell_.start_window(protocol_.warmup_strain / protocol_.warmup_windows);
    return;
  }
  phase_ = Phase::Measuring;
  if (window_index_ == 0) cell_.choose_neighbor_skin();  // no warm-up window chose it
  measurement_ = cell_.start_measurement(protocol_.measure_strain, protocol_.measure);
}

double ShearCellRun::progress() const {
  // Compaction against the steps it is expected to take (it may stay there a while or jump
  // ahead), the rest against the caps: a cell that becomes stationary or converges early jumps
  // ahead.
  const std::uint64_t compaction = cell_.expected_compaction_steps();
  const std::uint64_t warmup = window_steps_ * static_cast<std::uint64_t>(max_windows_);
  const std::uint64_t total = compaction + warmup + measure_steps_;
  std::uint64_t done_steps = 0;
  switch (phase_) {
    case Phase::Compacting:
      done_steps = std::min(cell_.system().step_count(), compaction);
      break;
    case Phase::WarmUp:
      done_steps = compaction + std::min(window_steps_ * static_cast<std::uint64_t>(window_index_) +
                                             window_.done,
                                         warmup);
      break;
    case Phase::Measuring:
      done_steps = compaction + warmup + std::min(measurement_.done, measure_steps_);
      break;
    case Phase::Done:
      done_steps = total;
      break;
  }
  return static_cast<double>(done_steps) / static_cast<double>(total);
}

std::string ShearCellRun::phase_name() const {
  switch (phase_) {
    case Phase::Compacting:
      return "compacting";
    case Phase::WarmUp:
      return fmt::format("warm-up window {} (at most {})", window_index_ + 1, max_windows_);
    case Phase::Measuring:
      return "measuring";
    case Phase::Done:
      return "measured";
  }
  return "unknown";
}

const ShearCellMeasurements& ShearCellRun::measurements() const {
  if (!done()) throw std::logic_error("shear cell run: no measurements before the run is done");
  return result_;
}

}  // namespace millflow::dem
