#include "engine/artifacts.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <fstream>
#include <stdexcept>

#include "engine/hash.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

std::string unique_suffix() {
  static std::atomic<unsigned> counter{0};
  return ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
}

void flush_to_disk(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

fs::path ArtifactStore::path_of(const std::string& sha256) const {
  return root_ / sha256.substr(0, 2) / sha256;
}

StoredArtifact ArtifactStore::put(const std::string& name, const fs::path& file) const {
  StoredArtifact artifact{name, sha256_file_hex(file), static_cast<std::int64_t>(fs::file_size(file))};
  if (verify(artifact)) return artifact;
  const fs::path target = path_of(artifact.sha256);
  fs::create_directories(target.parent_path());
  const fs::path temporary = target.string() + unique_suffix();
  fs::copy_file(file, temporary, fs::copy_options::overwrite_existing);
  flush_to_disk(temporary);
  fs::rename(temporary, target);
  if (!verify(artifact)) throw std::runtime_error("artifact " + name + " changed while it was being stored");
  return artifact;
}

bool ArtifactStore::verify(const StoredArtifact& artifact) const {
  const fs::path file = path_of(artifact.sha256);
  std::error_code error;
  const auto size = fs::file_size(file, error);
  if (error || static_cast<std::int64_t>(size) != artifact.size) return false;
  try {
    return sha256_file_hex(file) == artifact.sha256;
  } catch (const std::runtime_error&) {
    return false;
  }
}

std::vector<std::string> ArtifactStore::stored_digests() const {
  std::vector<std::string> digests;
  std::error_code error;
  if (!fs::is_directory(root_, error)) return digests;
  for (const auto& entry : fs::recursive_directory_iterator(root_)) {
    if (entry.is_regular_file()) digests.push_back(entry.path().filename().string());
  }
  return digests;
}

void ArtifactStore::remove(const std::string& sha256) const { fs::remove(root_ / sha256.substr(0, 2) / sha256); }

}  // namespace millflow::engine
