#include "engine/launcher.hpp"

#include <thread>

namespace millflow::engine {

TbbLauncher::TbbLauncher(int jobs, int threads_per_task)
    // Enough workers for every task slot and every task's own threads, whatever the core count:
    // tasks may sleep or wait on I/O, and the cap is --jobs, not the machine.
    : workers_(
          std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                static_cast<size_t>(jobs * threads_per_task + 1))),
      arena_(jobs, 0) {}

TbbLauncher::~TbbLauncher() {
  wait_idle();
}

void TbbLauncher::launch(std::function<void()> attempt) {
  in_flight_.fetch_add(1);
  arena_.enqueue([this, attempt = std::move(attempt)] {
    attempt();
    in_flight_.fetch_sub(1);
  });
}

void TbbLauncher::wait_idle() {
  while (in_flight_.load() > 0) std::this_thread::yield();
}

}  // namespace millflow::engine
