#include "engine/files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include "engine/hash.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

void flush_to_disk(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

std::optional<std::int64_t> LocalFileSystem::file_size(const fs::path& file) const {
  std::error_code error;
  const auto size = fs::file_size(file, error);
  if (error) return std::nullopt;
  return static_cast<std::int64_t>(size);
}

std::string LocalFileSystem::sha256(const fs::path& file) const {
  return sha256_file_hex(file);
}

void LocalFileSystem::copy_durably(const fs::path& from, const fs::path& to) const {
  fs::create_directories(to.parent_path());
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  flush_to_disk(to);
}

void LocalFileSystem::rename(const fs::path& from, const fs::path& to) const {
  fs::rename(from, to);
}

void LocalFileSystem::remove(const fs::path& file) const {
  std::error_code ignored;
  fs::remove(file, ignored);
}

std::vector<fs::path> LocalFileSystem::files_under(const fs::path& root) const {
  std::vector<fs::path> files;
  std::error_code error;
  if (!fs::is_directory(root, error)) return files;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    if (entry.is_regular_file()) files.push_back(entry.path());
  }
  return files;
}

const FileSystem& local_file_system() {
  static const LocalFileSystem local;
  return local;
}

}  // namespace millflow::engine
