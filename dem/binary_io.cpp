#include "dem/binary_io.hpp"

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <system_error>

#include <fcntl.h>
#include <unistd.h>

#include <fmt/format.h>
#include <openssl/evp.h>

namespace millflow::dem {

namespace {

constexpr std::size_t kMagicSize = 8;
constexpr std::size_t kHeaderSize = kMagicSize + sizeof(std::uint32_t) + sizeof(std::uint64_t);
constexpr std::size_t kDigestSize = 32;

using Digest = std::array<unsigned char, kDigestSize>;

Digest sha256(std::string_view bytes) {
  Digest digest{};
  unsigned int size = 0;
  if (EVP_Digest(bytes.data(), bytes.size(), digest.data(), &size, EVP_sha256(), nullptr) != 1 ||
      size != kDigestSize) {
    throw std::runtime_error("sha256: OpenSSL EVP_Digest failed");
  }
  return digest;
}

std::string to_hex(std::string_view bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * bytes.size());
  for (unsigned char byte : bytes) {
    hex.push_back(kDigits[byte >> 4]);
    hex.push_back(kDigits[byte & 0xf]);
  }
  return hex;
}

std::string_view as_chars(const Digest& digest) {
  return {reinterpret_cast<const char*>(digest.data()), digest.size()};
}

void require_magic8(std::string_view magic8) {
  if (magic8.size() != kMagicSize) {
    throw std::invalid_argument(
        fmt::format("binary file magic '{}' has {} bytes; it must be exactly {}", magic8,
                    magic8.size(), kMagicSize));
  }
}

[[noreturn]] void throw_system_error(const std::string& what, const std::filesystem::path& path) {
  throw std::system_error(errno, std::generic_category(),
                          fmt::format("{} '{}'", what, path.string()));
}

// Owns a POSIX file descriptor.
class FileDescriptor {
 public:
  explicit FileDescriptor(int fd) : fd_(fd) {}
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const { return fd_; }
  // Closes now, reporting the error that a destructor would have to swallow.
  int close() {
    const int result = ::close(fd_);
    fd_ = -1;
    return result;
  }

 private:
  int fd_;
};

void write_all(int fd, std::string_view bytes, const std::filesystem::path& path) {
  while (!bytes.empty()) {
    const ssize_t written = ::write(fd, bytes.data(), bytes.size());
    if (written < 0) {
      if (errno == EINTR) continue;
      throw_system_error("cannot write", path);
    }
    bytes.remove_prefix(static_cast<std::size_t>(written));
  }
}

// Makes a rename inside `directory` durable.
void sync_directory(const std::filesystem::path& directory) {
  FileDescriptor dir(::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.get() < 0 || ::fsync(dir.get()) != 0)
    throw_system_error("cannot sync directory", directory);
}

// Writes `bytes` to a new temporary file next to `path` and returns its name.
std::filesystem::path write_temporary_beside(const std::filesystem::path& path,
                                             std::string_view bytes) {
  const std::filesystem::path directory = path.parent_path().empty() ? "." : path.parent_path();
  std::string name = (directory / fmt::format(".{}.tmp.XXXXXX", path.filename().string())).string();
  FileDescriptor file(::mkstemp(name.data()));
  if (file.get() < 0) throw_system_error("cannot create a temporary file beside", path);
  const std::filesystem::path temporary = name;
  try {
    write_all(file.get(), bytes, temporary);
    if (::fsync(file.get()) != 0) throw_system_error("cannot sync", temporary);
    if (file.close() != 0) throw_system_error("cannot close", temporary);
  } catch (...) {
    ::unlink(temporary.c_str());
    throw;
  }
  return temporary;
}

std::string read_whole_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw CorruptData(fmt::format("cannot read '{}': {}", path.string(), std::strerror(errno)));
  }
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw CorruptData(fmt::format("error while reading '{}'", path.string()));
  return bytes;
}

template <class T>
T load(std::string_view bytes, std::size_t offset) {
  T value;
  std::memcpy(&value, bytes.data() + offset, sizeof(T));
  return value;
}

}  // namespace

const char* BinaryReader::take(std::size_t size, const char* what) {
  const std::size_t remaining = bytes_.size() - position_;
  if (size > remaining) {
    throw CorruptData(
        fmt::format("binary data truncated at byte {}: reading {} needs {} bytes, "
                    "only {} remain",
                    position_, what, size, remaining));
  }
  const char* start = bytes_.data() + position_;
  position_ += size;
  return start;
}

std::size_t BinaryReader::take_count(std::size_t element_size) {
  const std::size_t count_at = position_;
  const auto count = get<std::uint64_t>();
  const std::size_t remaining = bytes_.size() - position_;
  if (count > remaining / element_size) {
    throw CorruptData(
        fmt::format("binary data truncated at byte {}: {} elements of {} bytes "
                    "announced at byte {}, only {} bytes remain",
                    position_, count, element_size, count_at, remaining));
  }
  return static_cast<std::size_t>(count);
}

std::string sha256_hex(std::string_view bytes) {
  return to_hex(as_chars(sha256(bytes)));
}

void write_checksummed_file(const std::filesystem::path& path, std::string_view magic8,
                            std::uint32_t version, std::string_view payload) {
  require_magic8(magic8);
  BinaryWriter header;
  header.put(version);
  header.put<std::uint64_t>(payload.size());
  std::string bytes(magic8);
  bytes.append(header.bytes());
  bytes.append(payload);
  bytes.append(as_chars(sha256(bytes)));

  const std::filesystem::path temporary = write_temporary_beside(path, bytes);
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    errno = error;
    throw_system_error("cannot rename a temporary file over", path);
  }
  sync_directory(path.parent_path().empty() ? "." : path.parent_path());
}

std::string read_checksummed_file(const std::filesystem::path& path, std::string_view magic8,
                                  std::uint32_t max_version, std::uint32_t* version_out) {
  require_magic8(magic8);
  const std::string bytes = read_whole_file(path);
  const std::string name = path.string();
  if (bytes.size() >= kMagicSize && std::string_view(bytes).substr(0, kMagicSize) != magic8) {
    throw CorruptData(fmt::format("'{}' is not a {} file", name, magic8));
  }
  if (bytes.size() < kHeaderSize + kDigestSize) {
    throw CorruptData(fmt::format("'{}' is truncated: {} bytes, a {} file has at least {}", name,
                                  bytes.size(), magic8, kHeaderSize + kDigestSize));
  }
  const auto version = load<std::uint32_t>(bytes, kMagicSize);
  const auto payload_size = load<std::uint64_t>(bytes, kMagicSize + sizeof(std::uint32_t));
  const std::size_t room = bytes.size() - kHeaderSize - kDigestSize;
  if (payload_size != room) {
    throw CorruptData(fmt::format(
        "'{}' is {}: its header announces {} payload bytes, the file holds {}", name,
        payload_size > room ? "truncated" : "the wrong size (size mismatch)", payload_size, room));
  }
  const std::string_view checked = std::string_view(bytes).substr(0, kHeaderSize + room);
  const std::string_view stored = std::string_view(bytes).substr(kHeaderSize + room);
  if (as_chars(sha256(checked)) != stored) {
    throw CorruptData(
        fmt::format("'{}' is corrupt: checksum mismatch (stored sha256 {}, computed {})", name,
                    to_hex(stored), sha256_hex(checked)));
  }
  if (version > max_version) {
    throw CorruptData(
        fmt::format("'{}' was written by a newer millflow: version {}, this build reads up to {}",
                    name, version, max_version));
  }
  if (version_out) *version_out = version;
  return bytes.substr(kHeaderSize, room);
}

}  // namespace millflow::dem
