#pragma once
// The database file a command works on, checked before anything is written and resolved to the
// real file. The coordinator lock (<db>.lock) and every directory beside the database (artifacts,
// work, logs, jobs) are named from the resolved path, so a symbolic link or a relative path reaches
// the same lock as the real name. A hard link cannot be told from the real name, so a database file
// with more than one link is refused: two names would give two locks and two coordinators.
#include <filesystem>

namespace millflow::engine {

enum class DatabaseUse {
  create,    // submit: the file may not exist yet (its directory is created)
  existing,  // every other command: the file must exist; nothing is created
};

// Throws InvalidInput (path "--db", with a fix) for an empty path, a directory or other
// non-regular file, a dangling symbolic link, a missing file when `use` is existing, and a file
// with more than one hard link. Returns the absolute path with every symbolic link resolved.
std::filesystem::path resolve_database(const std::filesystem::path& given, DatabaseUse use);

}  // namespace millflow::engine
