#pragma once
// The wall clock as an interface, so tests can pin time.
#include <chrono>

namespace millflow::engine {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual double now() const = 0;  // seconds since the Unix epoch
};

class SystemClock final : public Clock {
 public:
  double now() const override {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  }
};

}  // namespace millflow::engine
