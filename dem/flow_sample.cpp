#include "dem/flow_sample.hpp"

#include <fmt/format.h>

#include "dem/binary_io.hpp"

namespace millflow::dem {
namespace {

constexpr std::string_view kMagic = "MFFLOWS1";

Float3 to_float3(const Vec3& v) {
  return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

template <class T>
void put(BinaryWriter& out, const std::vector<T>& values) {
  out.put_span(std::span<const T>(values));
}

template <class T>
void get(BinaryReader& in, std::vector<T>& values) {
  values = in.get_vector<T>();
}

// One list of every array of a frame, so writing and reading cannot drift apart.
template <class Frame, class Visit>
void visit_arrays(Frame& f, Visit&& visit) {
  visit(f.position);
  visit(f.velocity);
  visit(f.angular_velocity);
  visit(f.radius);
  visit(f.material);
  visit(f.contact_a);
  visit(f.contact_b);
  visit(f.contact_with_wall);
  visit(f.contact_point);
  visit(f.contact_force);
  visit(f.contact_branch);
  visit(f.event_time);
  visit(f.event_point);
  visit(f.event_impact_energy);
  visit(f.event_dissipated);
  visit(f.event_category);
  visit(f.event_with_wall);
}

void check_lengths(const FlowFrame& f) {
  const std::size_t n = f.position.size(), c = f.contact_a.size(), e = f.event_time.size();
  const bool ok = f.velocity.size() == n && f.angular_velocity.size() == n &&
                  f.radius.size() == n && f.material.size() == n && f.contact_b.size() == c &&
                  f.contact_with_wall.size() == c && f.contact_point.size() == c &&
                  f.contact_force.size() == c && f.contact_branch.size() == c &&
                  f.event_point.size() == e && f.event_impact_energy.size() == e &&
                  f.event_dissipated.size() == e && f.event_category.size() == e &&
                  f.event_with_wall.size() == e;
  if (!ok)
    throw CorruptData(
        fmt::format("flow sample: arrays of the frame at t = {} s differ in length", f.time));
}

}  // namespace

FlowFrame capture_frame(const System& system, double mill_angle,
                        std::span<const CollisionEvent> events) {
  FlowFrame frame;
  frame.time = system.time();
  frame.mill_angle = mill_angle;
  const auto groups = system.particle_groups();
  for (std::size_t p = 0; p < system.size(); ++p) {
    if (groups[p] != kFreeParticle) continue;
    frame.position.push_back(to_float3(system.positions()[p]));
    frame.velocity.push_back(to_float3(system.velocities()[p]));
    frame.angular_velocity.push_back(to_float3(system.angular_velocities()[p]));
    frame.radius.push_back(static_cast<float>(system.radii()[p]));
    frame.material.push_back(system.particle_materials()[p]);
  }
  for (const ActiveContact& c : system.active_contacts()) {
    frame.contact_a.push_back(c.a);
    frame.contact_b.push_back(c.b);
    frame.contact_with_wall.push_back(c.with_wall ? 1 : 0);
    frame.contact_point.push_back(to_float3(c.point));
    frame.contact_force.push_back(to_float3(c.force_on_a));
    frame.contact_branch.push_back(to_float3(c.branch));
  }
  for (const CollisionEvent& e : events) {
    frame.event_time.push_back(e.start_time + e.duration);
    frame.event_point.push_back(to_float3(e.point));
    frame.event_impact_energy.push_back(static_cast<float>(e.impact_energy));
    frame.event_dissipated.push_back(static_cast<float>(e.dissipated));
    frame.event_category.push_back(e.category);
    frame.event_with_wall.push_back(e.with_wall ? 1 : 0);
  }
  return frame;
}

void write_flow_segment(const std::filesystem::path& path, std::span<const FlowFrame> frames) {
  BinaryWriter out;
  out.put<std::uint64_t>(frames.size());
  for (const FlowFrame& frame : frames) {
    check_lengths(frame);
    out.put(frame.time);
    out.put(frame.mill_angle);
    visit_arrays(frame, [&](const auto& array) { put(out, array); });
  }
  write_checksummed_file(path, kMagic, kFlowSampleVersion, out.bytes());
}

std::vector<FlowFrame> read_flow_segment(const std::filesystem::path& path) {
  const std::string payload = read_checksummed_file(path, kMagic, kFlowSampleVersion);
  BinaryReader in(payload);
  std::vector<FlowFrame> frames(in.get<std::uint64_t>());
  for (FlowFrame& frame : frames) {
    frame.time = in.get<double>();
    frame.mill_angle = in.get<double>();
    visit_arrays(frame, [&](auto& array) { get(in, array); });
    check_lengths(frame);
  }
  if (!in.at_end())
    throw CorruptData(
        fmt::format("flow sample {}: trailing bytes after the last frame", path.string()));
  return frames;
}

}  // namespace millflow::dem
