#include "core/base/fixed.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

#ifdef CAMSIM_X86_AVX2
// 2k = countl_zero(x) rounded down to even, for x != 0, in four 64-bit lanes.
// AVX2 has no count of leading zeros; the position of the leading one of
// each 32-bit half comes from a float's exponent, as in GaussianAvx2
// (random.cc): v & ~(v >> 1) keeps v's leading one and stays below 1.5 times
// it, so the conversion cannot round up to the next power of two. A half
// with bit 31 set is negative as int32, of magnitude in (2^30, 2^31]: its
// exponent (sign masked off) says bit 30 or 31, and both give the same even
// count. A zero half gives exponent 0. The high half's exponent, where
// non-zero, plus 32 is the larger of the two, so the lane's leading one is at
// P = max(high + 32, low) - 127 and countl_zero = 63 - P.
CAMSIM_AVX2_TARGET inline __m256i EvenLeadingZeros(__m256i x) {
  const __m256i lead = _mm256_andnot_si256(_mm256_srli_epi32(x, 1), x);
  const __m256i e = _mm256_and_si256(_mm256_srli_epi32(_mm256_castps_si256(_mm256_cvtepi32_ps(lead)), 23),
                                     _mm256_set1_epi32(0xFF));
  const __m256i high_bias = _mm256_and_si256(_mm256_cmpgt_epi32(e, _mm256_setzero_si256()),
                                             _mm256_setr_epi32(0, 32, 0, 32, 0, 32, 0, 32));
  const __m256i biased = _mm256_add_epi32(e, high_bias);
  const __m256i q = _mm256_max_epu32(biased, _mm256_shuffle_epi32(biased, _MM_SHUFFLE(2, 3, 0, 1)));  // P + 127
  const __m256i clz = _mm256_sub_epi32(_mm256_set1_epi32(63 + 127), q);
  return _mm256_and_si256(clz, _mm256_set1_epi64x(0xFFFFFFFE));  // low half of each lane, even
}

using avx2::GreaterU64;

// ISqrt64 of four lanes, step for step the same integers (the bounds of its
// comment keep every product below within vpmuludq's 32 x 32 -> 64 bits):
//   - countl_zero has no AVX2 instruction: 2k comes from float exponents
//     (EvenLeadingZeros); x = 0 is computed as 1 and answered 0 at the end;
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
  const __m256i shift = EvenLeadingZeros(x1);      // 2k
  const __m256i xn = _mm256_sllv_epi64(x1, shift);
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
  const __m256i sq = _mm256_mul_epu32(r, r);
  const __m256i high = GreaterU64(sq, x1);  // one too high (all ones), else maybe one too low
  const __m256i low = _mm256_andnot_si256(high, GreaterU64(_mm256_sub_epi64(x1, sq), _mm256_add_epi64(r, r)));
  r = _mm256_sub_epi64(_mm256_add_epi64(r, high), low);
  return _mm256_andnot_si256(is_zero, r);
}

CAMSIM_AVX2_TARGET void ISqrt64LanesAvx2(const uint64_t* x, uint32_t* r, int n) {
  for (int i = 0; i < n; i += 4)
    avx2::StoreLow32x4(ISqrt64x4(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(x + i))), r + i);
}
#endif

#ifdef CAMSIM_X86_AVX512
// ISqrt64 in eight lanes, line for line: AVX-512 has the count of leading
// zeros, the 64-bit product (vpmullq) and the arithmetic shift that the
// AVX2 version builds from pieces. Products that fit 32 x 32 bits by
// ISqrt64's bounds (y0, y0sq, d >> 30, a and y are all below 2^32) stay
// vpmuludq; s^2, (e >> 16) y and r^2 need the 64-bit one.
CAMSIM_AVX512_TARGET __m512i ISqrt64x8(__m512i x) {
  using isqrt_detail::kRsqrt;
  using isqrt_detail::RsqrtTable;
  const __mmask8 nonzero = _mm512_test_epi64_mask(x, x);
  const __m512i one = _mm512_set1_epi64(1);
  const __m512i x1 = _mm512_mask_mov_epi64(one, nonzero, x);  // 0 -> 1
  const __m512i shift = _mm512_andnot_si512(one, _mm512_lzcnt_epi64(x1));  // 2k
  const __m512i xn = _mm512_sllv_epi64(x1, shift);
  const __m512i a = _mm512_srli_epi64(xn, 32);
  const __m512i cell = _mm512_sub_epi64(_mm512_srli_epi64(xn, 64 - RsqrtTable::kBits),
                                        _mm512_set1_epi64(RsqrtTable::kFirst));
  // A gather merges into its destination register. Given a full mask, GCC
  // drops the merge source and picks a register the previous vector wrote
  // last, which chains the loop's gathers one after the other (2.3x slower).
  // The mask (every lane: cell >= 0) is full, but GCC cannot prove it.
  const __mmask8 all = _mm512_cmpge_epi64_mask(cell, _mm512_setzero_si512());
  const __m256i gathered = _mm512_mask_i64gather_epi32(_mm256_setzero_si256(), all, cell, kRsqrt.v, 2);
  const __m256i entry = _mm256_and_si256(gathered, _mm256_set1_epi32(0xFFFF));
  const __m512i y0 = _mm512_slli_epi64(_mm512_cvtepu32_epi64(entry), 15);
  const __m512i y0sq = _mm512_srli_epi64(_mm512_mul_epu32(y0, y0), 32);
  const __m512i d = _mm512_sub_epi64(_mm512_set1_epi64(int64_t{3} << 60), _mm512_mul_epu32(a, y0sq));
  const __m512i y = _mm512_srli_epi64(_mm512_mul_epu32(y0, _mm512_srli_epi64(d, 30)), 31);
  const __m512i s = _mm512_srli_epi64(_mm512_mul_epu32(a, y), 30);
  const __m512i e = _mm512_sub_epi64(xn, _mm512_mullo_epi64(s, s));
  const __m512i ey = _mm512_mullo_epi64(_mm512_srai_epi64(e, 16), y);
  const __m512i s16 = _mm512_add_epi64(_mm512_slli_epi64(s, 16), _mm512_srai_epi64(ey, 31));
  __m512i r = _mm512_srlv_epi64(s16, _mm512_add_epi64(_mm512_srli_epi64(shift, 1), _mm512_set1_epi64(16)));
  r = _mm512_sub_epi64(r, _mm512_srli_epi64(r, 32));
  const __m512i sq = _mm512_mul_epu32(r, r);  // r < 2^32
  const __mmask8 high = _mm512_cmpgt_epu64_mask(sq, x1);  // one too high, else maybe one too low
  const __mmask8 low = _mm512_mask_cmpgt_epu64_mask(static_cast<__mmask8>(~high), _mm512_sub_epi64(x1, sq),
                                                    _mm512_add_epi64(r, r));
  r = _mm512_mask_add_epi64(_mm512_mask_sub_epi64(r, high, r, one), low, r, one);
  return _mm512_maskz_mov_epi64(nonzero, r);
}

CAMSIM_AVX512_TARGET void ISqrt64LanesAvx512(const uint64_t* x, uint32_t* r, int n) {
  for (int i = 0; i < n; i += 8)
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(r + i), _mm512_cvtepi64_epi32(ISqrt64x8(_mm512_loadu_si512(x + i))));
}
#endif

}  // namespace

void ISqrt64Lanes(const uint64_t* x, uint32_t* r, int n) {
  int i = 0;
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512()) {
    i = n & ~7;
    ISqrt64LanesAvx512(x, r, i);
  } else
#endif
#ifdef CAMSIM_X86_AVX2
  if (CpuHasAvx2()) {
    i = n & ~3;
    ISqrt64LanesAvx2(x, r, i);
  }
#endif
  for (; i < n; ++i) r[i] = ISqrt64(x[i]);
}

}  // namespace camsim
