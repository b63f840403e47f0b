#include "core/control/metering.h"

namespace camsim {

uint32_t MeteringWeight(Metering m, int x, int y, int width, int height) {
  if (m == Metering::kUniform || m == Metering::kImage) return 65536;
  const int64_t dx = 2 * int64_t{x} + 1 - width, dy = 2 * int64_t{y} + 1 - height;
  const int64_t num = dx * dx + dy * dy;                                      // r^2 * den
  const int64_t den = int64_t{width} * width + int64_t{height} * height;
  // r < 0.1, and always the 1, 2 or 4 pixels nearest the centre (num <= 2),
  // which a small frame's r < 0.1 disc may not reach.
  if (m == Metering::kSpot) return 100 * num < den || num <= 2 ? 65536u : 0u;
  const int64_t w = 65536 - (65536 * num) / den;                              // 1 - r^2, Q1.16
  return static_cast<uint32_t>(w < 4096 ? 4096 : w);                          // at least 1/16
}

double WeightedBrightness(const uint16_t* raw, int width, int height, ptrdiff_t stride, int channels,
                          int black_dn, int max_dn, Metering m, const uint16_t* weights) {
  uint64_t weighted = 0, total = 0;
  for (int y = 0; y < height; ++y) {
    const uint16_t* row = raw + y * stride;
    for (int x = 0; x < width; ++x) {
      const uint64_t w = m == Metering::kImage ? weights[static_cast<size_t>(y) * width + x]
                                               : MeteringWeight(m, x, y, width, height);
      if (w == 0) continue;
      uint64_t sum = 0;
      for (int c = 0; c < channels; ++c) {
        const int v = row[x * channels + c] - black_dn;
        sum += static_cast<uint64_t>(v > 0 ? v : 0);
      }
      weighted += w * sum;
      total += w * static_cast<uint64_t>(channels);
    }
  }
  if (total == 0 || max_dn <= black_dn) return 0.0;
  return static_cast<double>(weighted) / static_cast<double>(total) / (max_dn - black_dn);
}

}  // namespace camsim
