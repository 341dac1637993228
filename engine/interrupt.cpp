#include "engine/interrupt.hpp"

#include <unistd.h>

#include <chrono>
#include <csignal>
#include <initializer_list>
#include <utility>

namespace millflow::engine {
namespace {

volatile std::sig_atomic_t g_interrupts = 0;

extern "C" void on_interrupt(int) {
  g_interrupts = g_interrupts + 1;
  if (g_interrupts >= 2) ::_exit(130);
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
