#include "engine/artifacts.hpp"

#include <unistd.h>

#include <atomic>
#include <stdexcept>

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

std::string unique_suffix() {
  static std::atomic<unsigned> counter{0};
  return ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
}

}  // namespace

fs::path ArtifactStore::path_of(const std::string& sha256) const {
  return root_ / sha256.substr(0, 2) / sha256;
}

StoredArtifact ArtifactStore::put(const std::string& name, const fs::path& file) const {
  const auto size = files_->file_size(file);
  if (!size)
    throw std::runtime_error("artifact " + name + ": the task did not write " + file.string());
  StoredArtifact artifact{name, files_->sha256(file), *size};
  if (verify(artifact)) return artifact;
  const fs::path target = path_of(artifact.sha256);
  const fs::path temporary = target.string() + unique_suffix();
  try {
    files_->copy_durably(file, temporary);
    files_->rename(temporary, target);
  } catch (...) {
    files_->remove(temporary);
    throw;
  }
  if (!verify(artifact))
    throw std::runtime_error("artifact " + name + " changed while it was being stored");
  return artifact;
}

bool ArtifactStore::verify(const StoredArtifact& artifact) const {
  const fs::path file = path_of(artifact.sha256);
  if (files_->file_size(file) != artifact.size) return false;
  try {
    return files_->sha256(file) == artifact.sha256;
  } catch (const std::runtime_error&) {
    return false;
  }
}

std::vector<fs::path> ArtifactStore::stored_files() const {
  return files_->files_under(root_);
}

void ArtifactStore::remove(const fs::path& stored_file) const {
  files_->remove(stored_file);
}

}  // namespace millflow::engine
