// CAMSIM_CPU_CLONES: put before a hot integer function so that, on x86-64
// GNU/Linux, GCC and Clang compile it twice (baseline SSE2 and AVX2) and the
// loader picks the one the CPU runs (target_clones, an ifunc). Integer code
// only: both copies give the same bits, so outputs stay bit-exact.
// Elsewhere (ARM, bare metal) and with -DCAMSIM_NO_CPU_CLONES (the debug
// preset, so that CI also runs the baseline code) it expands to nothing.
#pragma once

//
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

namespace camsim {

inline bool CpuHasAvx2() {
#ifdef CAMSIM_X86_AVX2
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}

}  // namespace camsim
