#pragma once
// Ctrl-C handling for a coordinator: the first SIGINT/SIGTERM asks for a clean stop (no new
// tasks, running tasks stop at their next checkpoint and are recorded as interrupted); a second
// one exits at once with status 130 (the store stays consistent: every commit is atomic).
namespace millflow::engine {

void install_interrupt_handlers();
bool interrupt_requested();

}  // namespace millflow::engine
