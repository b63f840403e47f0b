#include "core/base/random.h"

#include "core/base/detmath.h"

namespace camsim {

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
