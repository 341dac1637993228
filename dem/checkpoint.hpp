#pragma once
// Checkpoints of a DEM system: the full state, so that a run continued from a checkpoint gives
// the same bits as a run that never stopped.
//
// File: the checksummed container of dem/binary_io.hpp with magic "MFDEMCKP", payload version
// kCheckpointVersion. Payload (version 4), in order, every Vec3 as three doubles:
//   materials: count; per material: name, density; per pair a <= b: defined flag (uint8) and, if
//              defined, restitution, friction, normal stiffness, tangential stiffness ratio,
//              tangential damping ratio
//   domain: lo, hi, periodic[3] (uint8), Lees-Edwards enabled (uint8), flow axis, gradient axis
//           (int32), offset, velocity
//   gravity, dt, time, step count (uint64), neighbour skin, record-collisions flag (uint8),
//   prepared flag (uint8: initial forces computed),
//   random generator state (4 x uint64)
//   particles: count; then per particle position, velocity, angular velocity, force, torque,
//              radius, mass, inverse mass, inverse inertia, material (uint32), group (uint32)
//   groups: count; per group name, velocity, load (force, torque, power, work) (versions 1-3
//           held a servo axis (int32), target, mobility and max speed after the velocity: read
//           and dropped, the groups' servo is gone)
//   walls: count; per wall name, material (uint32), shape tag (uint8: 0 plane, 1 mill), then
//          plane: origin, normal, velocity, servo target, servo mobility, servo max speed; or mill:
//          radius, length, lifter count (int32), lifter height, base width, face angle, end walls
//          (uint8), angular velocity, angle; then load (force, torque, power, work)
//   pair contacts in force: count; per contact i, j (uint32), its history and the force on i
//                           (the force since version 2: version 1 files restore it as zero, so
//                           a stress read before the next step misses the pair contacts)
//   wall contacts: per particle count (uint8) and, per contact, wall, feature (int32), history,
//                  force on the particle, contact point (the history's again)
//   dissipation of finished contacts per category: count; normal, tangential, friction each
//   since version 3: the contact virial (System::contact_virial), 9 doubles row by row (older
//   files sum it again from the pair forces, in another order, so its last bits may differ),
//   and the reorder interval (uint64; 0 in older files)
// A history is: spring, start time, impact speed, impact energy, elastic energy, dissipated
// (normal, tangential, friction), contact point, touching (uint8, 1: only contacts in force are
// written).
// Collision events not yet taken are not saved: take them before checkpointing.
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "dem/binary_io.hpp"
#include "dem/system.hpp"

namespace millflow::dem {

inline constexpr std::uint32_t kCheckpointVersion = 4;

// The payload above, for files that keep a system beside state of their own (the shear cell's
// checkpoint, dem/shear_cell.hpp); `version` is the payload's (kCheckpointVersion when written by
// this build). Throws CorruptData for bytes that do not describe a system or a newer version.
std::string checkpoint_payload(const System& system);
System system_from_checkpoint_payload(std::string_view payload, std::uint32_t version);

// The same system (particles, motion, walls, groups, contacts and their histories) with other
// materials of the same names: every contact's dashpot is worked out again from them, as a
// checkpoint's loader does, so the copy holds exactly what a run continued from a checkpoint
// saved with these materials would.
System system_with_materials(const System& system, const MaterialTable& materials);

// The encodings the payload uses for a material and a pair's interaction, shared with the shear
// cell's run identity.
void put_material(BinaryWriter& out, const Material& material);
void put_interaction(BinaryWriter& out, const InteractionSpec& spec);

// Writes atomically (temp file + rename): a crash leaves the previous checkpoint intact.
void save_checkpoint(const System& system, const std::filesystem::path& path);

// Throws CorruptData for a missing, truncated, altered or newer file.
System load_checkpoint(const std::filesystem::path& path);

}  // namespace millflow::dem
