#pragma once
// SHA-256 digests (OpenSSL libcrypto), as lowercase hex.
#include <filesystem>
#include <string>
#include <string_view>

namespace millflow::engine {

std::string sha256_hex(std::string_view data);

// Streams the file; throws std::runtime_error when it cannot be read.
std::string sha256_file_hex(const std::filesystem::path& file);

}  // namespace millflow::engine
