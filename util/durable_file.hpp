#pragma once
// The project's one way to write a file: a temporary file beside the target is written and
// fsync'ed, renamed over the target, and the directory is fsync'ed. A crash leaves either the old
// file or the whole new one, never a part; a reader never sees half a file.
//
// Errors are exceptions (std::system_error naming the file and the system's reason, e.g. "No
// space left on device") raised by the call that failed, never from a destructor: a failed write
// fails the caller's work, it does not terminate the process.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string_view>

namespace millflow::util {

// A new file being written under a temporary name until commit() puts it in place.
class DurableFile {
 public:
  // Creates the temporary file in the target's directory (which must exist).
  explicit DurableFile(std::filesystem::path target);
  // Removes the temporary file when commit() did not run (an error is being unwound); never throws.
  ~DurableFile();
  DurableFile(const DurableFile&) = delete;
  DurableFile& operator=(const DurableFile&) = delete;

  void append(std::string_view bytes);
  // fsync, close, rename over the target, fsync of the directory.
  void commit();

 private:
  std::filesystem::path target_;
  std::filesystem::path temporary_;
  int fd_ = -1;
};

void write_file_durably(const std::filesystem::path& target, std::string_view bytes);

// Copies `from` to `to` durably, streaming (artifacts may be large).
void copy_file_durably(const std::filesystem::path& from, const std::filesystem::path& to);

// Fills a directory: one that does not exist yet is filled under a temporary name beside it
// (".<name>.partial", cleared first: what a killed fill left) and renamed into place, so a crash
// leaves the whole directory or none. An existing one (it may hold files of its own, which are
// kept) is filled in kStagingDirectoryName inside it, whose entries then replace those of the
// same names by renames: a crash while `fill` runs leaves it as it was, one during the renames
// (milliseconds) some entries new and some old, each whole. `fill` writes into the directory it
// is given. When `fill` throws, nothing of it remains.
inline constexpr const char* kStagingDirectoryName = ".millflow.partial";
void fill_directory_durably(const std::filesystem::path& target,
                            const std::function<void(const std::filesystem::path&)>& fill);

// For tests: while one is alive, the writes of every DurableFile in the process fail with ENOSPC
// once `bytes_left` more bytes have been written, as on a full disk.
class SimulatedFullDisk {
 public:
  explicit SimulatedFullDisk(std::int64_t bytes_left = 0);
  ~SimulatedFullDisk();
  SimulatedFullDisk(const SimulatedFullDisk&) = delete;
  SimulatedFullDisk& operator=(const SimulatedFullDisk&) = delete;
};

}  // namespace millflow::util
