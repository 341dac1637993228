#pragma once
// The filesystem edge of the artifact store as an interface, so tests can put a disk that fails
// in its place. LocalFileSystem is the real disk.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace millflow::engine {

class FileSystem {
 public:
  virtual ~FileSystem() = default;
  // Size in bytes, or nullopt when there is no such regular file.
  virtual std::optional<std::int64_t> file_size(const std::filesystem::path& file) const = 0;
  // SHA-256 (hex) of the file's bytes; throws std::runtime_error when it cannot be read.
  virtual std::string sha256(const std::filesystem::path& file) const = 0;
  // Copies `from` to `to` (creating the directory of `to`) and flushes `to` to the disk.
  virtual void copy_durably(const std::filesystem::path& from,
                            const std::filesystem::path& to) const = 0;
  virtual void rename(const std::filesystem::path& from, const std::filesystem::path& to) const = 0;
  // Removes a file; nothing happens when it does not exist.
  virtual void remove(const std::filesystem::path& file) const = 0;
  // Regular files anywhere below `root`; none when `root` does not exist.
  virtual std::vector<std::filesystem::path> files_under(
      const std::filesystem::path& root) const = 0;
};

class LocalFileSystem final : public FileSystem {
 public:
  std::optional<std::int64_t> file_size(const std::filesystem::path& file) const override;
  std::string sha256(const std::filesystem::path& file) const override;
  void copy_durably(const std::filesystem::path& from,
                    const std::filesystem::path& to) const override;
  void rename(const std::filesystem::path& from, const std::filesystem::path& to) const override;
  void remove(const std::filesystem::path& file) const override;
  std::vector<std::filesystem::path> files_under(const std::filesystem::path& root) const override;
};

// The process-wide LocalFileSystem.
const FileSystem& local_file_system();

// Campaign files larger than this are refused (the largest example is a few kB).
inline constexpr std::uintmax_t kMaxInputFileBytes = 16u << 20;

// The text of a user's input file. Only a regular file of at most kMaxInputFileBytes is read, so
// that /dev/zero or a named pipe cannot hang the reader. Throws InvalidInput naming the file, the
// problem and a fix.
std::string read_input_file(const std::filesystem::path& file);

}  // namespace millflow::engine
