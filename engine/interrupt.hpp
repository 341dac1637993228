#pragma once
// Ctrl-C handling for a coordinator: the first SIGINT/SIGTERM/SIGHUP asks for a clean stop (no new
// tasks, running tasks stop at their next checkpoint and are recorded as interrupted); a second
// one, half a second or more after the first, exits at once with status 130 (the store stays
// consistent: every commit is atomic). Signals closer to the first are the same request
// delivered twice (timeout(1), a kill of the process group).
#include <functional>
#include <stop_token>
#include <thread>

namespace millflow::engine {

void install_interrupt_handlers();
// For one attempt run as a batch job (`millflow exec`): SIGUSR1, SIGUSR2, SIGTERM and SIGINT only
// ask it to checkpoint and stop (the scheduler's --signal before the time limit, scancel, Ctrl-C);
// the process never exits from a handler, so it can write its marker.
void install_checkpoint_handlers();
bool interrupt_requested();

// Asks a task to stop (through token()) once stop_requested() turns true: signal handlers only
// set a flag, which this object's thread polls every 20 ms until it is destroyed.
class StopWatcher {
 public:
  explicit StopWatcher(std::function<bool()> stop_requested);
  std::stop_token token() const { return source_.get_token(); }

 private:
  std::function<bool()> stop_requested_;
  std::stop_source source_;
  std::jthread thread_;  // last: it reads the members above
};

}  // namespace millflow::engine
