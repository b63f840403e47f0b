#include "core/control/metering_ref.h"

#include <algorithm>

namespace camsim::ref {

double RefMeteringWeight(Metering m, int x, int y, int width, int height) {
  if (m == Metering::kUniform || m == Metering::kImage) return 1.0;
  const double dx = 2.0 * x + 1 - width, dy = 2.0 * y + 1 - height;
  const double r2 = (dx * dx + dy * dy) / (static_cast<double>(width) * width + static_cast<double>(height) * height);
  // The spot's centre pixels: within sqrt(2) half-pixels of the centre (num <= 2 in metering.cc).
  if (m == Metering::kSpot) return r2 < 0.01 || dx * dx + dy * dy <= 2.0 ? 1.0 : 0.0;
  return std::max(1.0 - r2, 1.0 / 16.0);
}

double RefWeightedBrightness(const uint16_t* raw, int width, int height, ptrdiff_t stride, int channels,
                             int black_dn, int max_dn, Metering m, const double* weights) {
  double weighted = 0, total = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double w = m == Metering::kImage ? weights[static_cast<size_t>(y) * width + x]
                                             : RefMeteringWeight(m, x, y, width, height);
      for (int c = 0; c < channels; ++c) {
        const double v = static_cast<double>(raw[y * stride + x * channels + c]) - black_dn;
        weighted += w * std::max(v, 0.0);
        total += w;
      }
    }
  if (total == 0 || max_dn <= black_dn) return 0.0;
  return weighted / total / (max_dn - black_dn);
}

}  // namespace camsim::ref
