#include "core/base/random.h"

#include "core/base/detmath.h"

namespace camsim {

void DrawBitsLanes(uint64_t seed, uint32_t stream, uint32_t frame, uint32_t x0, uint32_t y, uint32_t draw,
                   RandomLanes* out) {
  constexpr int kLanes = RandomLanes::kLanes;
  uint32_t c0[kLanes], c1[kLanes], c2[kLanes], c3[kLanes];  // the counters, {x, y, frame, draw}
  for (int i = 0; i < kLanes; ++i) {
    c0[i] = x0 + static_cast<uint32_t>(i);
    c1[i] = y;
    c2[i] = frame;
    c3[i] = draw;
  }
  uint32_t k0 = static_cast<uint32_t>(seed);  // the key of DrawBits
  uint32_t k1 = static_cast<uint32_t>(seed >> 32) ^ (stream * 0x9E3779B9u);
  for (int round = 0; round < Philox4x32::kRounds; ++round) {  // Philox4x32::Generate, lane by lane
    if (round > 0) {
      k0 += Philox4x32::kW0;
      k1 += Philox4x32::kW1;
    }
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
    for (size_t i = 0; i < kNodes; ++i) {
      // Interval end i of the segment as a (possibly fractional) v, exact;
      // the last segment holds v = 0 alone.
      const double v =
          segment == kSegments - 1 ? 0.0 : (0x1p30 + static_cast<double>(i) * 0x1p24) * scale;
      const double z = -detmath::InvNormalCdf((v + 0.5) * 0x1p-32);
      storage[static_cast<size_t>(segment) * kNodes + i] =
          Q<7, kEntryFracBits, true>::FromDouble(z).raw;
    }
  }
  table_ = storage.data;
  return Status::Ok();
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
  return Status::Ok();
}

}  // namespace camsim
