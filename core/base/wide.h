// 64-bit value times a UScale without a 128-bit type (armhf has none):
// round(v * s.mant / 2^s.shift), ties up, saturated to 32 bits. The 96-bit
// product is kept in two 64-bit words.
#pragma once

#include <cstdint>

#include "core/base/fixed.h"

namespace camsim {

inline uint32_t MulScaleU64(uint64_t v, const UScale& s) {
  if (s.mant == 0 || v == 0) return 0;
  const uint64_t p_lo = (v & 0xFFFFFFFFu) * s.mant;
  const uint64_t p_hi = (v >> 32) * s.mant;
  uint64_t lo = p_lo + (p_hi << 32);
  uint64_t hi = (p_hi >> 32) + (lo < p_lo ? 1 : 0);
  const int shift = s.shift;
  if (shift > 0) {  // + 2^(shift - 1)
    if (shift - 1 < 64) {
      const uint64_t r = uint64_t{1} << (shift - 1);
      lo += r;
      hi += lo < r ? 1 : 0;
    } else {
      hi += uint64_t{1} << (shift - 1 - 64);
    }
  }
  uint64_t q;
  if (shift >= 64) {
    q = hi >> (shift - 64);
  } else {
    if (shift > 0 ? (hi >> shift) != 0 : hi != 0) return 0xFFFFFFFFu;
    q = shift > 0 ? (lo >> shift) | (hi << (64 - shift)) : lo;
  }
  return SatU32(q);
}

}  // namespace camsim
