#include "engine/interrupt.hpp"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <ctime>
#include <initializer_list>
#include <utility>

namespace millflow::engine {
namespace {

volatile std::sig_atomic_t g_interrupts = 0;

// Signals within kSameRequestNs of the first are that request again: timeout(1) signals the
// command and then its process group, a kill of the group reaches the process as well, so one
// request can arrive as two signals microseconds apart. A later one exits at once.
constexpr std::int64_t kSameRequestNs = 500'000'000;
std::atomic<std::int64_t> g_first_interrupt_ns{0};
static_assert(std::atomic<std::int64_t>::is_always_lock_free, "used in a signal handler");

// clock_gettime is async-signal-safe.
std::int64_t monotonic_ns() {
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

extern "C" void on_interrupt(int) {
  const std::int64_t now = monotonic_ns();
  std::int64_t first = 0;
  if (!g_first_interrupt_ns.compare_exchange_strong(first, now)) {
    if (now - first >= kSameRequestNs) ::_exit(130);
    return;
  }
  g_interrupts = 1;
  static constexpr char kMessage[] =
      "\nmillflow: stopping after running tasks reach a checkpoint (Ctrl-C again aborts)\n";
  [[maybe_unused]] const auto written = ::write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
}

extern "C" void on_checkpoint_request(int) {
  g_interrupts = g_interrupts + 1;
}

}  // namespace

void install_checkpoint_handlers() {
  struct sigaction action {};
  action.sa_handler = on_checkpoint_request;
  sigemptyset(&action.sa_mask);
  for (const int signal : {SIGUSR1, SIGUSR2, SIGTERM, SIGINT}) sigaction(signal, &action, nullptr);
}

void install_interrupt_handlers() {
  struct sigaction action {};
  action.sa_handler = on_interrupt;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  // A closed terminal or a dropped ssh session: stop cleanly rather than die mid-task (the
  // status line's writes to the gone terminal fail quietly, engine/progress.hpp).
  sigaction(SIGHUP, &action, nullptr);
}

bool interrupt_requested() {
  return g_interrupts > 0;
}

StopWatcher::StopWatcher(std::function<bool()> stop_requested)
    : stop_requested_(std::move(stop_requested)), thread_([this](std::stop_token done) {
        while (!done.stop_requested()) {
          if (stop_requested_()) {
            source_.request_stop();
            return;
          }
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
      }) {}

}  // namespace millflow::engine
