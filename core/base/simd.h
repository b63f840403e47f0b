// CAMSIM_CPU_CLONES: put before a hot integer function so that, on x86-64
// GNU/Linux, GCC and Clang compile it two or three times (baseline SSE2,
// AVX2, and x86-64-v4 below) and the loader picks the widest the CPU runs
// (target_clones, an ifunc). Integer code only: every copy gives the same
// bits, so outputs stay bit-exact. Elsewhere (ARM, bare metal) and with
// -DCAMSIM_NO_CPU_CLONES (the debug preset, so that CI also runs the
// baseline code) it expands to nothing.
#pragma once

// CAMSIM_X86_AVX2: defined under the same conditions, for the few kernels
// written with AVX2 intrinsics (integer only, the same bits as their portable
// twin, which runs elsewhere and in the debug preset). Such a kernel is
// compiled with CAMSIM_AVX2_TARGET and called only when CpuHasAvx2().
#if defined(__x86_64__) && defined(__linux__) && defined(__GNUC__) && !defined(CAMSIM_NO_CPU_CLONES)
#define CAMSIM_CPU_CLONES __attribute__((target_clones("avx2", "default")))
#define CAMSIM_X86_AVX2 1
#define CAMSIM_AVX2_TARGET __attribute__((target("avx2")))
#else
#define CAMSIM_CPU_CLONES
#endif

// CAMSIM_X86_AVX512: a third tier for the hottest of those kernels, in eight
// 64-bit (sixteen 32-bit) lanes with AVX-512 F, VL, DQ, BW and CD (x86-64-v4
// plus the leading-zero count). Compiled with CAMSIM_AVX512_TARGET and called
// only when CpuHasAvx512(); the same bits as the AVX2 and portable twins.
// -DCAMSIM_NO_AVX512 leaves it out (the clang preset, so that CI also runs
// the AVX2 kernels on a CPU that has AVX-512). With the tier,
// CAMSIM_CPU_CLONES adds its x86-64-v4 copy, which GCC vectorises up to
// sixteen 32-bit lanes wide (the 1080p pipeline without DoF: about 12 %
// faster); a loop over blocks of eight columns stays eight wide, so the
// blocked loops use blocks of sixteen.
#if defined(CAMSIM_X86_AVX2) && !defined(CAMSIM_NO_AVX512)
#define CAMSIM_X86_AVX512 1
#define CAMSIM_AVX512_TARGET __attribute__((target("avx2,avx512f,avx512vl,avx512dq,avx512bw,avx512cd")))
// Clang's resolver picks an arch= clone only from clang 18 (llvm issue 55830).
#if !defined(__clang__) || __clang_major__ >= 18
#undef CAMSIM_CPU_CLONES
#define CAMSIM_CPU_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#endif
#endif

// CAMSIM_X86_AVX512_IFMA: a few AVX-512 kernels have a second copy that
// multiplies with AVX-512 IFMA (52-bit multiply-add: Ice Lake, Zen 4 and
// later; not Skylake-SP), compiled with CAMSIM_AVX512_IFMA_TARGET and called
// only when CpuHasAvx512Ifma(); the same bits as the copy without.
// -DCAMSIM_NO_IFMA leaves the copy out (the core-only preset, whose
// core_golden run in scripts/cross.sh then checks the plain AVX-512 kernels).
#if defined(CAMSIM_X86_AVX512) && !defined(CAMSIM_NO_IFMA)
#define CAMSIM_X86_AVX512_IFMA 1
#define CAMSIM_AVX512_IFMA_TARGET \
  __attribute__((target("avx2,avx512f,avx512vl,avx512dq,avx512bw,avx512cd,avx512ifma")))
#endif

#include <cstdint>

#ifdef CAMSIM_X86_AVX2
// GCC 12 warns inside its own AVX-512 headers (_mm512_undefined_epi32 reads
// itself, GCC bug 105593); the pragma covers the header's lines only.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>
#pragma GCC diagnostic pop
#else
#include <immintrin.h>
#endif
#endif

namespace camsim {

inline bool CpuHasAvx2() {
#ifdef CAMSIM_X86_AVX2
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}

inline bool CpuHasAvx512() {
#ifdef CAMSIM_X86_AVX512
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
         __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512cd");
#else
  return false;
#endif
}

inline bool CpuHasAvx512Ifma() {
#ifdef CAMSIM_X86_AVX512_IFMA
  return CpuHasAvx512() && __builtin_cpu_supports("avx512ifma");
#else
  return false;
#endif
}

#ifdef CAMSIM_X86_AVX2
// Small helpers shared by the kernels that keep 64-bit values in four lanes.
namespace avx2 {
// Four uint32 into four 64-bit lanes.
CAMSIM_AVX2_TARGET inline __m256i LoadU32x4(const uint32_t* p) {
  return _mm256_cvtepu32_epi64(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}
// The low halves of four 64-bit lanes as four 32-bit words.
CAMSIM_AVX2_TARGET inline __m128i Low32x4(__m256i v) {
  return _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(v, _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6)));
}
// The same, stored as four uint32.
CAMSIM_AVX2_TARGET inline void StoreLow32x4(__m256i v, uint32_t* p) {
  _mm_storeu_si128(reinterpret_cast<__m128i*>(p), Low32x4(v));
}
// a > b as unsigned 64-bit lanes (AVX2 compares signed): all ones or 0.
CAMSIM_AVX2_TARGET inline __m256i GreaterU64(__m256i a, __m256i b) {
  const __m256i sign = _mm256_set1_epi64x(INT64_MIN);
  return _mm256_cmpgt_epi64(_mm256_xor_si256(a, sign), _mm256_xor_si256(b, sign));
}
// floor(n / 6) for 0 <= n < 2^38 in 64-bit lanes (AVX2 has no 64-bit
// division or multiply). With n' = floor(n / 2) = h 2^32 + l (h < 32) and
// 2^32 = 3 * 1431655765 + 1: floor(n / 6) = floor(n' / 3) =
// h * 1431655765 + floor(l / 3) + floor((h + l mod 3) / 3), where
// floor(l / 3) = l * 0xAAAAAAAB >> 33 for every 32-bit l, and the last
// quotient's dividend s <= 33 gives s * 171 >> 9 (exact for s < 256).
CAMSIM_AVX2_TARGET inline __m256i FloorDiv6(__m256i n) {
  const __m256i half = _mm256_srli_epi64(n, 1);
  const __m256i h = _mm256_srli_epi64(half, 32);
  const __m256i l_div3 = _mm256_srli_epi64(_mm256_mul_epu32(half, _mm256_set1_epi64x(0xAAAAAAAB)), 33);
  const __m256i l_mod3 = _mm256_sub_epi32(half, _mm256_mul_epu32(l_div3, _mm256_set1_epi64x(3)));  // low halves
  const __m256i s = _mm256_add_epi64(h, _mm256_and_si256(l_mod3, _mm256_set1_epi64x(0xFFFFFFFF)));
  return _mm256_add_epi64(_mm256_add_epi64(_mm256_mul_epu32(h, _mm256_set1_epi64x(1431655765)), l_div3),
                          _mm256_srli_epi64(_mm256_mul_epu32(s, _mm256_set1_epi64x(171)), 9));
}
}  // namespace avx2
#endif

#ifdef CAMSIM_X86_AVX512
namespace avx512 {
// avx2::FloorDiv6 in eight lanes: floor(n / 6) for 0 <= n < 2^38, the same steps.
CAMSIM_AVX512_TARGET inline __m512i FloorDiv6(__m512i n) {
  const __m512i half = _mm512_srli_epi64(n, 1);
  const __m512i h = _mm512_srli_epi64(half, 32);
  const __m512i l_div3 = _mm512_srli_epi64(_mm512_mul_epu32(half, _mm512_set1_epi64(0xAAAAAAAB)), 33);
  const __m512i l_mod3 = _mm512_sub_epi32(half, _mm512_mul_epu32(l_div3, _mm512_set1_epi64(3)));  // low halves
  const __m512i s = _mm512_add_epi64(h, _mm512_and_si512(l_mod3, _mm512_set1_epi64(0xFFFFFFFF)));
  return _mm512_add_epi64(_mm512_add_epi64(_mm512_mul_epu32(h, _mm512_set1_epi64(1431655765)), l_div3),
                          _mm512_srli_epi64(_mm512_mul_epu32(s, _mm512_set1_epi64(171)), 9));
}
}  // namespace avx512
#endif

}  // namespace camsim
