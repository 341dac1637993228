#include "util/durable_file.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

namespace millflow::util {
namespace fs = std::filesystem;
namespace {

constexpr std::int64_t kNoSimulatedLimit = -1;
std::atomic<std::int64_t> g_simulated_bytes_left{kNoSimulatedLimit};

[[noreturn]] void throw_system_error(int error, const std::string& what, const fs::path& path) {
  throw std::system_error(error, std::generic_category(),
                          fmt::format("{} '{}'", what, path.string()));
}

fs::path directory_of(const fs::path& file) {
  return file.parent_path().empty() ? fs::path(".") : file.parent_path();
}

// How many of `wanted` bytes the simulated full disk still takes (all without one).
std::size_t simulated_room(std::size_t wanted) {
  std::int64_t left = g_simulated_bytes_left.load();
  while (left != kNoSimulatedLimit) {
    const auto taken = std::min<std::int64_t>(left, static_cast<std::int64_t>(wanted));
    if (g_simulated_bytes_left.compare_exchange_weak(left, left - taken))
      return static_cast<std::size_t>(taken);
  }
  return wanted;
}

// The permissions a plain open() would give a new file (0666 less the umask): mkstemp makes 0600,
// and results are often shared with a group. The umask is read from /proc: umask() itself would
// change it for every thread while it is read.
mode_t new_file_mode() {
  static const mode_t mode = [] {
    mode_t mask = 022;
    std::ifstream status("/proc/self/status");
    for (std::string line; std::getline(status, line);) {
      if (line.starts_with("Umask:"))
        mask = static_cast<mode_t>(std::stoul(line.substr(6), nullptr, 8));
    }
    return static_cast<mode_t>(0666 & ~mask);
  }();
  return mode;
}

void sync_directory(const fs::path& directory) {
  const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw_system_error(errno, "cannot open directory", directory);
  const int result = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (result != 0) throw_system_error(error, "cannot sync directory", directory);
}

}  // namespace

DurableFile::DurableFile(fs::path target) : target_(std::move(target)) {
  std::string name =
      (directory_of(target_) / fmt::format(".{}.tmp.XXXXXX", target_.filename().string())).string();
  fd_ = ::mkstemp(name.data());
  if (fd_ < 0) throw_system_error(errno, "cannot create a temporary file beside", target_);
  temporary_ = name;
  if (::fchmod(fd_, new_file_mode()) != 0)
    throw_system_error(errno, "cannot set the permissions of a temporary file beside", target_);
}

DurableFile::~DurableFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!temporary_.empty()) ::unlink(temporary_.c_str());
}

void DurableFile::append(std::string_view bytes) {
  while (!bytes.empty()) {
    const std::size_t room = simulated_room(bytes.size());
    if (room == 0) throw_system_error(ENOSPC, "cannot write", target_);
    const ssize_t written = ::write(fd_, bytes.data(), room);
    if (written < 0) {
      if (errno == EINTR) continue;
      throw_system_error(errno, "cannot write", target_);
    }
    bytes.remove_prefix(static_cast<std::size_t>(written));
  }
}

void DurableFile::commit() {
  if (::fsync(fd_) != 0) throw_system_error(errno, "cannot sync", target_);
  const int closed = ::close(fd_);
  fd_ = -1;
  if (closed != 0) throw_system_error(errno, "cannot close", target_);
  if (::rename(temporary_.c_str(), target_.c_str()) != 0)
    throw_system_error(errno, "cannot rename a temporary file over", target_);
  temporary_.clear();
  sync_directory(directory_of(target_));
}

void write_file_durably(const fs::path& target, std::string_view bytes) {
  DurableFile file(target);
  file.append(bytes);
  file.commit();
}

void copy_file_durably(const fs::path& from, const fs::path& to) {
  const int source = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
  if (source < 0) throw_system_error(errno, "cannot read", from);
  try {
    DurableFile file(to);
    std::array<char, 1 << 16> buffer{};
    while (true) {
      const ssize_t read = ::read(source, buffer.data(), buffer.size());
      if (read < 0 && errno == EINTR) continue;
      if (read < 0) throw_system_error(errno, "cannot read", from);
      if (read == 0) break;
      file.append(std::string_view(buffer.data(), static_cast<std::size_t>(read)));
    }
    file.commit();
  } catch (...) {
    ::close(source);
    throw;
  }
  ::close(source);
}

namespace {

// Moves every entry of `from` into `to`, replacing an entry of the same name (a directory found
// in both is merged the same way), then makes the renames durable.
void move_entries_replacing(const fs::path& from, const fs::path& to) {
  // Listed first: a directory's listing while its entries move out is unspecified (POSIX).
  const std::vector<fs::directory_entry> listed{fs::directory_iterator(from),
                                                fs::directory_iterator()};
  for (const fs::directory_entry& entry : listed) {
    const fs::path destination = to / entry.path().filename();
    const bool both_directories = entry.is_directory() && fs::is_directory(destination);
    if (both_directories) {
      move_entries_replacing(entry.path(), destination);
      fs::remove(entry.path());  // emptied
      continue;
    }
    // A file cannot replace a directory by a rename, nor a directory a file.
    if (fs::exists(fs::symlink_status(destination)) &&
        entry.is_directory() != fs::is_directory(destination))
      fs::remove_all(destination);
    fs::rename(entry.path(), destination);
  }
  sync_directory(to);
}

}  // namespace

void fill_directory_durably(const fs::path& given,
                            const std::function<void(const fs::path&)>& fill) {
  const bool existing = fs::is_directory(given);
  fs::path target = given.lexically_normal();
  if (!target.has_filename()) target = target.parent_path();  // "out/"
  // An existing directory is staged inside it (its parent may not be writable), a new one beside
  // where it goes.
  const fs::path staging =
      existing ? target / kStagingDirectoryName
               : directory_of(target) / fmt::format(".{}.partial", target.filename().string());
  fs::remove_all(staging);
  fs::create_directories(staging);
  try {
    fill(staging);
    if (existing) {
      move_entries_replacing(staging, target);
      fs::remove(staging);
    } else {
      fs::rename(staging, target);
      sync_directory(directory_of(target));
    }
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(staging, ignored);
    throw;
  }
}

SimulatedFullDisk::SimulatedFullDisk(std::int64_t bytes_left) {
  g_simulated_bytes_left.store(bytes_left);
}

SimulatedFullDisk::~SimulatedFullDisk() {
  g_simulated_bytes_left.store(kNoSimulatedLimit);
}

}  // namespace millflow::util
