#include "dem/binary_io.hpp"

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>

#include <fmt/format.h>
#include "util/durable_file.hpp"
#include "util/sha256.hpp"

namespace millflow::dem {

namespace {

constexpr std::size_t kMagicSize = 8;
constexpr std::size_t kHeaderSize = kMagicSize + sizeof(std::uint32_t) + sizeof(std::uint64_t);
constexpr std::size_t kDigestSize = 32;

std::string_view as_chars(const util::Sha256Digest& digest) {
  return {reinterpret_cast<const char*>(digest.data()), digest.size()};
}

void require_magic8(std::string_view magic8) {
  if (magic8.size() != kMagicSize) {
    throw std::invalid_argument(
        fmt::format("binary file magic '{}' has {} bytes; it must be exactly {}", magic8,
                    magic8.size(), kMagicSize));
  }
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

void write_checksummed_file(const std::filesystem::path& path, std::string_view magic8,
                            std::uint32_t version, std::string_view payload) {
  require_magic8(magic8);
  BinaryWriter header;
  header.put(version);
  header.put<std::uint64_t>(payload.size());
  std::string bytes(magic8);
  bytes.append(header.bytes());
  bytes.append(payload);
  bytes.append(as_chars(util::sha256(bytes)));

  util::write_file_durably(path, bytes);
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
  if (as_chars(util::sha256(checked)) != stored) {
    throw CorruptData(
        fmt::format("'{}' is corrupt: checksum mismatch (stored sha256 {}, computed {})", name,
                    util::to_hex(stored), util::sha256_hex(checked)));
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
