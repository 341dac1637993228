// The System's finished contacts (collision events): buffered for take_collision_events, or handed
// to the owner's sink as they finish.
#include <utility>

#include "dem/system.hpp"

namespace millflow::dem {

void System::record_collision(const CollisionEvent& event) {
  if (collision_sink_)
    collision_sink_->add(event);
  else
    events_.push_back(event);
}

std::vector<CollisionEvent> System::take_collision_events() {
  return std::exchange(events_, {});
}

void System::set_collision_sink(CollisionSink* sink) {
  collision_sink_ = sink;
  if (!sink) return;
  for (const CollisionEvent& event : take_collision_events()) sink->add(event);
}

}  // namespace millflow::dem
