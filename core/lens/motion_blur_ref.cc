#include "core/lens/motion_blur_ref.h"

#include <algorithm>
#include <cmath>

namespace camsim::ref {
namespace {

constexpr double kMaxD = 16384.0;  // the stage's clamp of D, pixels

double Sample(const std::vector<double>& p, int w, int h, double x, double y) {
  x = std::clamp(x, 0.0, w - 1.0);
  y = std::clamp(y, 0.0, h - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int xx, int yy) { return p[static_cast<size_t>(yy) * w + xx]; };
  return (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x1, y0)) + fy * ((1 - fx) * at(x0, y1) + fx * at(x1, y1));
}

}  // namespace

void RefMotionDisplacement(const MotionBlurConfig& c, const MotionRefInput& in, double exposure_us, int x, int y,
                           double* dx, double* dy) {
  const double t = exposure_us * 1e-6;
  const size_t i = static_cast<size_t>(y) * in.width + x;
  if (c.source == MotionSource::kVectors) {
    const double s = exposure_us * c.vector_fps / 1e6;
    *dx = (*in.vectors[0])[i] * s;
    *dy = (*in.vectors[1])[i] * s;
    return;
  }
  const double cx = c.cx_px < 0 ? (in.width - 1) / 2.0 : c.cx_px;
  const double cy = c.cy_px < 0 ? (in.height - 1) / 2.0 : c.cy_px;
  const double xn = (x - cx) / c.fx_px, yn = (y - cy) / c.fy_px;
  const double* w = c.angular_velocity_rad_s;
  const double* v = c.linear_velocity_m_s;
  const double iz = in.inverse_depth != nullptr ? (*in.inverse_depth)[i] : 0.0;
  *dx = t * c.fx_px * ((-v[0] + xn * v[2]) * iz + xn * yn * w[0] - (1 + xn * xn) * w[1] + yn * w[2]);
  *dy = t * c.fy_px * ((-v[1] + yn * v[2]) * iz + (1 + yn * yn) * w[0] - xn * yn * w[1] - xn * w[2]);
}

std::vector<std::vector<double>> RefMotionBlur(const MotionBlurConfig& c, const MotionRefInput& in,
                                               double exposure_us, bool continuous) {
  const int w = in.width, h = in.height;
  std::vector<std::vector<double>> out(3, std::vector<double>(static_cast<size_t>(w) * h));
  const double bound = c.max_displacement_px;
  for (int y = 0; y < h; ++y) {
    const double rho = (y - (h - 1) / 2.0) * c.line_time_us / exposure_us;
    for (int x = 0; x < w; ++x) {
      double dx, dy;
      RefMotionDisplacement(c, in, exposure_us, x, y, &dx, &dy);
      dx = std::clamp(dx, -kMaxD, kMaxD);
      dy = std::clamp(dy, -kMaxD, kMaxD);
      const double len = std::max(std::abs(dx), std::abs(dy));
      const int n = continuous ? std::max(64, static_cast<int>(std::ceil(16 * len)))
                               : std::min(c.max_samples, 1 + static_cast<int>(std::ceil(len * c.samples_per_px)));
      double sum[3] = {0, 0, 0};
      for (int i = 0; i < n; ++i) {
        const double tau = rho - 0.5 + (i + 0.5) / n;  // time / T
        const double ox = std::clamp(-dx * tau, -bound, bound), oy = std::clamp(-dy * tau, -bound, bound);
        for (int ch = 0; ch < 3; ++ch) sum[ch] += Sample(*in.plane[ch], w, h, x + ox, y + oy);
      }
      for (int ch = 0; ch < 3; ++ch) out[ch][static_cast<size_t>(y) * w + x] = sum[ch] / n;
    }
  }
  return out;
}

}  // namespace camsim::ref
