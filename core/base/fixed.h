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
    if (mi >= 4294967296ull) { mi >>= 1; --shift; }
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

// Integer square root: floor(sqrt(x)) for 64-bit x, exact (bit-by-bit).
constexpr uint32_t ISqrt64(uint64_t x) {
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

}  // namespace camsim
