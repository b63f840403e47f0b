#include "core/base/fixed.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

#ifdef CAMSIM_X86_AVX2
// One step of ISqrt64's normalisation: where the top S bits of xn are 0,
// shift it left by S (S even) and add S to the shift.
template <int S>
CAMSIM_AVX2_TARGET inline void NormaliseStep(__m256i* xn, __m256i* shift) {
  const __m256i top_zero = _mm256_cmpeq_epi64(_mm256_srli_epi64(*xn, 64 - S), _mm256_setzero_si256());
  *xn = _mm256_blendv_epi8(*xn, _mm256_slli_epi64(*xn, S), top_zero);
  *shift = _mm256_add_epi64(*shift, _mm256_and_si256(top_zero, _mm256_set1_epi64x(S)));
}

using avx2::GreaterU64;

// ISqrt64 of four lanes, step for step the same integers (the bounds of its
// comment keep every product below within vpmuludq's 32 x 32 -> 64 bits):
//   - countl_zero has no AVX2 instruction: xn = x << 2k comes from four even
//     shifts (32, 16, 8, 4, 2), each taken where the top bits it skips are 0;
//     x = 0 is computed as 1 and answered 0 at the end;
//   - s < 2^33 (T < 2^32, |s - T| < 6575), so s^2 mod 2^64 = sl^2 + sh sl 2^33
//     with sh = s >> 32 and sl its low half;
//   - |xn - s^2| < 2^45.7, so (xn - s^2) >> 16 fits in int32: the signed
//     product with Y1 is the unsigned product of its low half minus Y1 2^32
//     where it is negative, and the arithmetic shift by 31 is a logical one
//     with the sign bits ORed in (AVX2 has no 64-bit arithmetic shift).
CAMSIM_AVX2_TARGET __m256i ISqrt64x4(__m256i x) {
  using isqrt_detail::kRsqrt;
  using isqrt_detail::RsqrtTable;
  const __m256i zero = _mm256_setzero_si256();
  const __m256i is_zero = _mm256_cmpeq_epi64(x, zero);
  const __m256i x1 = _mm256_sub_epi64(x, is_zero);  // 0 -> 1
  __m256i xn = x1, shift = zero;                    // shift = 2k
  NormaliseStep<32>(&xn, &shift);
  NormaliseStep<16>(&xn, &shift);
  NormaliseStep<8>(&xn, &shift);
  NormaliseStep<4>(&xn, &shift);
  NormaliseStep<2>(&xn, &shift);
  const __m256i a = _mm256_srli_epi64(xn, 32);
  const __m256i cell = _mm256_sub_epi64(_mm256_srli_epi64(xn, 64 - RsqrtTable::kBits),
                                        _mm256_set1_epi64x(RsqrtTable::kFirst));
  const __m128i entry = _mm_and_si128(
      _mm256_i64gather_epi32(reinterpret_cast<const int*>(kRsqrt.v), cell, 2), _mm_set1_epi32(0xFFFF));
  const __m256i y0 = _mm256_slli_epi64(_mm256_cvtepu32_epi64(entry), 15);
  const __m256i y0sq = _mm256_srli_epi64(_mm256_mul_epu32(y0, y0), 32);
  const __m256i d = _mm256_sub_epi64(_mm256_set1_epi64x(int64_t{3} << 60), _mm256_mul_epu32(a, y0sq));
  const __m256i y = _mm256_srli_epi64(_mm256_mul_epu32(y0, _mm256_srli_epi64(d, 30)), 31);
  const __m256i s = _mm256_srli_epi64(_mm256_mul_epu32(a, y), 30);
  const __m256i s_sq = _mm256_add_epi64(_mm256_mul_epu32(s, s),
                                        _mm256_slli_epi64(_mm256_mul_epu32(_mm256_srli_epi64(s, 32), s), 33));
  const __m256i e = _mm256_sub_epi64(xn, s_sq);
  const __m256i negative = _mm256_cmpgt_epi64(zero, e);
  const __m256i ey = _mm256_sub_epi64(_mm256_mul_epu32(_mm256_srli_epi64(e, 16), y),
                                      _mm256_and_si256(negative, _mm256_slli_epi64(y, 32)));
  const __m256i step = _mm256_or_si256(_mm256_srli_epi64(ey, 31),
                                       _mm256_and_si256(negative, _mm256_set1_epi64x(static_cast<int64_t>(~uint64_t{0} << 33))));
  const __m256i s16 = _mm256_add_epi64(_mm256_slli_epi64(s, 16), step);
  __m256i r = _mm256_srlv_epi64(s16, _mm256_add_epi64(_mm256_srli_epi64(shift, 1), _mm256_set1_epi64x(16)));
  r = _mm256_sub_epi64(r, _mm256_srli_epi64(r, 32));
  r = _mm256_add_epi64(r, GreaterU64(_mm256_mul_epu32(r, r), x1));  // one too high
  r = _mm256_sub_epi64(r, GreaterU64(_mm256_sub_epi64(x1, _mm256_mul_epu32(r, r)), _mm256_add_epi64(r, r)));
  return _mm256_andnot_si256(is_zero, r);
}

CAMSIM_AVX2_TARGET void ISqrt64LanesAvx2(const uint64_t* x, uint32_t* r, int n) {
  for (int i = 0; i < n; i += 4)
    avx2::StoreLow32x4(ISqrt64x4(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(x + i))), r + i);
}
#endif

}  // namespace

void ISqrt64Lanes(const uint64_t* x, uint32_t* r, int n) {
  int i = 0;
#ifdef CAMSIM_X86_AVX2
  if (CpuHasAvx2()) {
    i = n & ~3;
    ISqrt64LanesAvx2(x, r, i);
  }
#endif
  for (; i < n; ++i) r[i] = ISqrt64(x[i]);
}

}  // namespace camsim
