#include "engine/database_path.hpp"

#include <fmt/format.h>
#include <sys/stat.h>

#include "engine/validation.hpp"

namespace millflow::engine {
namespace fs = std::filesystem;
namespace {

[[noreturn]] void refuse(const std::string& problem, const std::string& fix) {
  throw InvalidInput({{"--db", problem, fix}});
}

}  // namespace

fs::path resolve_database(const fs::path& given, DatabaseUse use) {
  constexpr const char* kName = "name a database file, e.g. --db campaigns/mill.db";
  if (given.empty()) refuse("the database path is empty", kName);
  if (!given.has_filename())
    refuse(fmt::format("\"{}\" names a directory, not a database file", given.string()), kName);
  std::error_code error;
  const fs::file_status target = fs::status(given, error);
  if (fs::is_symlink(fs::symlink_status(given, error)) && !fs::exists(target)) {
    refuse(fmt::format("\"{}\" is a symbolic link to a missing file", given.string()),
           "pass the real database file, or remove the link");
  }
  if (!fs::exists(target)) {
    if (use == DatabaseUse::existing) {
      refuse(fmt::format("no database at \"{}\"", given.string()),
             "submit a campaign first, or pass the --db of an existing database");
    }
    return fs::weakly_canonical(fs::absolute(given));
  }
  if (!fs::is_regular_file(target)) {
    refuse(fmt::format("\"{}\" is {}, not a database file", given.string(),
                       fs::is_directory(target) ? "a directory" : "a special file"),
           kName);
  }
  const fs::path real = fs::canonical(given);
  struct stat info {};
  if (::stat(real.c_str(), &info) == 0 && info.st_nlink > 1) {
    refuse(fmt::format("\"{}\" has {} hard links: millflow locks a database by its name, so two "
                       "names would let two coordinators write it at once",
                       real.string(), info.st_nlink),
           "keep one name (remove the other hard links; `find / -samefile` lists them) or work on "
           "a copy");
  }
  return real;
}

}  // namespace millflow::engine
