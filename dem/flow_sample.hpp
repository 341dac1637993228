#pragma once
// Flow samples: snapshots of a DEM run (particle states, contacts in force, and the collisions
// that finished since the previous snapshot) that coarse-graining reads later, so averaging
// settings can change without re-running the DEM.
//
// A run writes its frames in segments, each a checksummed container (dem/binary_io.hpp) with
// magic "MFFLOWS1" and payload version kFlowSampleVersion. Payload (version 1):
//   uint64 frame count, then per frame, in this order:
//     time (f64, s), mill angle (f64, rad; 0 when there is no mill)
//     particles: each array as uint64 count + data
//       position, velocity, angular velocity (float32 x 3 each), radius (float32), material
//       (uint32)
//     contacts in force:
//       a (uint32), b (uint32: particle, or wall index), with_wall (uint8),
//       point, force on a, branch a -> b (float32 x 3 each)
//     collisions finished since the previous frame:
//       time (f64), point (float32 x 3), impact energy (float32, J), dissipated energy (float32,
//       J), category (uint32, System::category_name), with_wall (uint8)
// Single precision keeps a sample near 100 bytes per particle; it is plenty for averages.
#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "dem/system.hpp"

namespace millflow::dem {

inline constexpr std::uint32_t kFlowSampleVersion = 1;

using Float3 = std::array<float, 3>;

struct FlowFrame {
  double time = 0.0;
  double mill_angle = 0.0;

  std::vector<Float3> position, velocity, angular_velocity;
  std::vector<float> radius;
  std::vector<std::uint32_t> material;

  std::vector<std::uint32_t> contact_a, contact_b;
  std::vector<std::uint8_t> contact_with_wall;
  std::vector<Float3> contact_point, contact_force, contact_branch;

  std::vector<double> event_time;
  std::vector<Float3> event_point;
  std::vector<float> event_impact_energy, event_dissipated;
  std::vector<std::uint32_t> event_category;
  std::vector<std::uint8_t> event_with_wall;
};

// The free particles' state and contacts now, and the given finished collisions.
FlowFrame capture_frame(const System& system, double mill_angle,
                        std::span<const CollisionEvent> events);

// Atomic write (temp file + rename). Throws std::system_error on I/O failure.
void write_flow_segment(const std::filesystem::path& path, std::span<const FlowFrame> frames);

// Throws CorruptData for a missing, truncated, altered or newer file.
std::vector<FlowFrame> read_flow_segment(const std::filesystem::path& path);

}  // namespace millflow::dem
