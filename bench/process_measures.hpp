#pragma once
// What every benchmark program measures of itself: CPU time and peak memory of the process
// (getrusage), a scene's contacts per particle, and a hash of its state, so that two builds or a
// fresh and a cached scene can be shown to step the same bits.
#include <sys/resource.h>

#include <cstdint>
#include <span>

#include "dem/system.hpp"

namespace millflow::bench {

// User + system CPU seconds of this process so far (every thread).
inline double process_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const auto seconds = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
  };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

inline double peak_rss_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

// Pair and wall contacts in force per particle.
inline double contacts_per_particle(const dem::System& system) {
  return static_cast<double>(system.active_contact_count()) / static_cast<double>(system.size());
}

// FNV-1a over the bytes of the positions and velocities.
inline std::uint64_t state_hash(const dem::System& system) {
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  const auto mix = [&](std::span<const dem::Vec3> values) {
    const auto* bytes = reinterpret_cast<const unsigned char*>(values.data());
    for (std::size_t b = 0; b < values.size_bytes(); ++b)
      hash = (hash ^ bytes[b]) * 0x100000001b3ULL;
  };
  mix(system.positions());
  mix(system.velocities());
  return hash;
}

}  // namespace millflow::bench
