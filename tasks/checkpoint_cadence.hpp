#pragma once
// When a long task saves a checkpoint besides on a stop request: once `interval_s` of wall time
// has passed since the last one (the macro and shear_cell kinds' checkpoint_interval_s).
#include <chrono>

namespace millflow::tasks {

class CheckpointCadence {
 public:
  using Clock = std::chrono::steady_clock;
  explicit CheckpointCadence(double interval_s) : interval_(interval_s), last_(Clock::now()) {}
  bool due() const { return Clock::now() - last_ > interval_; }
  void saved() { last_ = Clock::now(); }

 private:
  std::chrono::duration<double> interval_;
  Clock::time_point last_;
};

}  // namespace millflow::tasks
