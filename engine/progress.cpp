#include "engine/progress.hpp"

#include <fmt/format.h>
#include <spdlog/sinks/base_sink.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string_view>

namespace millflow::engine {
namespace {

// Status and log lines are best effort: a terminal that went away or a full disk under a
// redirected stderr must not stop a campaign (its log lines are in the database and the campaign
// log). fmt::print would throw on a failed write.
void print_best_effort(std::FILE* out, std::string_view text) {
  std::fwrite(text.data(), 1, text.size(), out);
  std::fflush(out);
}

std::string format_duration(double seconds) {
  const auto total = static_cast<long>(seconds + 0.5);
  if (total >= 3600) return fmt::format("{}h{:02}m", total / 3600, (total / 60) % 60);
  if (total >= 60) return fmt::format("{}m{:02}s", total / 60, total % 60);
  return fmt::format("{}s", total);
}

class ViewSink final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  explicit ViewSink(ProgressView& view) : view_(view) {}

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    spdlog::memory_buf_t formatted;
    formatter_->format(msg, formatted);
    std::string line = fmt::to_string(formatted);
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    view_.message(line);
  }
  void flush_() override {}

 private:
  ProgressView& view_;
};

}  // namespace

std::shared_ptr<spdlog::logger> progress_logger(ProgressView& view) {
  auto logger = std::make_shared<spdlog::logger>("progress", std::make_shared<ViewSink>(view));
  logger->set_pattern("[%l] %v");
  return logger;
}

std::optional<Eta> estimate_remaining(const ProgressSnapshot& snapshot) {
  Eta eta;
  bool known = false;
  int tasks_left = 0;
  if (snapshot.estimated_tasks_left > 0) {
    const double pace =
        (snapshot.finished_measured_s + kEstimatePriorS / std::max(1, snapshot.threads_per_task)) /
        (snapshot.finished_estimate_s + kEstimatePriorS);
    eta.seconds += std::max(0.0, snapshot.estimated_left_s) * pace;
    tasks_left += snapshot.estimated_tasks_left;
    known = true;
  }
  for (const auto& [kind, remaining] : snapshot.remaining_by_kind) {
    if (remaining == 0) continue;
    const auto timing = snapshot.task_seconds_by_kind.find(kind);
    if (timing == snapshot.task_seconds_by_kind.end() || timing->second.second == 0) {
      eta.lower_bound = true;
      continue;
    }
    const double mean = timing->second.first / timing->second.second;
    double left = remaining * mean;
    for (const auto& task : snapshot.running) {
      if (task.kind == kind) left -= std::clamp(task.fraction, 0.0, 1.0) * mean;
    }
    eta.seconds += std::max(0.0, left);
    tasks_left += remaining;
    known = true;
  }
  if (!known) return std::nullopt;
  eta.seconds /= std::max(1, std::min(snapshot.jobs, tasks_left));
  return eta;
}

std::string format_status_line(const ProgressSnapshot& snapshot, std::size_t width) {
  std::vector<std::string> parts;
  parts.push_back(fmt::format("[{}]", format_duration(snapshot.elapsed_s)));
  if (snapshot.remaining > 0) {
    const auto eta = estimate_remaining(snapshot);
    parts.push_back(
        eta ? fmt::format("ETA {}{}", eta->lower_bound ? ">" : "", format_duration(eta->seconds))
            : std::string("ETA ?"));
  }
  for (const auto& [kind, counts] : snapshot.done_total_by_kind) {
    const auto skipped = snapshot.skipped_by_kind.find(kind);
    parts.push_back(fmt::format("{} {}/{}{}", kind, counts.first, counts.second,
                                skipped == snapshot.skipped_by_kind.end()
                                    ? ""
                                    : fmt::format(" ({} skipped)", skipped->second)));
  }
  for (const auto& task : snapshot.running) {
    // Tenths below 10%: a cell of hours would otherwise sit at 0% for many minutes.
    const double percent = 100.0 * task.fraction;
    parts.push_back(fmt::format("{}:{} {:.{}f}%", task.kind, task.key.substr(0, 6), percent,
                                percent < 9.95 ? 1 : 0));
  }
  std::string line;
  for (const auto& part : parts) {
    const std::size_t needed = line.empty() ? part.size() : line.size() + 1 + part.size();
    if (needed > width) break;
    if (!line.empty()) line += ' ';
    line += part;
  }
  return line.empty() ? parts.front().substr(0, width) : line;
}

std::size_t terminal_width(std::FILE* out) {
  winsize size{};
  if (::ioctl(::fileno(out), TIOCGWINSZ, &size) == 0 && size.ws_col > 0) return size.ws_col;
  if (const char* columns = std::getenv("COLUMNS")) {
    const long value = std::strtol(columns, nullptr, 10);
    if (value > 0) return static_cast<std::size_t>(value);
  }
  return 80;
}

void PlainProgress::task_event(const std::string& kind, const std::string& key,
                               const std::string& what) {
  message(fmt::format("{} {} {}", kind, key.substr(0, 12), what));
}

void PlainProgress::refresh(const ProgressSnapshot& snapshot) {
  const std::lock_guard lock(mutex_);
  line_ = format_status_line(snapshot);
  if (snapshot.elapsed_s < next_status_s_) return;
  next_status_s_ = snapshot.elapsed_s + status_every_s_;
  print_best_effort(out_, line_ + '\n');
}

void PlainProgress::message(const std::string& line) {
  const std::lock_guard lock(mutex_);
  print_best_effort(out_, line + '\n');
}

void PlainProgress::finish() {
  const std::lock_guard lock(mutex_);
  if (!line_.empty()) print_best_effort(out_, line_ + '\n');
}

void LiveProgress::task_event(const std::string& kind, const std::string& key,
                              const std::string& what) {
  message(fmt::format("{} {} {}", kind, key.substr(0, 12), what));
}

void LiveProgress::message(const std::string& line) {
  const std::lock_guard lock(mutex_);
  print_best_effort(out_, fmt::format("\r\033[K{}\n{}", line, line_));
}

void LiveProgress::refresh(const ProgressSnapshot& snapshot) {
  const std::lock_guard lock(mutex_);
  // One column short of the width: a line that fills the last column wraps on some terminals.
  line_ = format_status_line(snapshot, std::max<std::size_t>(terminal_width(out_), 2) - 1);
  print_best_effort(out_, "\r\033[K" + line_);
}

void LiveProgress::finish() {
  const std::lock_guard lock(mutex_);
  print_best_effort(out_, "\r\033[K" + line_ + '\n');
}

}  // namespace millflow::engine
