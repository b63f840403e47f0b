#include "core/base/random.h"

#include <cstring>

#include "core/base/detmath.h"
#include "core/base/simd.h"

namespace camsim {
namespace {

// The key of each Philox round under StreamKey(seed, stream), as
// Philox4x32::Generate bumps it: round r uses key + r (kW0, kW1).
struct RoundKeys {
  uint32_t k0[Philox4x32::kRounds], k1[Philox4x32::kRounds];
};
RoundKeys MakeRoundKeys(uint64_t seed, uint32_t stream) {
  uint32_t key[2];
  StreamKey(seed, stream, key);
  RoundKeys keys;
  for (int round = 0; round < Philox4x32::kRounds; ++round) {
    keys.k0[round] = key[0] + static_cast<uint32_t>(round) * Philox4x32::kW0;
    keys.k1[round] = key[1] + static_cast<uint32_t>(round) * Philox4x32::kW1;
  }
  return keys;
}

#ifdef CAMSIM_X86_AVX2
// The high and low 32 bits of m * c for eight unsigned lanes: vpmuludq
// multiplies the even lanes, so the odd ones are shifted down first.
CAMSIM_AVX2_TARGET inline void MulHiLo(__m256i c, __m256i m, __m256i* hi, __m256i* lo) {
  const __m256i even = _mm256_mul_epu32(c, m);                         // lanes 0, 2, 4, 6 as 64 bits
  const __m256i odd = _mm256_mul_epu32(_mm256_srli_epi64(c, 32), m);  // lanes 1, 3, 5, 7
  *hi = _mm256_blend_epi32(_mm256_srli_epi64(even, 32), odd, 0xAA);
  *lo = _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
}

// DrawBitsLanes in AVX2: the same rounds, eight lanes per register.
CAMSIM_AVX2_TARGET void DrawBitsLanesAvx2(uint64_t seed, uint32_t stream, uint32_t frame, uint32_t x0, uint32_t y,
                                          uint32_t draw, RandomLanes* out) {
  static_assert(RandomLanes::kLanes == 16, "two registers of eight lanes");
  const __m256i m0 = _mm256_set1_epi32(static_cast<int>(Philox4x32::kM0));
  const __m256i m1 = _mm256_set1_epi32(static_cast<int>(Philox4x32::kM1));
  const __m256i step = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256i c0[2], c1[2], c2[2], c3[2];
  for (int h = 0; h < 2; ++h) {
    c0[h] = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(x0 + 8u * static_cast<uint32_t>(h))), step);
    c1[h] = _mm256_set1_epi32(static_cast<int>(y));
    c2[h] = _mm256_set1_epi32(static_cast<int>(frame));
    c3[h] = _mm256_set1_epi32(static_cast<int>(draw));
  }
  const RoundKeys keys = MakeRoundKeys(seed, stream);
  for (int round = 0; round < Philox4x32::kRounds; ++round) {
    const uint32_t k0 = keys.k0[round], k1 = keys.k1[round];
    const __m256i vk0 = _mm256_set1_epi32(static_cast<int>(k0));
    const __m256i vk1 = _mm256_set1_epi32(static_cast<int>(k1));
    for (int h = 0; h < 2; ++h) {
      __m256i hi0, lo0, hi1, lo1;
      MulHiLo(c0[h], m0, &hi0, &lo0);
      MulHiLo(c2[h], m1, &hi1, &lo1);
      c0[h] = _mm256_xor_si256(_mm256_xor_si256(hi1, c1[h]), vk0);
      c2[h] = _mm256_xor_si256(_mm256_xor_si256(hi0, c3[h]), vk1);
      c1[h] = lo1;
      c3[h] = lo0;
    }
  }
  for (int h = 0; h < 2; ++h) {
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&out->v[0][8 * h]), c0[h]);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&out->v[1][8 * h]), c1[h]);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&out->v[2][8 * h]), c2[h]);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&out->v[3][8 * h]), c3[h]);
  }
}

// GaussianTable::Sample for eight words, step by step the same integers:
//   segment = countl_zero((v << 1) | 1): from the exponent of float(v & ~(v >> 1)),
//     exact because clearing the bit below the leading one keeps the value
//     under 1.5 * 2^e, so rounding to 24 bits cannot reach 2^(e + 1); v = 0
//     (exponent field 0) gives 157, clamped to 31;
//   mag = node0 * 2^24 + (node1 - node0) * frac in 64-bit lanes (even and odd
//     lanes apart: vpmuldq), >= 0 (|z| interpolated between two magnitudes),
//     so RoundShift(mag, 32) is the high half of mag + 2^31.
CAMSIM_AVX2_TARGET __m256i GaussianAvx2(const int32_t* table, __m256i u) {
  constexpr int kIndexBits = GaussianTable::kIndexBits;
  constexpr int kInterpBits = GaussianTable::kInterpBits;
  static_assert(kInterpBits + GaussianTable::kEntryFracBits - 16 == 32, "the rounding is to the high half");
  const __m256i upper = _mm256_srai_epi32(u, 31);
  const __m256i v = _mm256_and_si256(_mm256_xor_si256(u, upper), _mm256_set1_epi32(0x7FFFFFFF));
  const __m256i lead = _mm256_andnot_si256(_mm256_srli_epi32(v, 1), v);
  const __m256i exponent = _mm256_srli_epi32(_mm256_castps_si256(_mm256_cvtepi32_ps(lead)), 23);
  const __m256i segment = _mm256_min_epu32(_mm256_sub_epi32(_mm256_set1_epi32(157), exponent), _mm256_set1_epi32(31));
  const __m256i w = _mm256_sllv_epi32(v, segment);
  const __m256i interval = _mm256_or_si256(  // segment * kIntervals + the 6 index bits
      _mm256_slli_epi32(segment, kIndexBits),
      _mm256_and_si256(_mm256_srli_epi32(w, kInterpBits), _mm256_set1_epi32((1 << kIndexBits) - 1)));
  // One 64-bit gather of (start, end) pairs for the even lanes, one for the odd.
  const long long* pairs = reinterpret_cast<const long long*>(table);
  const __m256i even = _mm256_i32gather_epi64(
      pairs, _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(interval, _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6))), 8);
  const __m256i odd = _mm256_i32gather_epi64(
      pairs, _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(interval, _mm256_setr_epi32(1, 3, 5, 7, 1, 3, 5, 7))), 8);
  const __m256i frac = _mm256_and_si256(w, _mm256_set1_epi32((1 << kInterpBits) - 1));
  const __m256i half = _mm256_set1_epi64x(int64_t{1} << 31);
  const __m256i low32 = _mm256_set1_epi64x(0xFFFFFFFF);
  // start >= 0 in the low half, end - start in the low half of its own lane.
  const __m256i mag_even = _mm256_add_epi64(_mm256_slli_epi64(_mm256_and_si256(even, low32), kInterpBits),
                                            _mm256_mul_epi32(_mm256_sub_epi32(_mm256_srli_epi64(even, 32), even), frac));
  const __m256i mag_odd = _mm256_add_epi64(_mm256_slli_epi64(_mm256_and_si256(odd, low32), kInterpBits),
                                           _mm256_mul_epi32(_mm256_sub_epi32(_mm256_srli_epi64(odd, 32), odd),
                                                            _mm256_srli_epi64(frac, 32)));
  const __m256i z = _mm256_blend_epi32(_mm256_srli_epi64(_mm256_add_epi64(mag_even, half), 32),
                                       _mm256_add_epi64(mag_odd, half), 0xAA);
  const __m256i negate = _mm256_xor_si256(upper, _mm256_set1_epi32(-1));
  return _mm256_sub_epi32(_mm256_xor_si256(z, negate), negate);
}

CAMSIM_AVX2_TARGET void GaussianLanesAvx2(const int32_t* table, const uint32_t* u, int32_t* z, int n) {
  for (int i = 0; i < n; i += 8)
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(z + i),
                        GaussianAvx2(table, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(u + i))));
}
#endif

#ifdef CAMSIM_X86_AVX512
// DrawBitsLanesAvx2 with all sixteen lanes in one register.
CAMSIM_AVX512_TARGET void DrawBitsLanesAvx512(uint64_t seed, uint32_t stream, uint32_t frame, uint32_t x0,
                                              uint32_t y, uint32_t draw, RandomLanes* out) {
  static_assert(RandomLanes::kLanes == 16, "one register of sixteen lanes");
  const __m512i m0 = _mm512_set1_epi32(static_cast<int>(Philox4x32::kM0));
  const __m512i m1 = _mm512_set1_epi32(static_cast<int>(Philox4x32::kM1));
  constexpr __mmask16 kOdd = 0xAAAA;
  __m512i c0 = _mm512_add_epi32(_mm512_set1_epi32(static_cast<int>(x0)),
                                _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15));
  __m512i c1 = _mm512_set1_epi32(static_cast<int>(y));
  __m512i c2 = _mm512_set1_epi32(static_cast<int>(frame));
  __m512i c3 = _mm512_set1_epi32(static_cast<int>(draw));
  const RoundKeys keys = MakeRoundKeys(seed, stream);
  for (int round = 0; round < Philox4x32::kRounds; ++round) {
    const uint32_t k0 = keys.k0[round], k1 = keys.k1[round];
    // The high and low halves of c * m: vpmuludq multiplies the even lanes
    // (it reads only the low dword of each 64-bit lane, so the odd lanes go
    // in by a dword copy). The halves are moved by dword shuffles, not 64-bit
    // shifts and blends: shuffles issue on port 5, while the shifts shared
    // port 0 with the multiplies, the loop's bottleneck on AVX-512 cores.
    constexpr _MM_PERM_ENUM kHigh = _MM_PERM_DDBB, kLow = _MM_PERM_CCAA;  // dwords 1 1 3 3, 0 0 2 2 of each 128 bits
    constexpr __mmask16 kEven = static_cast<__mmask16>(~kOdd);
    const __m512i even0 = _mm512_mul_epu32(c0, m0), odd0 = _mm512_mul_epu32(_mm512_shuffle_epi32(c0, kHigh), m0);
    const __m512i even1 = _mm512_mul_epu32(c2, m1), odd1 = _mm512_mul_epu32(_mm512_shuffle_epi32(c2, kHigh), m1);
    const __m512i hi0 = _mm512_mask_shuffle_epi32(odd0, kEven, even0, kHigh);
    const __m512i hi1 = _mm512_mask_shuffle_epi32(odd1, kEven, even1, kHigh);
    const __m512i lo0 = _mm512_mask_shuffle_epi32(even0, kOdd, odd0, kLow);
    const __m512i lo1 = _mm512_mask_shuffle_epi32(even1, kOdd, odd1, kLow);
    c0 = _mm512_xor_si512(_mm512_xor_si512(hi1, c1), _mm512_set1_epi32(static_cast<int>(k0)));
    c2 = _mm512_xor_si512(_mm512_xor_si512(hi0, c3), _mm512_set1_epi32(static_cast<int>(k1)));
    c1 = lo1;
    c3 = lo0;
  }
  _mm512_storeu_si512(out->v[0], c0);
  _mm512_storeu_si512(out->v[1], c1);
  _mm512_storeu_si512(out->v[2], c2);
  _mm512_storeu_si512(out->v[3], c3);
}

// GaussianAvx2 for sixteen words: the segment from AVX-512's count of
// leading zeros, then the even and the odd lanes each gather their (start,
// end) pairs and interpolate in 64-bit lanes, as in GaussianAvx2. The lanes'
// dwords are moved by shuffles (port 5) rather than 64-bit shifts, which
// share port 0 with the multiplies.
CAMSIM_AVX512_TARGET __m512i GaussianAvx512(const int32_t* table, __m512i u) {
  constexpr int kIndexBits = GaussianTable::kIndexBits;
  constexpr int kInterpBits = GaussianTable::kInterpBits;
  static_assert(kInterpBits + GaussianTable::kEntryFracBits - 16 == 32, "the rounding is to the high half");
  constexpr __mmask16 kEven = 0x5555;
  const __m512i upper = _mm512_srai_epi32(u, 31);
  const __m512i v = _mm512_and_si512(_mm512_xor_si512(u, upper), _mm512_set1_epi32(0x7FFFFFFF));
  const __m512i segment = _mm512_lzcnt_epi32(_mm512_or_si512(_mm512_slli_epi32(v, 1), _mm512_set1_epi32(1)));
  const __m512i w = _mm512_sllv_epi32(v, segment);
  const __m512i interval = _mm512_or_si512(
      _mm512_slli_epi32(segment, kIndexBits),
      _mm512_and_si512(_mm512_srli_epi32(w, kInterpBits), _mm512_set1_epi32((1 << kIndexBits) - 1)));
  const __m512i frac = _mm512_and_si512(w, _mm512_set1_epi32((1 << kInterpBits) - 1));
  const __m512i half = _mm512_set1_epi64(int64_t{1} << 31);
  const __m512i low32 = _mm512_set1_epi64(0xFFFFFFFF);
  __m512i rounded[2];  // even, odd lanes: the result in the high dword of each 64-bit lane
  for (int odd = 0; odd < 2; ++odd) {
    // The lanes' intervals and fractions in the low dwords (vpmuludq and
    // vpmuldq read only those), the intervals zero-extended as gather indices.
    const __m512i index = odd == 0 ? _mm512_and_si512(interval, low32)
                                   : _mm512_maskz_shuffle_epi32(kEven, interval, _MM_PERM_DDBB);
    const __m512i f = odd == 0 ? frac : _mm512_shuffle_epi32(frac, _MM_PERM_DDBB);
    // A mask GCC cannot prove full: see ISqrt64x8 (fixed.cc).
    const __mmask8 all = _mm512_cmpge_epi64_mask(index, _mm512_setzero_si512());
    const __m512i pair = _mm512_mask_i64gather_epi64(_mm512_setzero_si512(), all, index, table, 8);
    const __m512i start = _mm512_and_si512(pair, low32);  // >= 0
    const __m512i span = _mm512_sub_epi32(_mm512_shuffle_epi32(pair, _MM_PERM_DDBB), pair);  // low dword: end - start
    const __m512i mag = _mm512_add_epi64(_mm512_slli_epi64(start, kInterpBits), _mm512_mul_epi32(span, f));
    rounded[odd] = _mm512_add_epi64(mag, half);
  }
  const __m512i zz = _mm512_mask_shuffle_epi32(rounded[1], kEven, rounded[0], _MM_PERM_DDBB);
  const __m512i negate = _mm512_xor_si512(upper, _mm512_set1_epi32(-1));
  return _mm512_sub_epi32(_mm512_xor_si512(zz, negate), negate);
}

CAMSIM_AVX512_TARGET void GaussianLanesAvx512(const int32_t* table, const uint32_t* u, int32_t* z, int n) {
  for (int i = 0; i < n; i += 16) _mm512_storeu_si512(z + i, GaussianAvx512(table, _mm512_loadu_si512(u + i)));
}
#endif

}  // namespace

void GaussianTable::SampleLanes(const uint32_t* u, int32_t* z, int n) const {
  int i = 0;
#ifdef CAMSIM_X86_AVX512
  if (avx512_) {
    i = n & ~15;
    GaussianLanesAvx512(table_, u, z, i);
  } else
#endif
#ifdef CAMSIM_X86_AVX2
  if (avx2_) {
    i = n & ~7;
    GaussianLanesAvx2(table_, u, z, i);
  }
#endif
  for (; i < n; ++i) z[i] = Sample(u[i]);
}

void DrawBitsLanes(uint64_t seed, uint32_t stream, uint32_t frame, uint32_t x0, uint32_t y, uint32_t draw,
                   RandomLanes* out) {
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512()) return DrawBitsLanesAvx512(seed, stream, frame, x0, y, draw, out);
#endif
#ifdef CAMSIM_X86_AVX2
  if (CpuHasAvx2()) return DrawBitsLanesAvx2(seed, stream, frame, x0, y, draw, out);
#endif
  constexpr int kLanes = RandomLanes::kLanes;
  uint32_t c0[kLanes], c1[kLanes], c2[kLanes], c3[kLanes];  // the counters, {x, y, frame, draw}
  for (int i = 0; i < kLanes; ++i) {
    c0[i] = x0 + static_cast<uint32_t>(i);
    c1[i] = y;
    c2[i] = frame;
    c3[i] = draw;
  }
  const RoundKeys keys = MakeRoundKeys(seed, stream);
  for (int round = 0; round < Philox4x32::kRounds; ++round) {  // Philox4x32::Generate, lane by lane
    const uint32_t k0 = keys.k0[round], k1 = keys.k1[round];
    // Kept a loop: fully unrolled, GCC no longer vectorises it (~20 % slower).
#pragma GCC unroll 1
    for (int i = 0; i < kLanes; ++i) {
      const uint64_t p0 = static_cast<uint64_t>(Philox4x32::kM0) * c0[i];
      const uint64_t p1 = static_cast<uint64_t>(Philox4x32::kM1) * c2[i];
      const uint32_t n0 = static_cast<uint32_t>(p1 >> 32) ^ c1[i] ^ k0;
      const uint32_t n2 = static_cast<uint32_t>(p0 >> 32) ^ c3[i] ^ k1;
      c1[i] = static_cast<uint32_t>(p1);
      c3[i] = static_cast<uint32_t>(p0);
      c0[i] = n0;
      c2[i] = n2;
    }
  }
  for (int i = 0; i < kLanes; ++i) {
    out->v[0][i] = c0[i];
    out->v[1][i] = c1[i];
    out->v[2][i] = c2[i];
    out->v[3][i] = c3[i];
  }
}

Status GaussianTable::Build(Span<int32_t> storage) {
  if (storage.data == nullptr || storage.size < kEntries) {
    return Status(StatusCode::kResourceExhausted, "gaussian table needs kEntries int32", "storage");
  }
  double scale = 1.0;  // 2^-segment
  for (int segment = 0; segment < kSegments; ++segment, scale *= 0.5) {
    for (size_t i = 0; i <= kIntervals; ++i) {
      // Interval end i of the segment as a (possibly fractional) v, exact;
      // the last segment holds v = 0 alone. It ends interval i - 1 and starts i.
      const double v =
          segment == kSegments - 1 ? 0.0 : (0x1p30 + static_cast<double>(i) * 0x1p24) * scale;
      const double z = -detmath::InvNormalCdf((v + 0.5) * 0x1p-32);
      const int32_t raw = Q<7, kEntryFracBits, true>::FromDouble(z).raw;
      const size_t pair = 2 * (static_cast<size_t>(segment) * kIntervals + i);
      if (i > 0) storage[pair - 1] = raw;
      if (i < kIntervals) storage[pair] = raw;
    }
  }
  table_ = storage.data;
  avx2_ = CpuHasAvx2();
  avx512_ = CpuHasAvx512();
  return Status::Ok();
}

Status GaussianTable::CopyFrom(const GaussianTable& built, Span<int32_t> storage) {
  if (storage.data == nullptr || storage.size < kEntries || !built.built())
    return Status(StatusCode::kResourceExhausted, "gaussian table needs kEntries int32 and a built table", "storage");
  std::memcpy(storage.data, built.table_, kEntries * sizeof(int32_t));
  *this = built;
  table_ = storage.data;
  return Status::Ok();
}

void PoissonTable::SigmaLanes(const uint32_t* lambda_q8, uint32_t* sigma_q16, int n) {
  constexpr int kChunk = 64;
  uint64_t x[kChunk];
  for (int i0 = 0; i0 < n; i0 += kChunk) {
    const int m = n - i0 < kChunk ? n - i0 : kChunk;
    for (int i = 0; i < m; ++i) x[i] = (static_cast<uint64_t>(lambda_q8[i0 + i]) << 24) - kVarianceCorrection;
    ISqrt64Lanes(x, sigma_q16 + i0, m);
  }
}

#ifdef CAMSIM_X86_AVX2
namespace {
// DivideSmall(n, d) for n < 2^53 in four 64-bit lanes, r = kReciprocals[d - 1]
// = rh 2^32 + rl (rh <= 2^31): the 128-bit product's bits from 63 up are
// 2 nh rh + floor(t / 2^31) with t = nh rl + nl rh + floor(nl rl / 2^32)
// (n = nh 2^32 + nl, nh < 2^21); t < 2^53 + 2^63 + 2^32 fits 64 bits.
CAMSIM_AVX2_TARGET inline __m256i DivideSmall4(__m256i n, uint64_t r) {
  const __m256i rl = _mm256_set1_epi64x(static_cast<int64_t>(r & 0xFFFFFFFFu));
  const __m256i rh = _mm256_set1_epi64x(static_cast<int64_t>(r >> 32));
  const __m256i nh = _mm256_srli_epi64(n, 32);
  const __m256i t = _mm256_add_epi64(_mm256_add_epi64(_mm256_mul_epu32(nh, rl), _mm256_mul_epu32(n, rh)),
                                     _mm256_srli_epi64(_mm256_mul_epu32(n, rl), 32));
  return _mm256_add_epi64(_mm256_slli_epi64(_mm256_mul_epu32(nh, rh), 1), _mm256_srli_epi64(t, 31));
}

// SampleSmall's search for four pixels. Their loops run in lockstep: a lane
// still searching at step m has k = m - 1, so the divisor m is the same for
// all of them; a lane stops where SampleSmall would (target < cdf, p rounding
// to 0; the kMaxSmallCount cap is never reached, as k <= 43) and keeps its
// k. Bounds as there: p < 2^49 and lambda_q8 < 2^12, so
// p * lambda_q8 (two vpmuludq; p's high half is < 2^17) < 2^61 and the
// quotient's dividend < 2^53; cdf and target stay below 2^62, so signed
// compares order them.
struct SmallSearch {
  __m256i lambda, target, p, cdf, k, searching;
};

CAMSIM_AVX2_TARGET inline void StartSmall(const uint32_t* table, const uint32_t* lambda_q8, const uint32_t* u,
                                          SmallSearch* s) {
  s->lambda = avx2::LoadU32x4(lambda_q8);
  const __m256i n = _mm256_srli_epi64(_mm256_mul_epu32(s->lambda, _mm256_set1_epi64x(369)), 16);
  s->target = _mm256_sllv_epi64(avx2::LoadU32x4(u), n);
  s->p = _mm256_cvtepu32_epi64(_mm256_i64gather_epi32(reinterpret_cast<const int*>(table), s->lambda, 4));
  s->cdf = s->p;
  s->k = _mm256_setzero_si256();
  s->searching = _mm256_xor_si256(_mm256_cmpgt_epi64(s->cdf, s->target), _mm256_set1_epi64x(-1));
}

CAMSIM_AVX2_TARGET inline void StepSmall(uint32_t m, SmallSearch* s) {
  const __m256i product = _mm256_add_epi64(
      _mm256_mul_epu32(s->p, s->lambda), _mm256_slli_epi64(_mm256_mul_epu32(_mm256_srli_epi64(s->p, 32), s->lambda), 32));
  const __m256i next = DivideSmall4(_mm256_srli_epi64(_mm256_add_epi64(product, _mm256_set1_epi64x(128 * m)), 8),
                                    random_detail::kReciprocals.v[m - 1]);
  const __m256i step = _mm256_andnot_si256(_mm256_cmpeq_epi64(next, _mm256_setzero_si256()), s->searching);
  s->p = _mm256_blendv_epi8(s->p, next, step);
  s->k = _mm256_sub_epi64(s->k, step);  // + 1 where stepping
  s->cdf = _mm256_add_epi64(s->cdf, _mm256_and_si256(next, step));
  s->searching = _mm256_andnot_si256(_mm256_cmpgt_epi64(s->cdf, s->target), step);
}

// kGroups x 4 pixels a step as independent searches, so that one's chain of
// multiplies runs while another's waits (four: 52 -> 44 ms for a dark 1080p
// frame's sensor stage against two); n a multiple of kPixelsPerStep.
constexpr int kGroups = 4;
constexpr int kPixelsPerStep = 4 * kGroups;
CAMSIM_AVX2_TARGET void SampleSmallLanesAvx2(const uint32_t* table, const uint32_t* lambda_q8, const uint32_t* u,
                                             uint32_t* count, int n) {
  for (int i = 0; i < n; i += kPixelsPerStep) {
    SmallSearch s[kGroups];
    for (int g = 0; g < kGroups; ++g) StartSmall(table, lambda_q8 + i + 4 * g, u + i + 4 * g, &s[g]);
    for (uint32_t m = 1; m <= PoissonTable::kMaxSmallCount; ++m) {
      __m256i any = s[0].searching;
      for (int g = 1; g < kGroups; ++g) any = _mm256_or_si256(any, s[g].searching);
      if (_mm256_testz_si256(any, any)) break;
      for (int g = 0; g < kGroups; ++g) StepSmall(m, &s[g]);
    }
    for (int g = 0; g < kGroups; ++g) avx2::StoreLow32x4(s[g].k, count + i + 4 * g);
  }
}

#ifdef CAMSIM_X86_AVX512
// The same searches in eight lanes, with AVX-512's masks for the lanes still
// searching; the same integers step for step. kGroups x 8 = 32 pixels a
// step, a sensor block's small pixels in one (two groups measured slower).
// Dark 1080p sensor stage on an Intel Xeon VM: BM_SensorLowLight/100 46.3
// -> 40.5 ms, /1000 41.1 -> 35.7 ms.
constexpr int kPixelsPerStepAvx512 = 8 * kGroups;
struct SmallSearch8 {
  __m512i lambda, target, p, cdf, k;
  __mmask8 searching;
};

// DivideSmall4 in eight lanes.
CAMSIM_AVX512_TARGET inline __m512i DivideSmall8(__m512i n, uint64_t r) {
  const __m512i rl = _mm512_set1_epi64(static_cast<int64_t>(r & 0xFFFFFFFFu));
  const __m512i rh = _mm512_set1_epi64(static_cast<int64_t>(r >> 32));
  const __m512i nh = _mm512_srli_epi64(n, 32);
  const __m512i t = _mm512_add_epi64(_mm512_add_epi64(_mm512_mul_epu32(nh, rl), _mm512_mul_epu32(n, rh)),
                                     _mm512_srli_epi64(_mm512_mul_epu32(n, rl), 32));
  return _mm512_add_epi64(_mm512_slli_epi64(_mm512_mul_epu32(nh, rh), 1), _mm512_srli_epi64(t, 31));
}

CAMSIM_AVX512_TARGET inline void StartSmall8(const uint32_t* table, const uint32_t* lambda_q8, const uint32_t* u,
                                             SmallSearch8* s) {
  s->lambda = _mm512_cvtepu32_epi64(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(lambda_q8)));
  const __m512i n = _mm512_srli_epi64(_mm512_mul_epu32(s->lambda, _mm512_set1_epi64(369)), 16);
  s->target = _mm512_sllv_epi64(_mm512_cvtepu32_epi64(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(u))), n);
  // A mask GCC cannot prove full: see ISqrt64x8 (fixed.cc).
  const __mmask8 all = _mm512_cmpge_epi64_mask(s->lambda, _mm512_setzero_si512());
  s->p = _mm512_cvtepu32_epi64(_mm512_mask_i64gather_epi32(_mm256_setzero_si256(), all, s->lambda, table, 4));
  s->cdf = s->p;
  s->k = _mm512_setzero_si512();
  s->searching = _mm512_cmple_epi64_mask(s->cdf, s->target);
}

CAMSIM_AVX512_TARGET inline void StepSmall8(uint32_t m, SmallSearch8* s) {
  const __m512i p_high = _mm512_mul_epu32(_mm512_srli_epi64(s->p, 32), s->lambda);
  const __m512i product = _mm512_add_epi64(_mm512_mul_epu32(s->p, s->lambda), _mm512_slli_epi64(p_high, 32));
  const __m512i next = DivideSmall8(_mm512_srli_epi64(_mm512_add_epi64(product, _mm512_set1_epi64(128 * m)), 8),
                                    random_detail::kReciprocals.v[m - 1]);
  const __mmask8 step = _mm512_mask_test_epi64_mask(s->searching, next, next);
  s->p = _mm512_mask_mov_epi64(s->p, step, next);
  s->k = _mm512_mask_add_epi64(s->k, step, s->k, _mm512_set1_epi64(1));
  s->cdf = _mm512_mask_add_epi64(s->cdf, step, s->cdf, next);
  s->searching = _mm512_mask_cmple_epi64_mask(step, s->cdf, s->target);
}

CAMSIM_AVX512_TARGET void SampleSmallLanesAvx512(const uint32_t* table, const uint32_t* lambda_q8, const uint32_t* u,
                                                 uint32_t* count, int n) {
  for (int i = 0; i < n; i += kPixelsPerStepAvx512) {
    SmallSearch8 s[kGroups];
    for (int g = 0; g < kGroups; ++g) StartSmall8(table, lambda_q8 + i + 8 * g, u + i + 8 * g, &s[g]);
    for (uint32_t m = 1; m <= PoissonTable::kMaxSmallCount; ++m) {
      __mmask8 any = s[0].searching;
      for (int g = 1; g < kGroups; ++g) any |= s[g].searching;
      if (any == 0) break;
      for (int g = 0; g < kGroups; ++g) StepSmall8(m, &s[g]);
    }
    for (int g = 0; g < kGroups; ++g)
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(count + i + 8 * g), _mm512_cvtepi64_epi32(s[g].k));
  }
}
#endif
}  // namespace
#endif

#ifdef CAMSIM_X86_AVX2
namespace {
// A lane kernel that takes kStep pixels a step over any n: the whole steps,
// then the rest padded with mean 0 (a search that ends at once).
template <int kStep>
void SmallInSteps(void (*kernel)(const uint32_t*, const uint32_t*, const uint32_t*, uint32_t*, int),
                  const uint32_t* table, const uint32_t* lambda_q8, const uint32_t* u, uint32_t* count, int n) {
  const int i = n - n % kStep;
  kernel(table, lambda_q8, u, count, i);
  if (i == n) return;
  uint32_t lambda_rest[kStep] = {}, u_rest[kStep] = {}, count_rest[kStep];
  for (int j = i; j < n; ++j) lambda_rest[j - i] = lambda_q8[j], u_rest[j - i] = u[j];
  kernel(table, lambda_rest, u_rest, count_rest, kStep);
  for (int j = i; j < n; ++j) count[j] = count_rest[j - i];
}
}  // namespace
#endif

void PoissonTable::SampleSmallLanes(const uint32_t* lambda_q8, const uint32_t* u, uint32_t* count, int n) const {
#ifdef CAMSIM_X86_AVX512
  if (avx512_) return SmallInSteps<kPixelsPerStepAvx512>(SampleSmallLanesAvx512, table_, lambda_q8, u, count, n);
#endif
#ifdef CAMSIM_X86_AVX2
  if (avx2_) return SmallInSteps<kPixelsPerStep>(SampleSmallLanesAvx2, table_, lambda_q8, u, count, n);
#endif
  for (int i = 0; i < n; ++i) count[i] = SampleSmall(lambda_q8[i], u[i]);
}

Status PoissonTable::Build(Span<uint32_t> storage) {
  if (storage.data == nullptr || storage.size < kEntries) {
    return Status(StatusCode::kResourceExhausted, "poisson table needs kEntries uint32", "storage");
  }
  for (uint32_t q = 0; q < kSmallQ8; ++q) {
    const uint32_t n = (q * 369u) >> 16;
    double scale = 0x1p32;  // 2^(32 + n), exact
    for (uint32_t i = 0; i < n; ++i) scale *= 2.0;
    const double p0 = detmath::Exp(-static_cast<double>(q) / 256.0) * scale;  // <= 2^32
    storage[q] = SatU32(static_cast<uint64_t>(p0 + 0.5));  // only q = 0 (p0 = 2^32) saturates
  }
  table_ = storage.data;
  avx2_ = CpuHasAvx2();
  avx512_ = CpuHasAvx512();
  return Status::Ok();
}

Status PoissonTable::CopyFrom(const PoissonTable& built, Span<uint32_t> storage) {
  if (storage.data == nullptr || storage.size < kEntries || !built.built())
    return Status(StatusCode::kResourceExhausted, "poisson table needs kEntries uint32 and a built table", "storage");
  std::memcpy(storage.data, built.table_, kEntries * sizeof(uint32_t));
  *this = built;
  table_ = storage.data;
  return Status::Ok();
}

}  // namespace camsim
