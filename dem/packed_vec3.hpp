#pragma once
// The 3-vector of the pair pass's contacts taken one at a time (those that start, a block's last
// few; the others go four at a time, dem/contact_lanes.hpp) and of the force gather. Eigen
// keeps a Vector3d in three scalars, and GCC packs few of the law's operations, so a contact ran
// about 180 scalar multiplications, additions, subtractions and loads (docs/benchmarks.md, "One
// contact's vectors in one register"). Where the build has AVX2, PackedVec3 holds x, y and z in
// the low three lanes of one 256-bit register, the fourth lane zero: an element-wise operation is
// one instruction. Each operation is the IEEE operation Eigen does on the same elements in the
// same order, so the law gives the same bits on either type:
//   a + b, a - b, s * a, a * s, a / s, -a  element by element (no FMA: -ffp-contract=off)
//   a.dot(b), a.squaredNorm()              (a0 b0 + a1 b1) + a2 b2, Eigen's order for a 3-vector
//   a.cross(b)                             (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)
// Builds without AVX2 compute with Vec3 itself (ContactVec3 below).
#include "dem/contact_law.hpp"
#include "dem/vec.hpp"

#if defined(__AVX2__)
#include <immintrin.h>
#endif

namespace millflow::dem {

#if defined(__AVX2__)

class PackedVec3 {
 public:
  using Scalar = double;
  PackedVec3() = default;  // uninitialised, as a Vec3
  static PackedVec3 Zero() { return PackedVec3(_mm256_setzero_pd()); }
  // Two loads, x and y then z: the element after a Vec3 may lie past the end of its array (a
  // masked load of the three ran as fast). A Vec3 written just before by narrower stores is
  // better built in registers: this load waits for those stores to reach the cache.
  static PackedVec3 load(const Vec3& a) {
    return PackedVec3(_mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(a.data())),
                                           _mm_load_sd(a.data() + 2), 1));
  }
  void store(Vec3& out) const {
    _mm_storeu_pd(out.data(), _mm256_castpd256_pd128(lanes_));
    _mm_store_sd(out.data() + 2, _mm256_extractf128_pd(lanes_, 1));
  }

  double dot(const PackedVec3& b) const { return sum_of_three(_mm256_mul_pd(lanes_, b.lanes_)); }
  double squaredNorm() const { return dot(*this); }
  // t = a * b.yzx - a.yzx * b holds the cross product's z, x and y: one permute fewer than
  // a.yzx * b.zxy - a.zxy * b.yzx, with the same products subtracted in the same order.
  PackedVec3 cross(const PackedVec3& b) const {
    const __m256d t =
        _mm256_sub_pd(_mm256_mul_pd(lanes_, yzx(b.lanes_)), _mm256_mul_pd(yzx(lanes_), b.lanes_));
    return PackedVec3(yzx(t));
  }

  PackedVec3& operator+=(const PackedVec3& b) { return *this = *this + b; }
  PackedVec3& operator-=(const PackedVec3& b) { return *this = *this - b; }

  friend PackedVec3 operator+(const PackedVec3& a, const PackedVec3& b) {
    return PackedVec3(_mm256_add_pd(a.lanes_, b.lanes_));
  }
  friend PackedVec3 operator-(const PackedVec3& a, const PackedVec3& b) {
    return PackedVec3(_mm256_sub_pd(a.lanes_, b.lanes_));
  }
  friend PackedVec3 operator-(const PackedVec3& a) {
    return PackedVec3(_mm256_xor_pd(a.lanes_, _mm256_set1_pd(-0.0)));
  }
  friend PackedVec3 operator*(double s, const PackedVec3& a) {
    return PackedVec3(_mm256_mul_pd(_mm256_set1_pd(s), a.lanes_));
  }
  friend PackedVec3 operator*(const PackedVec3& a, double s) {
    return PackedVec3(_mm256_mul_pd(a.lanes_, _mm256_set1_pd(s)));
  }
  friend PackedVec3 operator/(const PackedVec3& a, double s) {
    return PackedVec3(_mm256_div_pd(a.lanes_, _mm256_set1_pd(s)));
  }

 private:
  explicit PackedVec3(__m256d lanes) : lanes_(lanes) {}
  // (y, z, x, 0)
  static __m256d yzx(__m256d v) { return _mm256_permute4x64_pd(v, 0b11'00'10'01); }
  static double sum_of_three(__m256d v) {
    const __m128d xy = _mm256_castpd256_pd128(v);
    const __m128d z = _mm256_extractf128_pd(v, 1);
    return _mm_cvtsd_f64(_mm_add_sd(_mm_add_sd(xy, _mm_unpackhi_pd(xy, xy)), z));
  }

  __m256d lanes_;
};

using ContactVec3 = PackedVec3;
inline PackedVec3 load_contact_vec3(const Vec3& a) {
  return PackedVec3::load(a);
}
inline void store_contact_vec3(Vec3& out, const PackedVec3& a) {
  a.store(out);
}

#else

using ContactVec3 = Vec3;
inline const Vec3& load_contact_vec3(const Vec3& a) {
  return a;
}

#endif

// Either type stores (the force gather's sums are a Vec3 once a wall's contact is added).
inline void store_contact_vec3(Vec3& out, const Vec3& a) {
  out = a;
}

// For the tests, which are built without the library's instruction set: whether the library's
// ContactVec3 is PackedVec3, each of its operations on Vec3s loaded into it, and the contact law
// on it, as the pair pass runs them.
bool contact_vec3_is_packed();
struct ContactVec3Operations {
  Vec3 sum, difference, negated, scaled_before, scaled_after, divided, cross;
  double dot = 0.0, squared_norm = 0.0;
};
ContactVec3Operations contact_vec3_operations(const Vec3& a, const Vec3& b, double s);
ContactResponse contact_law_on_contact_vec3(const PairParams& params, double damping_n,
                                            const ContactGeometry& geometry, const Vec3& spring,
                                            double dt);

}  // namespace millflow::dem
