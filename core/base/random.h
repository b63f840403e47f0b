// Counter-based random numbers and the per-pixel noise samplers built on them.
//
// No generator state: every random word is a pure function of
// (seed, stream, frame, x, y, draw), so any pixel of any frame can be produced
// in any order, on any thread, on any platform, with the same bits.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>

#include "core/base/fixed.h"
#include "core/base/span.h"
#include "core/base/status.h"

namespace camsim {

// Philox4x32-10 (Salmon, Moraes, Dror, Shaw, SC'11; as in Random123):
// a 10-round bijection of a 4x32-bit counter under a 2x32-bit key.
struct Philox4x32 {
  static constexpr uint32_t kM0 = 0xD2511F53u;  // round multipliers
  static constexpr uint32_t kM1 = 0xCD9E8D57u;
  static constexpr uint32_t kW0 = 0x9E3779B9u;  // Weyl key increments
  static constexpr uint32_t kW1 = 0xBB67AE85u;
  static constexpr int kRounds = 10;

  static void Generate(const uint32_t counter[4], const uint32_t key[2], uint32_t out[4]) {
    uint32_t c0 = counter[0], c1 = counter[1], c2 = counter[2], c3 = counter[3];
    uint32_t k0 = key[0], k1 = key[1];
    for (int round = 0; round < kRounds; ++round) {
      if (round > 0) {
        k0 += kW0;
        k1 += kW1;
      }
      const uint64_t p0 = static_cast<uint64_t>(kM0) * c0;
      const uint64_t p1 = static_cast<uint64_t>(kM1) * c2;
      c0 = static_cast<uint32_t>(p1 >> 32) ^ c1 ^ k0;
      c2 = static_cast<uint32_t>(p0 >> 32) ^ c3 ^ k1;
      c1 = static_cast<uint32_t>(p1);
      c3 = static_cast<uint32_t>(p0);
    }
    out[0] = c0;
    out[1] = c1;
    out[2] = c2;
    out[3] = c3;
  }
};

struct RandomBits {
  uint32_t v[4];
};

// The Philox key of one (seed, stream):
//   key = {lo32(seed), hi32(seed) ^ (stream * 0x9E3779B9 mod 2^32)}
// The multiplier is odd, so distinct streams of one seed always get distinct keys.
inline void StreamKey(uint64_t seed, uint32_t stream, uint32_t key[2]) {
  key[0] = static_cast<uint32_t>(seed);
  key[1] = static_cast<uint32_t>(seed >> 32) ^ (stream * 0x9E3779B9u);
}

// 128 random bits for one (pixel, frame, draw) of one (seed, stream):
// Philox4x32 of the counter {x, y, frame, draw} under StreamKey(seed, stream).
inline RandomBits DrawBits(uint64_t seed, uint32_t stream, uint32_t frame, uint32_t x, uint32_t y,
                           uint32_t draw = 0) {
  const uint32_t counter[4] = {x, y, frame, draw};
  uint32_t key[2];
  StreamKey(seed, stream, key);
  RandomBits bits;
  Philox4x32::Generate(counter, key, bits.v);
  return bits;
}

// DrawBits for kLanes consecutive pixels of a row at once:
//   out->v[w][i] == DrawBits(seed, stream, frame, x0 + i, y, draw).v[w]
// (x0 + i modulo 2^32). The same Philox rounds, each as a plain loop over the
// lanes, compiled on its own (random.cc) so that the compiler's choice does
// not depend on the caller: GCC and clang vectorise it (SSE2, NEON: the
// 32x32->64 multiplies become SIMD widening multiplies), and where they do
// not, the lanes' multiply chains still overlap. ~2x the throughput of
// DrawBits called pixel by pixel from a loop that does other work. Where the
// CPU has AVX-512 or AVX2, an intrinsics twin takes sixteen or eight lanes
// per instruction.
struct RandomLanes {
  static constexpr int kLanes = 16;
  uint32_t v[4][kLanes];
};
void DrawBitsLanes(uint64_t seed, uint32_t stream, uint32_t frame, uint32_t x0, uint32_t y, uint32_t draw,
                   RandomLanes* out);

// Standard normal variate from 32 uniform bits: Sample(u) approximates the
// exact quantile InvNormalCdf((u + 0.5) / 2^32) of u's bucket midpoint, so it
// is non-decreasing in u and exactly antisymmetric: Sample(~u) == -Sample(u).
// Output in Q15.16 (int32, z * 65536).
//
// Table: the top bit of u picks the half; v = the other 31 bits, mirrored in
// the upper half, counts buckets from the nearer end (|z| decreases with v).
// v is split dyadically by its leading zeros into 32 segments (segment s
// covers v in [2^(30-s), 2^(31-s)), i.e. tail probability [2^-(s+2), 2^-(s+1))),
// and each segment into 64 linear-interpolation intervals (the 6 bits after
// the leading one index, the remaining 24 interpolate). Entries hold |z| at
// the interval ends in Q7.24, stored as a pair per interval (start, end), so
// that one 64-bit load (or gather, in lanes) fetches both; one rounding to
// Q16 at the end.
//   Size: 32 * 64 pairs = 4096 int32 = 16384 bytes.
//   Error vs the exact quantile of the bucket midpoint: measured max 2.03e-5
//   in z units (at 2^20 strided u plus every segment's ends and both extreme
//   tails; interpolation <= ~1.3e-5 plus the final rounding to 2^-16); the
//   unit test asserts <= 2.5e-5, for all |z|, not only |z| < 4.
//   Tail: |Sample| <= 415364 = 6.33795 * 65536, the quantile of 2^-33 (u = 0
//   or ~0); the table covers the whole range, so no clamp is needed.
class GaussianTable {
 public:
  static constexpr int kSegments = 32;
  static constexpr int kIndexBits = 6;
  static constexpr int kInterpBits = 30 - kIndexBits;              // bits below the index
  static constexpr int kEntryFracBits = 24;                        // entries are Q7.24
  static constexpr size_t kIntervals = size_t{1} << kIndexBits;  // per segment
  static constexpr size_t kEntries = 2 * kSegments * kIntervals;  // 4096: (start, end) pairs

  // Fills storage[0 .. kEntries) (caller-owned, configure time; uses
  // detmath::InvNormalCdf) and keeps a pointer to it.
  [[nodiscard]] Status Build(Span<int32_t> storage);
  // The same from a built table's entries (a copy: the table is a constant).
  [[nodiscard]] Status CopyFrom(const GaussianTable& built, Span<int32_t> storage);
  bool built() const { return table_ != nullptr; }

  // Per pixel: integers only, no loops. Requires a successful Build().
  int32_t Sample(uint32_t u) const {
    const uint32_t upper = 0u - (u >> 31);         // all ones for the upper half
    const uint32_t v = (u ^ upper) & 0x7FFFFFFFu;  // buckets from the nearer end
    // segment = countl_zero(v) - 1, 0..31 (v == 0 gives 31), computed on an
    // argument that is never 0 so that no compiler needs a branch for 0.
    const int segment = std::countl_zero((v << 1) | 1u);
    const uint32_t w = v << segment;               // leading one at bit 30
    const int32_t* node = table_ + 2 * (static_cast<size_t>(segment) * kIntervals +
                                        ((w >> kInterpBits) & ((1u << kIndexBits) - 1)));
    const int64_t frac = w & ((1u << kInterpBits) - 1);
    const int64_t mag = (static_cast<int64_t>(node[0]) << kInterpBits) +
                        static_cast<int64_t>(node[1] - node[0]) * frac;  // Q(24+24)
    const int32_t z = static_cast<int32_t>(RoundShift(mag, kInterpBits + kEntryFracBits - 16));
    const int32_t negate = static_cast<int32_t>(~upper);  // -1 for the lower half
    return (z ^ negate) - negate;
  }

  // z[i] = Sample(u[i]) for i < n: the same bits, sixteen (AVX-512) or eight
  // (AVX2) words at a time where the CPU has them (random.cc), one by one elsewhere.
  void SampleLanes(const uint32_t* u, int32_t* z, int n) const;

 private:
  const int32_t* table_ = nullptr;
  bool avx2_ = false;    // SampleLanes' kernels, chosen at Build
  bool avx512_ = false;
};

// floor(n / d) for n < 2^57 and 1 <= d <= 64, exactly, without a division
// where the compiler has a 64x64->128-bit multiply (x86-64, aarch64):
// n * c / 2^63 with c = ceil(2^63 / d). Proof: c d = 2^63 + e with 0 <= e < d,
// so n c / 2^63 = n / d + n e / (d 2^63), and n e < 2^57 * 2^6 = 2^63 makes
// the excess smaller than 1 / d; as the fractional part of n / d is at most
// (d - 1) / d, the floor is unchanged. Elsewhere (32-bit targets) a plain
// division, which gives the same result.
namespace random_detail {
struct Reciprocals {
  uint64_t v[64] = {};  // v[d - 1] = ceil(2^63 / d)
};
constexpr Reciprocals MakeReciprocals() {
  Reciprocals r;
  for (uint64_t d = 1; d <= 64; ++d) r.v[d - 1] = ((uint64_t{1} << 63) + d - 1) / d;
  return r;
}
inline constexpr Reciprocals kReciprocals = MakeReciprocals();
}  // namespace random_detail

constexpr uint64_t DivideSmall(uint64_t n, uint32_t d) {
#if defined(__SIZEOF_INT128__)
  __extension__ typedef unsigned __int128 U128;
  return static_cast<uint64_t>((static_cast<U128>(n) * random_detail::kReciprocals.v[d - 1]) >> 63);
#else
  return n / d;
#endif
}

// Poisson variate with mean lambda = lambda_q8 / 256, in whole counts.
//
// lambda < 12 (lambda_q8 < kSmallQ8): exact inverse transform on u: returns
// the smallest k with u < 2^32 * CDF(k), where p_0 comes from the table and
// p_k = p_{k-1} * lambda / k in 64-bit integers (rounded, ties up). Each
// entry stores exp(-lambda) * 2^(32 + n) with n = (lambda_q8 * 369) >> 16
// (<= lambda * log2(e)), i.e. Q0.32 with an exponent implied by lambda_q8, so
// p_0 keeps >= 31 significant bits even at lambda = 12 (exp(-12) ~ 2^-17.3).
// u is compared scaled by the same 2^n. The loop stops once p_k rounds to 0
// (k <= 43 for every lambda_q8 and u) and is capped at kMaxSmallCount anyway.
// lambda = 0 always gives 0.
//
// lambda >= 12: normal approximation with Cornish-Fisher skew correction,
//   n = lambda + sigma * z + (z^2 - 1) / 6,  sigma = sqrt(lambda - 5/36),
// in Q32 integers (ISqrt64 for sigma), rounded (ties up), clamped at 0 and
// saturated at UINT32_MAX. Using lambda - 5/36 instead of lambda under the
// root removes the variance added by the skew term (1/18) and by rounding to
// an integer (1/12), so Var(n) = lambda to O(1/lambda). z_q16 is a
// GaussianTable::Sample() of bits independent of u; any int32 is safe.
class PoissonTable {
 public:
  static constexpr uint32_t kSmallQ8 = 12 * 256;
  static constexpr size_t kEntries = kSmallQ8;  // 3072 uint32 = 12288 bytes
  static constexpr uint32_t kMaxSmallCount = 64;
  static constexpr uint64_t kVarianceCorrection = 596523236;  // round(5/36 * 2^32)

  // Fills storage[0 .. kEntries) (caller-owned, configure time; uses
  // detmath::Exp) and keeps a pointer to it.
  [[nodiscard]] Status Build(Span<uint32_t> storage);
  // The same from a built table's entries (a copy: the table is a constant).
  [[nodiscard]] Status CopyFrom(const PoissonTable& built, Span<uint32_t> storage);
  bool built() const { return table_ != nullptr; }

  // Per pixel: integers only, bounded time, defined for every input.
  // Requires a successful Build().
  uint32_t Sample(uint32_t lambda_q8, uint32_t u, int32_t z_q16) const {
    return Sample(lambda_q8, u, z_q16, lambda_q8 < kSmallQ8 ? 0 : Sigma(lambda_q8));
  }
  // The same draw with sigma = Sigma(lambda_q8) computed beforehand (only
  // read when lambda_q8 >= kSmallQ8), e.g. for a block by SigmaLanes.
  uint32_t Sample(uint32_t lambda_q8, uint32_t u, int32_t z_q16, uint32_t sigma_q16) const {
    return lambda_q8 < kSmallQ8 ? SampleSmall(lambda_q8, u) : SampleLarge(lambda_q8, z_q16, sigma_q16);
  }
  // The normal approximation's sigma = sqrt(lambda - 5/36), Q16 (< 2^28).
  // Defined for every input; meaningful for lambda_q8 >= kSmallQ8.
  static uint32_t Sigma(uint32_t lambda_q8) {
    return ISqrt64((static_cast<uint64_t>(lambda_q8) << 24) - kVarianceCorrection);
  }
  // sigma_q16[i] = Sigma(lambda_q8[i]) for i < n, in SIMD lanes (ISqrt64Lanes).
  static void SigmaLanes(const uint32_t* lambda_q8, uint32_t* sigma_q16, int n);
  // count[i] = Sample(lambda_q8[i], u[i], any z) for i < n where every
  // lambda_q8[i] < kSmallQ8 (the exact inverse transform): the same integers,
  // 32 at a time in AVX-512 or sixteen in AVX2 lanes where the CPU has them (random.cc).
  void SampleSmallLanes(const uint32_t* lambda_q8, const uint32_t* u, uint32_t* count, int n) const;

 private:
  uint32_t SampleSmall(uint32_t lambda_q8, uint32_t u) const {
    const uint32_t n = (lambda_q8 * 369u) >> 16;
    const uint64_t target = static_cast<uint64_t>(u) << n;
    uint64_t p = table_[lambda_q8];  // < 2^49 throughout; p * lambda_q8 < 2^61
    uint64_t cdf = p;
    uint32_t k = 0;
    while (target >= cdf && k < kMaxSmallCount) {
      // p = round(p * lambda_q8 / (256 (k + 1))), ties up, as
      // floor((p * lambda_q8 + 128 (k + 1)) / 256 / (k + 1)): the same value
      // (floor(floor(a / b) / c) == floor(a / (b c))), dividend < 2^53.
      const uint32_t m = k + 1;
      p = DivideSmall((p * lambda_q8 + 128u * m) >> 8, m);
      if (p == 0) break;
      ++k;
      cdf += p;
    }
    return k;
  }

  static uint32_t SampleLarge(uint32_t lambda_q8, int32_t z_q16, uint32_t sigma_q16) {
    const uint64_t lambda = static_cast<uint64_t>(lambda_q8) << 24;  // Q32, < 2^56
    const int64_t sigma = sigma_q16;                                 // Q16, < 2^28
    const int64_t z = z_q16;
    const int64_t n =
        static_cast<int64_t>(lambda) + sigma * z + (z * z - (int64_t{1} << 32)) / 6;  // Q32
    return SatU32(RoundShift(n, 32));
  }

  const uint32_t* table_ = nullptr;
  bool avx2_ = false;  // SampleSmallLanes' kernels, chosen at Build
  bool avx512_ = false;
};

}  // namespace camsim
