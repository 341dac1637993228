#include "engine/interrupt.hpp"

#include <unistd.h>

#include <csignal>
#include <initializer_list>

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

}  // namespace millflow::engine
