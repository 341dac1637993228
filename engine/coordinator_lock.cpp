#include "engine/coordinator_lock.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "engine/clock.hpp"
#include "engine/sqlite.hpp"
#include "engine/store.hpp"

namespace millflow::engine {

std::optional<std::string> describe_coordinator(const std::filesystem::path& db) {
  if (!std::filesystem::exists(db)) return std::nullopt;
  // Not open_read_only: a database whose first submit died before creating the schema is one to
  // submit to again, not an error.
  sql::Connection connection(db, sql::Access::read_only);
  if (connection.user_version() == 0) return std::nullopt;
  auto row =
      connection.prepare("SELECT pid, host, started_at, coalesce(campaign, '') FROM coordinator");
  if (!row.step()) return std::nullopt;
  return fmt::format("pid {} on {} since {} (campaign \"{}\")", row.integer(0), row.text(1),
                     iso8601_utc(row.real(2)), row.text(3));
}

CoordinatorLock::CoordinatorLock(const std::filesystem::path& db) {
  const auto file = lock_file(db);
  fd_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw std::runtime_error("cannot open lock file " + file.string() + ": " +
                             std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    fd_ = -1;
    const auto holder = describe_coordinator(db);
    throw CoordinatorBusy(
        "database " + db.string() + " is in use by another millflow coordinator: " +
        holder.value_or("(starting up)") + "; wait for it, or interrupt it with Ctrl-C");
  }
  stale_holder_ = describe_coordinator(db);
}

CoordinatorLock::~CoordinatorLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the descriptor releases the flock
}

}  // namespace millflow::engine
