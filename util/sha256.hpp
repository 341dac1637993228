#pragma once
// SHA-256 digests (OpenSSL libcrypto): the project's one implementation, for task keys, artifact
// addresses and the trailers of binary files.
#include <array>
#include <filesystem>
#include <string>
#include <string_view>

namespace millflow::util {

using Sha256Digest = std::array<unsigned char, 32>;

Sha256Digest sha256(std::string_view bytes);

// 64 lowercase hex digits.
std::string to_hex(std::string_view bytes);
std::string sha256_hex(std::string_view bytes);

// Streams the file; throws std::runtime_error when it cannot be read.
std::string sha256_file_hex(const std::filesystem::path& file);

}  // namespace millflow::util
