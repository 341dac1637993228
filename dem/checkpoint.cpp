#include "dem/checkpoint.hpp"

#include <fmt/format.h>

#include "dem/binary_io.hpp"

namespace millflow::dem {
namespace {

constexpr std::string_view kMagic = "MFDEMCKP";

void put(BinaryWriter& out, const Vec3& v) {
  out.put(v.x());
  out.put(v.y());
  out.put(v.z());
}

Vec3 get_vec3(BinaryReader& in) {
  const double x = in.get<double>(), y = in.get<double>(), z = in.get<double>();
  return Vec3(x, y, z);
}

void put(BinaryWriter& out, const WallLoad& load) {
  put(out, load.force);
  put(out, load.torque);
  out.put(load.power);
  out.put(load.work);
}

WallLoad get_load(BinaryReader& in) {
  WallLoad load;
  load.force = get_vec3(in);
  load.torque = get_vec3(in);
  load.power = in.get<double>();
  load.work = in.get<double>();
  return load;
}

void put(BinaryWriter& out, const ContactHistory& h) {
  put(out, h.spring);
  out.put(h.start_time);
  out.put(h.impact_speed);
  out.put(h.impact_energy);
  out.put(h.elastic_energy);
  out.put(h.dissipated.normal);
  out.put(h.dissipated.tangential);
  out.put(h.dissipated.friction);
  put(out, h.point);
  out.put<std::uint8_t>(1);  // touching: every history written is of a contact in force
}

ContactHistory get_history(BinaryReader& in) {
  ContactHistory h;
  h.spring = get_vec3(in);
  h.start_time = in.get<double>();
  h.impact_speed = in.get<double>();
  h.impact_energy = in.get<double>();
  h.elastic_energy = in.get<double>();
  h.dissipated.normal = in.get<double>();
  h.dissipated.tangential = in.get<double>();
  h.dissipated.friction = in.get<double>();
  h.point = get_vec3(in);
  if (in.get<std::uint8_t>() != 1) throw CorruptData("checkpoint: a contact history not in force");
  return h;
}

void put_vec3s(BinaryWriter& out, const std::vector<Vec3>& values) {
  for (const Vec3& v : values) put(out, v);
}

void get_vec3s(BinaryReader& in, std::vector<Vec3>& values, std::size_t count) {
  values.resize(count);
  for (Vec3& v : values) v = get_vec3(in);
}

template <class T>
void put_array(BinaryWriter& out, const std::vector<T>& values) {
  out.put_span(std::span<const T>(values));
}

template <class T>
void get_array(BinaryReader& in, std::vector<T>& values, std::size_t count) {
  values = in.get_vector<T>();
  if (values.size() != count) {
    throw CorruptData(fmt::format(
        "checkpoint: array of {} elements where {} particles were declared", values.size(), count));
  }
}

MaterialTable get_materials(BinaryReader& in) {
  MaterialTable table;
  const auto count = in.get<std::uint64_t>();
  for (std::uint64_t m = 0; m < count; ++m) {
    Material material;
    material.name = in.get_string();
    material.density = in.get<double>();
    table.add(material);
  }
  for (MaterialId a = 0; a < count; ++a) {
    for (MaterialId b = a; b < count; ++b) {
      if (in.get<std::uint8_t>() == 0) continue;
      InteractionSpec s;
      s.restitution = in.get<double>();
      s.friction = in.get<double>();
      s.normal_stiffness = in.get<double>();
      s.tangential_stiffness_ratio = in.get<double>();
      s.tangential_damping_ratio = in.get<double>();
      table.set_interaction(a, b, s);
    }
  }
  return table;
}

void put_domain(BinaryWriter& out, const Domain& d) {
  put(out, d.lo);
  put(out, d.hi);
  for (bool p : d.periodic) out.put<std::uint8_t>(p);
  out.put<std::uint8_t>(d.lees_edwards.enabled);
  out.put<std::int32_t>(d.lees_edwards.flow_axis);
  out.put<std::int32_t>(d.lees_edwards.gradient_axis);
  out.put(d.lees_edwards.offset);
  out.put(d.lees_edwards.velocity);
}

Domain get_domain(BinaryReader& in) {
  Domain d;
  d.lo = get_vec3(in);
  d.hi = get_vec3(in);
  for (bool& p : d.periodic) p = in.get<std::uint8_t>() != 0;
  d.lees_edwards.enabled = in.get<std::uint8_t>() != 0;
  d.lees_edwards.flow_axis = in.get<std::int32_t>();
  d.lees_edwards.gradient_axis = in.get<std::int32_t>();
  d.lees_edwards.offset = in.get<double>();
  d.lees_edwards.velocity = in.get<double>();
  return d;
}

void put_wall(BinaryWriter& out, const Wall& wall) {
  out.put_string(wall.name);
  out.put<std::uint32_t>(wall.material);
  if (const auto* plane = std::get_if<PlaneWall>(&wall.shape)) {
    out.put<std::uint8_t>(0);
    put(out, plane->origin);
    put(out, plane->normal);
    put(out, plane->velocity);
    out.put(plane->servo_target_force);
    out.put(plane->servo_mobility);
    out.put(plane->servo_max_speed);
  } else {
    const auto& mill = std::get<MillWall>(wall.shape);
    out.put<std::uint8_t>(1);
    out.put(mill.shell.radius);
    out.put(mill.shell.length);
    out.put<std::int32_t>(mill.shell.lifter_count);
    out.put(mill.shell.lifter.height);
    out.put(mill.shell.lifter.base_width);
    out.put(mill.shell.lifter.face_angle_deg);
    out.put<std::uint8_t>(mill.shell.end_walls);
    out.put(mill.angular_velocity);
    out.put(mill.angle);
  }
}

Wall get_wall(BinaryReader& in) {
  Wall wall;
  wall.name = in.get_string();
  wall.material = in.get<std::uint32_t>();
  const auto tag = in.get<std::uint8_t>();
  if (tag == 0) {
    PlaneWall plane;
    plane.origin = get_vec3(in);
    plane.normal = get_vec3(in);
    plane.velocity = get_vec3(in);
    plane.servo_target_force = in.get<double>();
    plane.servo_mobility = in.get<double>();
    plane.servo_max_speed = in.get<double>();
    wall.shape = plane;
  } else if (tag == 1) {
    MillWall mill;
    mill.shell.radius = in.get<double>();
    mill.shell.length = in.get<double>();
    mill.shell.lifter_count = in.get<std::int32_t>();
    mill.shell.lifter.height = in.get<double>();
    mill.shell.lifter.base_width = in.get<double>();
    mill.shell.lifter.face_angle_deg = in.get<double>();
    mill.shell.end_walls = in.get<std::uint8_t>() != 0;
    mill.angular_velocity = in.get<double>();
    mill.angle = in.get<double>();
    wall.shape = mill;
  } else {
    throw CorruptData(fmt::format("checkpoint: unknown wall shape tag {}", tag));
  }
  return wall;
}

void put_materials(BinaryWriter& out, const MaterialTable& table) {
  out.put<std::uint64_t>(table.size());
  for (MaterialId m = 0; m < table.size(); ++m) put_material(out, table.material(m));
  for (MaterialId a = 0; a < table.size(); ++a) {
    for (MaterialId b = a; b < table.size(); ++b) {
      const bool defined = table.has_interaction(a, b);
      out.put<std::uint8_t>(defined);
      if (defined) put_interaction(out, table.interaction(a, b));
    }
  }
}

}  // namespace

void put_material(BinaryWriter& out, const Material& material) {
  out.put_string(material.name);
  out.put(material.density);
}

void put_interaction(BinaryWriter& out, const InteractionSpec& spec) {
  out.put(spec.restitution);
  out.put(spec.friction);
  out.put(spec.normal_stiffness);
  out.put(spec.tangential_stiffness_ratio);
  out.put(spec.tangential_damping_ratio);
}

// Reads and writes System's private state for the checkpoint functions.
class CheckpointAccess {
 public:
  static std::string serialise(const System& s) { return serialise(s, s.materials_); }
  static std::string serialise(const System& s, const MaterialTable& materials) {
    BinaryWriter out;
    put_materials(out, materials);
    put_domain(out, s.domain_);
    put(out, s.gravity_);
    out.put(s.dt_);
    out.put(s.time_);
    out.put<std::uint64_t>(s.step_count_);
    out.put(s.skin_);
    out.put<std::uint8_t>(s.record_collisions_);
    out.put<std::uint8_t>(s.prepared_);
    for (std::uint64_t word : s.rng_.state()) out.put(word);

    out.put<std::uint64_t>(s.size());
    for (const auto* array :
         {&s.position_, &s.velocity_, &s.angular_velocity_, &s.force_, &s.torque_}) {
      put_vec3s(out, *array);
    }
    for (const auto* array : {&s.radius_, &s.mass_, &s.inv_mass_, &s.inv_inertia_})
      put_array(out, *array);
    put_array(out, s.material_);
    put_array(out, s.group_);

    out.put<std::uint64_t>(s.groups_.size());
    for (std::size_t g = 0; g < s.groups_.size(); ++g) {
      const KinematicGroup& group = s.groups_[g];
      out.put_string(group.name);
      put(out, group.velocity);
      put(out, s.group_loads_[g]);
    }
    out.put<std::uint64_t>(s.walls_.size());
    for (std::size_t w = 0; w < s.walls_.size(); ++w) {
      put_wall(out, s.walls_[w]);
      put(out, s.wall_loads_[w]);
    }

    const auto& pairs = s.neighbors_.pairs();
    std::uint64_t touching = 0;
    for (std::size_t k = 0; k < pairs.size(); ++k) touching += s.pair_touching(k) ? 1 : 0;
    out.put(touching);
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      if (!s.pair_touching(k)) continue;
      out.put(pairs[k].i);
      out.put(pairs[k].j);
      put(out, s.pair_history(k));
      put(out, s.pair_force(k));
    }
    for (std::size_t p = 0; p < s.size(); ++p) {
      const System::WallSlots& current = s.current_wall_slots();
      const int count = s.wall_contact_count(p);
      out.put(static_cast<std::uint8_t>(count));
      for (int c = 0; c < count; ++c) {
        const WallContactHistory& slot = current.of(p)[c];
        out.put(slot.wall);
        out.put(slot.feature);
        put(out, slot.history);
        put(out, slot.force_on_particle);
        put(out, slot.history.point);  // the contact point, again
      }
    }
    out.put<std::uint64_t>(s.finished_dissipation_.size());
    for (const Dissipation& d : s.finished_dissipation_) {
      out.put(d.normal);
      out.put(d.tangential);
      out.put(d.friction);
    }
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) out.put(s.contact_virial_(row, col));
    }
    out.put(s.reorder_every_);
    return out.bytes();
  }

  static System deserialise(std::string_view bytes, std::uint32_t version) {
    BinaryReader in(bytes);
    MaterialTable materials = get_materials(in);
    const Domain domain = get_domain(in);
    const Vec3 gravity = get_vec3(in);
    System s(std::move(materials), domain, gravity);
    s.dt_ = in.get<double>();
    s.time_ = in.get<double>();
    s.step_count_ = in.get<std::uint64_t>();
    s.skin_ = in.get<double>();
    s.record_collisions_ = in.get<std::uint8_t>() != 0;
    const bool prepared = in.get<std::uint8_t>() != 0;
    std::array<std::uint64_t, 4> rng_state;
    for (auto& word : rng_state) word = in.get<std::uint64_t>();
    s.rng_.set_state(rng_state);

    const auto n = in.get<std::uint64_t>();
    for (auto* array : {&s.position_, &s.velocity_, &s.angular_velocity_, &s.force_, &s.torque_})
      get_vec3s(in, *array, n);
    for (auto* array : {&s.radius_, &s.mass_, &s.inv_mass_, &s.inv_inertia_})
      get_array(in, *array, n);
    get_array(in, s.material_, n);
    get_array(in, s.group_, n);
    s.predicted_velocity_ = s.velocity_;
    s.predicted_angular_velocity_ = s.angular_velocity_;

    const auto group_count = in.get<std::uint64_t>();
    for (std::uint64_t g = 0; g < group_count; ++g) {
      KinematicGroup group;
      group.name = in.get_string();
      group.velocity = get_vec3(in);
      if (version < 4) {  // the groups' servo, gone: axis, target, mobility, max speed
        in.get<std::int32_t>();
        for (int field = 0; field < 3; ++field) in.get<double>();
      }
      s.groups_.push_back(group);
      s.group_loads_.push_back(get_load(in));
    }
    const auto wall_count = in.get<std::uint64_t>();
    for (std::uint64_t w = 0; w < wall_count; ++w) {
      s.walls_.push_back(get_wall(in));
      s.wall_loads_.push_back(get_load(in));
    }

    const auto touching = in.get<std::uint64_t>();
    std::vector<NeighborPair> pairs;
    std::vector<ContactHistory> histories;
    std::vector<Vec3> forces;
    for (std::uint64_t k = 0; k < touching; ++k) {
      const auto i = in.get<std::uint32_t>();
      const auto j = in.get<std::uint32_t>();
      if (i >= n || j >= n) throw CorruptData("checkpoint: a touching pair names no particle");
      pairs.push_back({i, j});
      histories.push_back(get_history(in));
      histories.back().normal_damping = s.pair_normal_damping(i, j);
      forces.push_back(version >= 2 ? get_vec3(in) : Vec3::Zero());
    }
    if (!s.walls_.empty()) {
      for (System::WallSlots& buffer : s.wall_slots_) buffer.resize(n);
      s.finished_wall_mask_.assign(n, 0);
    }
    s.wall_current_ = 0;
    System::WallSlots& current = s.wall_slots_[0];
    for (std::size_t p = 0; p < n; ++p) {
      const auto count = in.get<std::uint8_t>();
      if (count > (s.walls_.empty() ? 0 : kMaxWallContactsPerParticle))
        throw CorruptData("checkpoint: too many wall contacts");
      if (count == 0) continue;
      current.count[p] = count;
      for (int c = 0; c < count; ++c) {
        WallContactHistory& slot = current.of(p)[c];
        slot.wall = in.get<std::int32_t>();
        slot.feature = in.get<std::int32_t>();
        slot.history = get_history(in);
        slot.force_on_particle = get_vec3(in);
        get_vec3(in);  // the history's contact point, again
      }
    }
    s.finished_dissipation_.resize(in.get<std::uint64_t>());
    for (Dissipation& d : s.finished_dissipation_) {
      d.normal = in.get<double>();
      d.tangential = in.get<double>();
      d.friction = in.get<double>();
    }
    if (version >= 3) {
      for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col) s.contact_virial_(row, col) = in.get<double>();
      }
      s.reorder_every_ = in.get<std::uint64_t>();
    }
    if (!in.at_end()) throw CorruptData("checkpoint: trailing bytes after the last section");

    // Forces, loads and histories are restored; only the neighbour list is rebuilt, which does
    // not change results (forces are summed over touching contacts in (i, j) order). The pair
    // forces go back to their pairs in the new list, so what reads the contacts in force before
    // the next step (stress virials, flow frames) sees what the uninterrupted run saw.
    s.neighbors_ = NeighborSearch(NeighborSearchOptions{.skin = s.skin_});
    s.rebuild_neighbors(pairs, std::move(histories));
    try {
      s.restore_pair_forces(pairs, forces);
    } catch (const std::logic_error&) {
      throw CorruptData("checkpoint: a touching pair is out of reach of its particles");
    }
    // Older files lack the virial: sum it again (in another order than the force pass did).
    if (version < 3) {
      for (std::size_t c = 0; c < pairs.size(); ++c) {
        s.contact_virial_.noalias() +=
            forces[c] *
            domain.separation(s.position_[pairs[c].i], s.position_[pairs[c].j]).transpose();
      }
    }
    s.prepared_ = prepared;
    return s;
  }
};

std::string checkpoint_payload(const System& system) {
  return CheckpointAccess::serialise(system);
}

System system_with_materials(const System& system, const MaterialTable& materials) {
  if (materials.size() != system.materials().size())
    throw std::invalid_argument("system_with_materials: another number of materials");
  for (MaterialId m = 0; m < materials.size(); ++m) {
    if (materials.material(m).name != system.materials().material(m).name)
      throw std::invalid_argument("system_with_materials: materials of other names");
  }
  return system_from_checkpoint_payload(CheckpointAccess::serialise(system, materials),
                                        kCheckpointVersion);
}

System system_from_checkpoint_payload(std::string_view payload, std::uint32_t version) {
  if (version < 1 || version > kCheckpointVersion) {
    throw CorruptData(fmt::format("checkpoint: system payload version {}, this build reads 1 to {}",
                                  version, kCheckpointVersion));
  }
  return CheckpointAccess::deserialise(payload, version);
}

void save_checkpoint(const System& system, const std::filesystem::path& path) {
  write_checksummed_file(path, kMagic, kCheckpointVersion, checkpoint_payload(system));
}

System load_checkpoint(const std::filesystem::path& path) {
  std::uint32_t version = 0;
  const std::string payload = read_checksummed_file(path, kMagic, kCheckpointVersion, &version);
  return system_from_checkpoint_payload(payload, version);
}

}  // namespace millflow::dem
