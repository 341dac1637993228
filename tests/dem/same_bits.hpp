#pragma once
// Whether two results are the same to the bit (NaN matches NaN of the same payload, -0 does not
// match +0): what the determinism tests compare.
#include <cstring>
#include <span>

#include "dem/vec.hpp"

namespace millflow::dem::testing {

inline bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

inline bool same_bits(std::span<const Vec3> a, std::span<const Vec3> b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size_bytes()) == 0;
}

inline bool same_bits(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * 9) == 0;
}

}  // namespace millflow::dem::testing
