// Fixed-point arithmetic for the pixel path.
//
// One rounding rule everywhere: round to nearest, ties toward +infinity,
// implemented as (x + 2^(s-1)) >> s on a wide enough integer (arithmetic shift
// for signed values, which C++20 defines). One saturation rule: results are
// clamped to the destination's representable range, never wrapped.
//
// Formats are written Qm.n: m integer bits, n fractional bits; a value v is
// stored as round(v * 2^n). Unsigned unless the name says otherwise.
#pragma once

#include <bit>
#include <cstdint>
#include <type_traits>

#include "core/base/status.h"

namespace camsim {

// A fixed-point value that carries its format in its type: Q<I, F, Signed>.
// Used for parameters and tables; pixel kernels work on the raw integers.
template <int I, int F, bool Signed = false>
struct Q {
  static_assert(I + F + (Signed ? 1 : 0) <= 32, "Q format must fit in 32 bits");
  using Raw = typename std::conditional<Signed, int32_t, uint32_t>::type;
  static constexpr int kIntBits = I;
  static constexpr int kFracBits = F;
  static constexpr int64_t kMaxRaw =
      Signed ? (int64_t{1} << (I + F)) - 1 : (int64_t{1} << (I + F)) - 1;
  static constexpr int64_t kMinRaw = Signed ? -(int64_t{1} << (I + F)) : 0;
  static constexpr int64_t kOne = int64_t{1} << F;

  Raw raw = 0;

  // Conversion from a double at configure time: round to nearest (ties up),
  // clamp to range; NaN becomes 0. Uses only IEEE basic operations.
  static constexpr Q FromDouble(double v) {
    Q q;
    if (!(v == v)) return q;  // NaN
    const double scaled = v * static_cast<double>(kOne);  // exact: power of two
    if (scaled >= static_cast<double>(kMaxRaw)) {
      q.raw = static_cast<Raw>(kMaxRaw);
    } else if (scaled <= static_cast<double>(kMinRaw)) {
      q.raw = static_cast<Raw>(kMinRaw);
    } else {
      const double shifted = scaled + 0.5;
      int64_t f = static_cast<int64_t>(shifted);          // truncates toward 0
      if (static_cast<double>(f) > shifted) f -= 1;       // floor for negatives
      q.raw = static_cast<Raw>(f);
    }
    return q;
  }
  constexpr double ToDouble() const { return static_cast<double>(raw) / static_cast<double>(kOne); }
};

// Round-to-nearest (ties up) right shift. s may be 0.
constexpr int64_t RoundShift(int64_t x, int s) {
  return s == 0 ? x : (x + (int64_t{1} << (s - 1))) >> s;
}
constexpr uint64_t RoundShiftU(uint64_t x, int s) {
  return s == 0 ? x : (x >> s) + ((x >> (s - 1)) & 1u);  // no overflow near 2^64
}

constexpr uint32_t SatU32(uint64_t x) { return x > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<uint32_t>(x); }
constexpr uint32_t SatU32(int64_t x) {
  return x < 0 ? 0u : (x > 0xFFFFFFFFll ? 0xFFFFFFFFu : static_cast<uint32_t>(x));
}
constexpr int64_t Clamp64(int64_t x, int64_t lo, int64_t hi) { return x < lo ? lo : (x > hi ? hi : x); }

// A positive scale factor as mantissa * 2^-shift, mantissa normalised to
// [2^31, 2^32): 32 significant bits over any range, so exposure factors from
// 1e-9 to 1e9 keep the same relative precision (2^-32). Apply() multiplies an
// unsigned 32-bit sample in a 64-bit product and rounds (ties up), saturating.
struct UScale {
  uint32_t mant = 0;  // 0 means the factor is zero
  int shift = 0;      // 0..95

  static constexpr int kMaxShift = 95;

  // Exact normalisation by powers of two (IEEE exact), then one rounding.
  // Fails for factors that would need a negative shift (> 2^32) or NaN.
  static Result<UScale> FromDouble(double factor, const char* field) {
    if (!(factor >= 0.0)) return InvalidArgument(field, "scale factor must be >= 0 and not NaN");
    UScale s;
    if (factor == 0.0) return s;
    int shift = 0;
    double m = factor;
    while (m < 2147483648.0 && shift < kMaxShift) { m *= 2.0; ++shift; }  // into [2^31, 2^32)
    if (m >= 4294967296.0) return InvalidArgument(field, "scale factor too large (>= 2^32)");
    if (shift >= kMaxShift && m < 2147483648.0) return s;  // below 2^-64: zero
    double r = m + 0.5;
    uint64_t mi = static_cast<uint64_t>(r);
    if (mi >= 4294967296ull) {  // m rounded up to 2^32
      if (shift == 0) return InvalidArgument(field, "scale factor too large (>= 2^32 - 0.5)");
      mi >>= 1;
      --shift;
    }
    s.mant = static_cast<uint32_t>(mi);
    s.shift = shift;
    return s;
  }

  constexpr double ToDouble() const {
    double v = static_cast<double>(mant);
    for (int i = 0; i < shift; ++i) v *= 0.5;
    return v;
  }

  // round(x * factor), saturated to 32 bits.
  constexpr uint32_t Apply(uint32_t x) const {
    const uint64_t p = static_cast<uint64_t>(x) * mant;
    if (shift >= 64) return shift == 64 ? static_cast<uint32_t>(p >> 63) : 0u;  // < 1 result
    return SatU32(RoundShiftU(p, shift));
  }
};

// Integer square root, bit by bit: floor(sqrt(x)) for every 64-bit x. Slow
// (one data-dependent branch per result bit); kept as the reference that
// ISqrt64 is tested against and to build ISqrt64's table at compile time.
constexpr uint32_t ISqrt64BitByBit(uint64_t x) {
  uint64_t res = 0;
  uint64_t bit = uint64_t{1} << 62;
  while (bit > x) bit >>= 2;
  while (bit != 0) {
    if (x >= res + bit) {
      x -= res + bit;
      res = (res >> 1) + bit;
    } else {
      res >>= 1;
    }
    bit >>= 2;
  }
  return static_cast<uint32_t>(res);
}

namespace isqrt_detail {
// 1/sqrt(A) for A = (i + 1/2) / 1024, i = 256..1023 (the top 10 bits of a
// normalised 64-bit x), in Q1.15: floor(sqrt(2^41 / (2i + 1))), at most 65472.
// 768 entries, 1536 bytes, built at compile time, and one spare 0 so that a
// 32-bit gather of the last entry (ISqrt64Lanes) stays inside the array.
struct RsqrtTable {
  static constexpr int kBits = 10;
  static constexpr uint32_t kFirst = 256;  // 2^(kBits - 2): A >= 1/4
  uint16_t v[(1u << kBits) - kFirst + 1] = {};
};
constexpr RsqrtTable MakeRsqrtTable() {
  RsqrtTable t;
  for (uint32_t i = RsqrtTable::kFirst; i < (1u << RsqrtTable::kBits); ++i)
    t.v[i - RsqrtTable::kFirst] = static_cast<uint16_t>(ISqrt64BitByBit((uint64_t{1} << 41) / (2 * i + 1)));
  return t;
}
inline constexpr RsqrtTable kRsqrt = MakeRsqrtTable();
}  // namespace isqrt_detail

// Integer square root: floor(sqrt(x)) for every 64-bit x, exact. No division,
// no loop and no branch on the data besides x == 0 (32 unpredictable branches
// are what made the bit-by-bit version slow): 7 multiplies, about 10x faster
// on x86-64.
//
//   1. Normalise: xn = x * 4^k in [2^62, 2^64), T = sqrt(xn) in [2^31, 2^32);
//      floor(sqrt(x)) = floor(T / 2^k). A = a / 2^32, a = the top 32 bits of
//      xn, so A in [1/4, 1) and sqrt(A) 2^32 = T (1 - eps), eps < 2^-31.
//   2. Y0 ~ 1/sqrt(A) from the table: relative error |d0| <= 1/1026 + 2^-15
//      < 1.01e-3. One Newton step Y1 = Y0 (3 - A Y0^2) / 2 has relative
//      error -1.5 d0^2 - 0.5 d0^3 plus truncations (< 2^-28): |d1| < 1.53e-6.
//   3. s = A Y1 2^32: |s - T| = D < T (1.53e-6 + eps) + 1 < 6575, and
//      |xn - s^2| < D (2T + D) < 2^45.7. One coupled Newton (Karp-Markstein)
//      step s' = s + (xn - s^2) Y1 / 2^33, in Q.16 and signed (s may be on
//      either side of T). The exact step with 1/T for Y1 lands at
//      T - D^2 / (2T), off by < 0.0101; Y1's error adds < D * 1.53e-6 <
//      0.0101 and the two truncations < 2^-15: |s' - T| < 0.021.
//   4. r = floor(s' / 2^k) is therefore floor(sqrt(x)) - 1, + 0 or + 1 (it is
//      at most 2^32: T < 2^32, so r = 2^32 only from the overshoot, and is
//      brought back first). Two exact tests then pick floor(sqrt(x)):
//      r^2 > x means one too high; x - r^2 > 2r, i.e. (r + 1)^2 <= x, one too low.
//      At most one holds, so one square serves both tests.
// Every operation is on uint64 (modulo 2^64; the bounds above keep the true
// values of the signed quantities far inside int64), so no input can overflow.
// The unit tests (test_random.cc) check every x < 2^22, perfect squares and
// their neighbours across the whole range, both ends of every table cell at
// every scale, and random values (an exhaustive run over x < 2^34 and 2e8
// random values also found no difference from ISqrt64BitByBit).
constexpr uint32_t ISqrt64(uint64_t x) {
  using isqrt_detail::kRsqrt;
  using isqrt_detail::RsqrtTable;
  if (x == 0) return 0;
  const int k = std::countl_zero(x) >> 1;
  const uint64_t xn = x << (2 * k);
  const uint64_t a = xn >> 32;  // A in Q0.32, [2^30, 2^32)
  const uint64_t y0 = uint64_t{kRsqrt.v[(a >> (32 - RsqrtTable::kBits)) - RsqrtTable::kFirst]} << 15;  // Q2.30
  const uint64_t y0sq = (y0 * y0) >> 32;                  // Y0^2, Q.28
  const uint64_t d = (uint64_t{3} << 60) - a * y0sq;      // 3 - A Y0^2, Q.60, ~2^61
  const uint64_t y = (y0 * (d >> 30)) >> 31;              // Y1, Q.30, <= 2^31 (1 + 2e-6)
  const uint64_t s = (a * y) >> 30;                       // ~T
  const int64_t e = static_cast<int64_t>(xn - s * s);     // xn - s^2
  const uint64_t ey = static_cast<uint64_t>(e >> 16) * y; // (xn - s^2) Y1, Q.46, |.| < 2^61
  const uint64_t s16 = (s << 16) + static_cast<uint64_t>(static_cast<int64_t>(ey) >> 31);  // s', Q.16, > 0
  uint64_t r = s16 >> (16 + k);
  r -= r >> 32;           // 2^32 -> 2^32 - 1 (r <= 2^32), so r * r below cannot wrap
  const uint64_t sq = r * r;
  r = r - (sq > x) + (sq <= x && x - sq > 2 * r);  // one too high, one too low (at most one holds)
  return static_cast<uint32_t>(r);
}

// r[i] = ISqrt64(x[i]) for i < n: the same steps in eight 64-bit AVX-512 or
// four AVX2 lanes where the CPU has them (fixed.cc), one by one elsewhere.
void ISqrt64Lanes(const uint64_t* x, uint32_t* r, int n);

}  // namespace camsim
