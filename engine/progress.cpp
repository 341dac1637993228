#include "engine/progress.hpp"

#include <fmt/format.h>

namespace millflow::engine {
namespace {

std::string format_duration(double seconds) {
  const auto total = static_cast<long>(seconds + 0.5);
  if (total >= 3600) return fmt::format("{}h{:02}m", total / 3600, (total / 60) % 60);
  if (total >= 60) return fmt::format("{}m{:02}s", total / 60, total % 60);
  return fmt::format("{}s", total);
}

}  // namespace

std::string format_status_line(const ProgressSnapshot& snapshot) {
  std::string line = fmt::format("[{}]", format_duration(snapshot.elapsed_s));
  for (const auto& [kind, counts] : snapshot.done_total_by_kind) {
    line += fmt::format(" {} {}/{}", kind, counts.first, counts.second);
  }
  if (!snapshot.running.empty()) {
    line += " | running:";
    for (const auto& task : snapshot.running) {
      line +=
          fmt::format(" {}:{} {:.0f}%", task.kind, task.key.substr(0, 8), 100.0 * task.fraction);
    }
  }
  if (snapshot.finished_this_run > 0 && snapshot.remaining > 0) {
    const double eta = snapshot.elapsed_s / snapshot.finished_this_run * snapshot.remaining;
    line += " | ETA " + format_duration(eta);
  }
  return line;
}

void PlainProgress::task_event(const std::string& kind, const std::string& key,
                               const std::string& what) {
  fmt::print(out_, "{} {} {}\n", kind, key.substr(0, 12), what);
  std::fflush(out_);
}

void LiveProgress::task_event(const std::string& kind, const std::string& key,
                              const std::string& what) {
  fmt::print(out_, "\r\033[K{} {} {}\n{}", kind, key.substr(0, 12), what, line_);
  std::fflush(out_);
}

void LiveProgress::refresh(const ProgressSnapshot& snapshot) {
  line_ = format_status_line(snapshot);
  fmt::print(out_, "\r\033[K{}", line_);
  std::fflush(out_);
}

void LiveProgress::finish() {
  fmt::print(out_, "\r\033[K{}\n", line_);
  std::fflush(out_);
}

}  // namespace millflow::engine
