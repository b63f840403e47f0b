#include "core/lens/distortion_ref.h"

#include <cmath>

namespace camsim {

ReferenceDistortion::ReferenceDistortion(const DistortionConfig& c, const SensorGeometry& g)
    : config_(c), geometry_(g) {
  const LensModel& m = c.lens;
  // Cover the whole frame plus a margin (the stage covers its grid nodes).
  double rd = 0.0;
  for (int corner = 0; corner < 4; ++corner) {
    const double u = corner & 1 ? g.width + 64.0 : -64.0, v = corner & 2 ? g.height + 64.0 : -64.0;
    const double x = (u - m.cx) / m.fx, y = (v - m.cy) / m.fy;
    rd = std::fmax(rd, std::sqrt(x * x + y * y));
  }
  if (m.model != DistortionModel::kOff) branch_ = LensAnalyse(m, rd);
}

bool ReferenceDistortion::Source(double u, double v, int c, double* sx, double* sy) const {
  const LensModel& m = config_.lens;
  double x = 0.0, y = 0.0;
  if (m.model == DistortionModel::kOff) {
    x = (u - m.cx) / m.fx;
    y = (v - m.cy) / m.fy;
  } else if (!LensUndistort(m, branch_, (u - m.cx) / m.fx, (v - m.cy) / m.fy, &x, &y)) {
    return false;
  }
  const double s = config_.chromatic_scale[c];
  *sx = m.cx + s * m.fx * x;
  *sy = m.cy + s * m.fy * y;
  return std::isfinite(*sx) && std::isfinite(*sy);
}

double ReferenceDistortion::Filter(const ImageView<const uint32_t>& p, double sx, double sy) const {
  const int n = ResampleTaps(config_.filter), before = n / 2 - 1;
  const double fx = std::floor(sx), fy = std::floor(sy);
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  double wx[6], wy[6], sumx = 0.0, sumy = 0.0;
  for (int t = 0; t < n; ++t) {
    wx[t] = ResampleKernel(config_.filter, (ix - before + t) - sx);
    wy[t] = ResampleKernel(config_.filter, (iy - before + t) - sy);
    sumx += wx[t];
    sumy += wy[t];
  }
  const auto at = [&p](int x, int y) {
    return static_cast<double>(*(p.row(Reflect101(y, p.height)) + Reflect101(x, p.width)));
  };
  double v = 0.0;
  for (int k = 0; k < n; ++k) {
    double h = 0.0;
    for (int t = 0; t < n; ++t) h += wx[t] / sumx * at(ix - before + t, iy - before + k);
    v += wy[k] / sumy * h;
  }
  if (n > 2) {
    // The clamp's 2x2 neighbourhood is the stage's: around the position
    // rounded to 1/phases (it differs from floor() just below an integer).
    const double ph = config_.phases;
    const int cx = static_cast<int>(std::floor(std::floor(sx * ph + 0.5) / ph));
    const int cy = static_cast<int>(std::floor(std::floor(sy * ph + 0.5) / ph));
    const double a = at(cx, cy), b = at(cx + 1, cy), c = at(cx, cy + 1), d = at(cx + 1, cy + 1);
    v = std::fmin(std::fmax(v, std::fmin(std::fmin(a, b), std::fmin(c, d))), std::fmax(std::fmax(a, b), std::fmax(c, d)));
  }
  return std::fmin(std::fmax(v, 0.0), 4294967295.0);
}

double ReferenceDistortion::Sample(const ImageView<const uint32_t>& p, int x, int y, int c) const {
  double sx = 0.0, sy = 0.0;
  if (!Source(x, y, c, &sx, &sy)) return 0.0;
  if (sx < -0.5 || sy < -0.5 || sx > geometry_.width - 0.5 || sy > geometry_.height - 0.5) return 0.0;
  return Filter(p, sx, sy);
}

}  // namespace camsim
