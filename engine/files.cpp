#include "engine/files.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "engine/validation.hpp"
#include "util/durable_file.hpp"
#include "util/sha256.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
std::optional<std::int64_t> LocalFileSystem::file_size(const fs::path& file) const {
  std::error_code error;
  const auto size = fs::file_size(file, error);
  if (error) return std::nullopt;
  return static_cast<std::int64_t>(size);
}

std::string LocalFileSystem::sha256(const fs::path& file) const {
  return util::sha256_file_hex(file);
}

void LocalFileSystem::copy_durably(const fs::path& from, const fs::path& to) const {
  fs::create_directories(to.parent_path());
  util::copy_file_durably(from, to);
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

std::string read_input_file(const fs::path& file) {
  const auto unreadable = [&file](int error) {
    return InvalidInput(
        {{"", fmt::format("cannot read campaign file {}: {}", file.string(), std::strerror(error)),
          "check the file name and its permissions"}});
  };
  std::error_code error;
  const auto status = fs::status(file, error);
  if (!fs::exists(status)) throw unreadable(error ? error.value() : ENOENT);
  if (!fs::is_regular_file(status)) {
    throw InvalidInput({{"", fmt::format("{} is not a regular file", file.string()),
                         "pass a campaign JSON file"}});
  }
  const auto size = fs::file_size(file, error);
  if (error) throw unreadable(error.value());
  if (size > kMaxInputFileBytes) {
    throw InvalidInput(
        {{"",
          fmt::format("{} has {} bytes, more than the {} a campaign file may have", file.string(),
                      size, kMaxInputFileBytes),
          "a campaign describes its points by sweeps; split a longer one into several"}});
  }
  std::ifstream in(file, std::ios::binary);
  std::string text(size, '\0');
  if (!in.read(text.data(), static_cast<std::streamsize>(size))) throw unreadable(errno);
  return text;
}

const FileSystem& local_file_system() {
  static const LocalFileSystem local;
  return local;
}

}  // namespace millflow::engine
