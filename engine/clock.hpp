#pragma once
// The wall clock as an interface, so tests can pin time.
#include <chrono>
#include <string>

namespace millflow::engine {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual double now() const = 0;  // seconds since the Unix epoch
};

class SystemClock final : public Clock {
 public:
  double now() const override {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
        .count();
  }
};

// ISO-8601 UTC with milliseconds, e.g. "2024-06-11T05:14:30.125Z", for stored Unix seconds.
std::string iso8601_utc(double unix_seconds);

}  // namespace millflow::engine
