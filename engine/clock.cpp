#include "engine/clock.hpp"

#include <fmt/format.h>

#include <cmath>
#include <ctime>

namespace millflow::engine {

std::string iso8601_utc(double unix_seconds) {
  const auto milliseconds = static_cast<std::int64_t>(std::llround(unix_seconds * 1000.0));
  const auto whole =
      static_cast<std::time_t>(std::floor(static_cast<double>(milliseconds) / 1000.0));
  const auto fraction = milliseconds - static_cast<std::int64_t>(whole) * 1000;
  std::tm utc{};
  ::gmtime_r(&whole, &utc);
  return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", utc.tm_year + 1900,
                     utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec, fraction);
}

}  // namespace millflow::engine
