#pragma once
// Content-addressed artifact files beside the database: <db>.artifacts/<sha[0:2]>/<sha>.
// Files are copied in under a temporary name and renamed into place, so a crash never leaves a
// partial file under a content name (and a failed copy leaves no file at all); they are verified
// (size and SHA-256) whenever they are read. All disk access goes through a FileSystem.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "engine/files.hpp"

namespace millflow::engine {

struct StoredArtifact {
  std::string name;
  std::string sha256;
  std::int64_t size = 0;
};

class ArtifactStore {
 public:
  explicit ArtifactStore(std::filesystem::path root, const FileSystem& files = local_file_system())
      : root_(std::move(root)), files_(&files) {}

  // Copies `file` into the store (a no-op when identical content is already there).
  StoredArtifact put(const std::string& name, const std::filesystem::path& file) const;

  std::filesystem::path path_of(const std::string& sha256) const;
  // True when the stored file exists with exactly this size and digest.
  bool verify(const StoredArtifact& artifact) const;
  // Every file present (for garbage collection): content files, and the temporary files of copies
  // a crash interrupted, whose names are no digest's and which are not where path_of puts one.
  std::vector<std::filesystem::path> stored_files() const;
  void remove(const std::filesystem::path& stored_file) const;
  const std::filesystem::path& root() const { return root_; }

 private:
  std::filesystem::path root_;
  const FileSystem* files_;
};

}  // namespace millflow::engine
