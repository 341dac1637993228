#pragma once
// One coordinator per database: an flock on <db>.lock held for the coordinator's lifetime, plus a
// row in the `coordinator` table naming it (pid, host, start time). The kernel drops the flock
// when its process dies, so a row whose lock file is free is stale and is taken over.
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

namespace millflow::engine {

class CoordinatorBusy : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CoordinatorLock {
 public:
  // Throws CoordinatorBusy naming the running coordinator when another process holds it. The
  // lock file is named from the database's real path (resolve_database).
  explicit CoordinatorLock(const std::filesystem::path& db);
  ~CoordinatorLock();
  CoordinatorLock(const CoordinatorLock&) = delete;
  CoordinatorLock& operator=(const CoordinatorLock&) = delete;

  // The coordinator row left by a process that died holding the database, if there was one.
  const std::optional<std::string>& stale_holder() const { return stale_holder_; }

 private:
  int fd_ = -1;
  std::optional<std::string> stale_holder_;
};

// "pid 123 on host since 2024-..." for the coordinator row of a database, if any.
std::optional<std::string> describe_coordinator(const std::filesystem::path& db);

// The coordinator row of a database checked against its lock: a row whose process no longer holds
// the lock was left by a coordinator that died (kill -9, a crash) and is taken over by the next.
struct CoordinatorState {
  bool alive = false;
  // alive: "pid 123 on host since ... (campaign "c")"; dead: "not running (last coordinator pid
  // 123 died)".
  std::string description;
};
std::optional<CoordinatorState> coordinator_state(const std::filesystem::path& db);

}  // namespace millflow::engine
