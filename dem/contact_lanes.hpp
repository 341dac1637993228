#pragma once
// Four contacts at once, one per lane of an AVX2 register (docs/benchmarks.md, "Four contacts in
// lanes"). A contact's law is a chain of dependent operations (about 100 cycles from its loads
// to its force) that the core cannot overlap with the next contact's; four contacts in the lanes
// of the same instructions run that chain once for four.
//
// Lanes4 holds one double per contact, Vec3Lanes a 3-vector per contact as three Lanes4 (x, y,
// z). Every operation is, in each lane, the IEEE operation Vec3 does on the same elements in the
// same order, so the law gives each contact the bits it gets alone:
//   a + b, a - b, a * b, a / b, -a, abs, sqrt   element by element (no FMA: -ffp-contract=off)
//   a.dot(b), a.squaredNorm()                   (a0 b0 + a1 b1) + a2 b2, Eigen's order
//   a.cross(b)                                  (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)
// The law's conditions are masks of lanes (Mask4): select() blends, any() says whether a lane
// needs a slow path.
#include <array>
#include <cstddef>

#include "dem/contact_law.hpp"
#include "dem/packed_vec3.hpp"
#include "dem/vec.hpp"

namespace millflow::dem {
inline constexpr std::size_t kContactLanes = 4;  // contacts at once where the build has AVX2
}  // namespace millflow::dem

#if defined(__AVX2__)
#include <immintrin.h>

namespace millflow::dem {

class Mask4 {
 public:
  Mask4() : bits_(_mm256_setzero_pd()) {}  // no lane set
  explicit Mask4(__m256d bits) : bits_(bits) {}
  __m256d bits() const { return bits_; }
  friend Mask4 operator|(const Mask4& a, const Mask4& b) {
    return Mask4(_mm256_or_pd(a.bits_, b.bits_));
  }
  friend Mask4 operator!(const Mask4& a) {
    return Mask4(_mm256_xor_pd(a.bits_, _mm256_castsi256_pd(_mm256_set1_epi64x(-1))));
  }
  friend bool any(const Mask4& a) { return _mm256_movemask_pd(a.bits_) != 0; }
  // The lanes set, as bits 0-3.
  int lanes() const { return _mm256_movemask_pd(bits_); }

 private:
  __m256d bits_;
};

class Lanes4 {
 public:
  Lanes4() = default;                                      // uninitialised, as a double
  Lanes4(double value) : lanes_(_mm256_set1_pd(value)) {}  // NOLINT: a constant in every lane
  explicit Lanes4(__m256d lanes) : lanes_(lanes) {}
  static Lanes4 of(double a, double b, double c, double d) {
    return Lanes4(_mm256_setr_pd(a, b, c, d));
  }
  __m256d lanes() const { return lanes_; }
  std::array<double, 4> values() const {
    std::array<double, 4> out;
    _mm256_storeu_pd(out.data(), lanes_);
    return out;
  }

  friend Lanes4 operator+(const Lanes4& a, const Lanes4& b) {
    return Lanes4(_mm256_add_pd(a.lanes_, b.lanes_));
  }
  friend Lanes4 operator-(const Lanes4& a, const Lanes4& b) {
    return Lanes4(_mm256_sub_pd(a.lanes_, b.lanes_));
  }
  friend Lanes4 operator*(const Lanes4& a, const Lanes4& b) {
    return Lanes4(_mm256_mul_pd(a.lanes_, b.lanes_));
  }
  friend Lanes4 operator/(const Lanes4& a, const Lanes4& b) {
    return Lanes4(_mm256_div_pd(a.lanes_, b.lanes_));
  }
  friend Lanes4 operator-(const Lanes4& a) {
    return Lanes4(_mm256_xor_pd(a.lanes_, _mm256_set1_pd(-0.0)));
  }
  friend Lanes4 abs(const Lanes4& a) {
    return Lanes4(_mm256_andnot_pd(_mm256_set1_pd(-0.0), a.lanes_));
  }
  friend Lanes4 sqrt(const Lanes4& a) { return Lanes4(_mm256_sqrt_pd(a.lanes_)); }
  // As C++ compares doubles: false where either is NaN, but != true there.
  friend Mask4 operator<(const Lanes4& a, const Lanes4& b) {
    return Mask4(_mm256_cmp_pd(a.lanes_, b.lanes_, _CMP_LT_OQ));
  }
  friend Mask4 operator>(const Lanes4& a, const Lanes4& b) {
    return Mask4(_mm256_cmp_pd(a.lanes_, b.lanes_, _CMP_GT_OQ));
  }
  friend Mask4 operator==(const Lanes4& a, const Lanes4& b) {
    return Mask4(_mm256_cmp_pd(a.lanes_, b.lanes_, _CMP_EQ_OQ));
  }
  friend Mask4 operator!=(const Lanes4& a, const Lanes4& b) {
    return Mask4(_mm256_cmp_pd(a.lanes_, b.lanes_, _CMP_NEQ_UQ));
  }
  friend Lanes4 select(const Mask4& condition, const Lanes4& if_true, const Lanes4& if_false) {
    return Lanes4(_mm256_blendv_pd(if_false.lanes_, if_true.lanes_, condition.bits()));
  }

 private:
  __m256d lanes_;
};

class Vec3Lanes {
 public:
  using Scalar = Lanes4;
  Vec3Lanes() = default;  // uninitialised, as a Vec3
  Vec3Lanes(const Lanes4& x, const Lanes4& y, const Lanes4& z) : x_(x), y_(y), z_(z) {}
  static Vec3Lanes Zero() { return {Lanes4(0.0), Lanes4(0.0), Lanes4(0.0)}; }
  // a's 3-vector in lane 0, b's in lane 1 and so on.
  static Vec3Lanes gather(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    const __m256d xy_ac = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(a.data())),
                                               _mm_loadu_pd(c.data()), 1);
    const __m256d xy_bd = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(b.data())),
                                               _mm_loadu_pd(d.data()), 1);
    return {Lanes4(_mm256_unpacklo_pd(xy_ac, xy_bd)), Lanes4(_mm256_unpackhi_pd(xy_ac, xy_bd)),
            Lanes4::of(a[2], b[2], c[2], d[2])};
  }
  void scatter(Vec3& a, Vec3& b, Vec3& c, Vec3& d) const {
    const __m256d xy_ac = _mm256_unpacklo_pd(x_.lanes(), y_.lanes());
    const __m256d xy_bd = _mm256_unpackhi_pd(x_.lanes(), y_.lanes());
    _mm_storeu_pd(a.data(), _mm256_castpd256_pd128(xy_ac));
    _mm_storeu_pd(c.data(), _mm256_extractf128_pd(xy_ac, 1));
    _mm_storeu_pd(b.data(), _mm256_castpd256_pd128(xy_bd));
    _mm_storeu_pd(d.data(), _mm256_extractf128_pd(xy_bd, 1));
    const __m128d z_ab = _mm256_castpd256_pd128(z_.lanes());
    const __m128d z_cd = _mm256_extractf128_pd(z_.lanes(), 1);
    _mm_store_sd(a.data() + 2, z_ab);
    _mm_storeh_pd(b.data() + 2, z_ab);
    _mm_store_sd(c.data() + 2, z_cd);
    _mm_storeh_pd(d.data() + 2, z_cd);
  }

  Lanes4 dot(const Vec3Lanes& b) const { return (x_ * b.x_ + y_ * b.y_) + z_ * b.z_; }
  Lanes4 squaredNorm() const { return dot(*this); }
  Vec3Lanes cross(const Vec3Lanes& b) const {
    return {y_ * b.z_ - z_ * b.y_, z_ * b.x_ - x_ * b.z_, x_ * b.y_ - y_ * b.x_};
  }

  friend Vec3Lanes operator+(const Vec3Lanes& a, const Vec3Lanes& b) {
    return {a.x_ + b.x_, a.y_ + b.y_, a.z_ + b.z_};
  }
  friend Vec3Lanes operator-(const Vec3Lanes& a, const Vec3Lanes& b) {
    return {a.x_ - b.x_, a.y_ - b.y_, a.z_ - b.z_};
  }
  friend Vec3Lanes operator-(const Vec3Lanes& a) { return {-a.x_, -a.y_, -a.z_}; }
  friend Vec3Lanes operator*(const Lanes4& s, const Vec3Lanes& a) {
    return {s * a.x_, s * a.y_, s * a.z_};
  }
  friend Vec3Lanes operator*(const Vec3Lanes& a, const Lanes4& s) {
    return {a.x_ * s, a.y_ * s, a.z_ * s};
  }
  friend Vec3Lanes operator/(const Vec3Lanes& a, const Lanes4& s) {
    return {a.x_ / s, a.y_ / s, a.z_ / s};
  }
  friend Vec3Lanes select(const Mask4& condition, const Vec3Lanes& if_true,
                          const Vec3Lanes& if_false) {
    return {select(condition, if_true.x_, if_false.x_), select(condition, if_true.y_, if_false.y_),
            select(condition, if_true.z_, if_false.z_)};
  }

 private:
  Lanes4 x_, y_, z_;
};

// What the law reads of a pair's parameters, one pair per lane.
struct PairParamsLanes {
  Lanes4 normal_stiffness, tangential_stiffness, tangential_damping_ratio, friction;
};
inline PairParamsLanes gather_pair_params(const PairParams& a, const PairParams& b,
                                          const PairParams& c, const PairParams& d) {
  if (&a == &b && &a == &c && &a == &d)  // one material pair: the common case
    return {a.normal_stiffness, a.tangential_stiffness, a.tangential_damping_ratio, a.friction};
  const auto field = [&](double PairParams::*f) { return Lanes4::of(a.*f, b.*f, c.*f, d.*f); };
  return {field(&PairParams::normal_stiffness), field(&PairParams::tangential_stiffness),
          field(&PairParams::tangential_damping_ratio), field(&PairParams::friction)};
}

}  // namespace millflow::dem

#endif

namespace millflow::dem {

// For the tests, which are built without the library's instruction set: whether the pair pass
// runs contacts in lanes, each lane operation on four pairs of vectors at once, and the law on
// four contacts at once.
bool contact_lanes_available();
std::array<ContactVec3Operations, 4> operations_in_lanes(const std::array<Vec3, 4>& a,
                                                         const std::array<Vec3, 4>& b,
                                                         const std::array<double, 4>& s);
struct ContactLawInputs {
  PairParams params;
  double damping_n = 0.0;
  ContactGeometry geometry;
  Vec3 spring = Vec3::Zero();
};
std::array<ContactResponse, 4> contact_law_in_lanes(const std::array<ContactLawInputs, 4>& four,
                                                    double dt);

}  // namespace millflow::dem
