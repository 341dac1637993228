#include "engine/coordinator_lock.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "engine/clock.hpp"
#include "engine/database_path.hpp"
#include "engine/sqlite.hpp"
#include "engine/store.hpp"
#include "engine/validation.hpp"

namespace millflow::engine {

namespace {

struct CoordinatorRow {
  std::int64_t pid = 0;
  std::string description;
};

std::optional<CoordinatorRow> coordinator_row(const std::filesystem::path& db) {
  if (!std::filesystem::exists(db)) return std::nullopt;
  // Not open_read_only: a database whose first submit died before creating the schema is one to
  // submit to again, not an error.
  sql::Connection connection(db, sql::Access::read_only);
  const auto coordinator = find_coordinator(connection);
  if (!coordinator) return std::nullopt;
  return CoordinatorRow{
      coordinator->pid,
      fmt::format("pid {} on {} since {} (campaign \"{}\")", coordinator->pid, coordinator->host,
                  iso8601_utc(coordinator->started_at), coordinator->campaign)};
}

// Whether some process holds the flock of the database's lock file. Creates nothing.
bool lock_is_held(const std::filesystem::path& db) {
  const int fd = ::open(lock_file(db).c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool held = ::flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);  // drops the shared lock at once if it was granted
  return held;
}

}  // namespace

std::optional<std::string> describe_coordinator(const std::filesystem::path& db) {
  const auto row = coordinator_row(db);
  if (!row) return std::nullopt;
  return row->description;
}

std::optional<CoordinatorState> coordinator_state(const std::filesystem::path& db) {
  const auto row = coordinator_row(db);
  if (!row) return std::nullopt;
  if (lock_is_held(db)) return CoordinatorState{true, row->description};
  return CoordinatorState{false,
                          fmt::format("not running (last coordinator pid {} died)", row->pid)};
}

CoordinatorLock::CoordinatorLock(const std::filesystem::path& db) {
  const auto real = resolve_database(db, DatabaseUse::create);
  // A file SQLite cannot read is refused before a lock file is created beside it.
  check_database_readable(real);
  const auto file = lock_file(real);
  fd_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    throw InvalidInput(
        {{"--db",
          fmt::format("cannot create the lock file {}: {}", file.string(), std::strerror(errno)),
          "put the database in a directory you can write (its lock file, logs and "
          "artifacts go beside it)"}});
  }
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
