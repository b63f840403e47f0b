#include "core/lens/distortion_ref.h"

#include <algorithm>
#include <cmath>

namespace camsim {

ReferenceDistortion::ReferenceDistortion(const DistortionConfig& c, const SensorGeometry& g)
    : config_(c), geometry_(g) {
  LensModel& m = config_.lens;
  if (m.model == DistortionModel::kOff && m.fx == 0.0 && m.fy == 0.0) {  // as the stage: mesh or CA alone
    m.fx = m.fy = 1.0;
    if (m.cx == 0.0 && m.cy == 0.0) {
      m.cx = (g.width - 1) / 2.0;
      m.cy = (g.height - 1) / 2.0;
    }
  }
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
  double ux = m.cx + m.fx * x, uy = m.cy + m.fy * y;
  const DisplacementMesh& mesh = config_.mesh;
  if (mesh.dxdy != nullptr) {  // bilinear between nodes, edge nodes beyond
    const double gx = std::clamp(u / mesh.step, 0.0, mesh.cols - 1.0), gy = std::clamp(v / mesh.step, 0.0, mesh.rows - 1.0);
    const int i = std::min(static_cast<int>(gx), mesh.cols - 2), j = std::min(static_cast<int>(gy), mesh.rows - 2);
    const auto node = [&mesh](int ii, int jj, int k) { return mesh.dxdy[(static_cast<size_t>(jj) * mesh.cols + ii) * 2 + k]; };
    double d[2];
    for (int k = 0; k < 2; ++k) {
      const double top = node(i, j, k) + (node(i + 1, j, k) - node(i, j, k)) * (gx - i);
      const double bottom = node(i, j + 1, k) + (node(i + 1, j + 1, k) - node(i, j + 1, k)) * (gx - i);
      d[k] = top + (bottom - top) * (gy - j);
    }
    ux += d[0];
    uy += d[1];
  }
  const double s = config_.chromatic_scale[c];
  *sx = m.cx + s * (ux - m.cx);
  *sy = m.cy + s * (uy - m.cy);
  return std::isfinite(*sx) && std::isfinite(*sy);
}

double ReferenceDistortion::Filter(const ImageView<const uint32_t>& p, double sx, double sy) const {
  return FilterAt(
      [&p](int x, int y) { return static_cast<double>(*(p.row(Reflect101(y, p.height)) + Reflect101(x, p.width))); }, sx,
      sy);
}

double ReferenceDistortion::Sample(const double* plane, int x, int y, int c) const {
  double sx = 0.0, sy = 0.0;
  const int w = geometry_.width, h = geometry_.height;
  if (!Source(x, y, c, &sx, &sy)) return 0.0;
  if (sx < -0.5 || sy < -0.5 || sx > w - 0.5 || sy > h - 0.5) return 0.0;
  return FilterAt([plane, w, h](int px, int py) { return plane[static_cast<size_t>(Reflect101(py, h)) * w + Reflect101(px, w)]; },
                  sx, sy);
}

template <typename At>
double ReferenceDistortion::FilterAt(const At& at, double sx, double sy) const {
  const int n = ResampleTaps(config_.filter), before = n / 2 - 1;
  const double fx = std::floor(sx), fy = std::floor(sy);
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  double wx[8], wy[8], sumx = 0.0, sumy = 0.0;  // up to Lanczos-4
  for (int t = 0; t < n; ++t) {
    wx[t] = ResampleKernel(config_.filter, (ix - before + t) - sx);
    wy[t] = ResampleKernel(config_.filter, (iy - before + t) - sy);
    sumx += wx[t];
    sumy += wy[t];
  }
  double v = 0.0;
  for (int k = 0; k < n; ++k) {
    double h = 0.0;
    for (int t = 0; t < n; ++t) h += wx[t] / sumx * at(ix - before + t, iy - before + k);
    v += wy[k] / sumy * h;
  }
  if (n > 2 && config_.ringing_clamp) {
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
