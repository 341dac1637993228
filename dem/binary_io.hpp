#pragma once
// Binary serialisation for checkpoints and flow samples: a byte writer/reader for the payload and
// a versioned, checksummed file container around it.
//
// Container file layout (all integers little-endian, no padding):
//   offset        size  field
//   0             8     magic: 8 ASCII bytes naming the file kind (e.g. "MFCHKPT1")
//   8             4     uint32 format version of the payload
//   12            8     uint64 payload size P in bytes
//   20            P     payload bytes
//   20 + P        32    SHA-256 of bytes [0, 20 + P) (magic, version, size and payload)
// Total size: 52 + P bytes. The container layout itself never changes between versions; the
// version describes the payload's own layout, so a reader checks the checksum first and only
// then decides whether it understands the version.
//
// Payload encoding written by BinaryWriter (read back by BinaryReader in the same order):
//   put<T>(v)        sizeof(T) bytes: the object representation of v (little-endian hosts only)
//   put_span<T>(s)   uint64 element count, then count * sizeof(T) bytes
//   put_string(s)    uint64 byte count, then the bytes (no terminator)
// Nothing is self-describing: reader and writer must agree on the sequence of calls.
#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace millflow::dem {

static_assert(std::endian::native == std::endian::little,
              "millflow's binary files are little-endian and written by memcpy");

// Raised for any file or byte sequence that cannot be read back: missing, truncated, altered,
// of another kind or from a newer format.
struct CorruptData : std::runtime_error {
  using std::runtime_error::runtime_error;
};

template <class T>
concept TriviallyCopyable = std::is_trivially_copyable_v<T>;

class BinaryWriter {
 public:
  template <TriviallyCopyable T>
  void put(const T& value) {
    append(&value, sizeof(T));
  }

  template <TriviallyCopyable T>
  void put_span(std::span<const T> values) {
    put<std::uint64_t>(values.size());
    append(values.data(), values.size_bytes());
  }

  void put_string(std::string_view text) {
    put<std::uint64_t>(text.size());
    append(text.data(), text.size());
  }

  const std::string& bytes() const { return bytes_; }

 private:
  void append(const void* data, std::size_t size) {
    bytes_.append(static_cast<const char*>(data), size);
  }

  std::string bytes_;
};

// Reads from a view of bytes it does not own: the bytes must outlive the reader. Every read is
// bounds-checked and throws CorruptData("... truncated at byte N ...") instead of overrunning.
class BinaryReader {
 public:
  explicit BinaryReader(std::string_view bytes) : bytes_(bytes) {}

  template <TriviallyCopyable T>
  T get() {
    T value;
    std::memcpy(&value, take(sizeof(T), "a value"), sizeof(T));
    return value;
  }

  template <TriviallyCopyable T>
  std::vector<T> get_vector() {
    const std::size_t count = take_count(sizeof(T));
    std::vector<T> values(count);
    if (count > 0)
      std::memcpy(values.data(), take(count * sizeof(T), "an array"), count * sizeof(T));
    return values;
  }

  std::string get_string() {
    const std::size_t size = take_count(1);
    return std::string(take(size, "a string"), size);
  }

  bool at_end() const { return position_ == bytes_.size(); }
  std::size_t position() const { return position_; }

 private:
  // Advances past `size` bytes and returns where they start; `what` names them for the error.
  const char* take(std::size_t size, const char* what);
  // Reads an element count and checks that that many elements of `element_size` bytes remain.
  std::size_t take_count(std::size_t element_size);

  std::string_view bytes_;
  std::size_t position_ = 0;
};

// Writes the container durably (util::write_file_durably): a crash leaves either the old file or
// the complete new one. `magic8` must be exactly 8 bytes (std::invalid_argument
// otherwise); I/O failures throw std::runtime_error naming the path and the system error.
void write_checksummed_file(const std::filesystem::path& path, std::string_view magic8,
                            std::uint32_t version, std::string_view payload);

// Reads and verifies the container; returns the payload and stores the version in *version_out
// if given. Throws CorruptData for a missing or unreadable file, a truncated file, a wrong magic
// ("not a <magic> file"), a size mismatch, a checksum mismatch, or a version newer than
// `max_version` ("written by a newer millflow: version X, this build reads up to Y").
std::string read_checksummed_file(const std::filesystem::path& path, std::string_view magic8,
                                  std::uint32_t max_version, std::uint32_t* version_out = nullptr);

}  // namespace millflow::dem
