#include "core/lens/dof_ref.h"

#include <algorithm>
#include <cmath>

namespace camsim {

double ReferenceCocPixels(const DofConfig& c, double n, double z) {
  const double f = c.focal_length_mm / 1000.0, zf = c.focus_distance_m, pitch = c.pixel_pitch_um * 1e-6;
  double coc;
  if (std::isnan(z) || (std::isinf(z) && z > 0)) {
    coc = f * f / (n * (zf - f)) / pitch;  // the limit z -> inf
  } else if (z < 0) {
    return 0.0;
  } else if (z == 0) {
    coc = c.max_coc_px;
  } else {
    coc = f * f * std::fabs(z - zf) / (n * z * (zf - f)) / pitch;
  }
  if (coc < c.min_coc_px) return 0.0;
  return std::min(coc, c.max_coc_px);
}

void ReferenceSolveLine(const double* x, const double* b, int n, double* y) {
  std::vector<double> cp(static_cast<size_t>(n)), dp(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const double lo = i > 0 ? b[i] : 0.0, up = i + 1 < n ? b[i + 1] : 0.0;
    const double diag = 1.0 + lo + up;
    // a_i = -lo; c'_{i-1} = c_{i-1} / denom_{i-1} with c_{i-1} = -lo.
    const double denom = i > 0 ? diag + lo * cp[static_cast<size_t>(i - 1)] : diag;
    cp[static_cast<size_t>(i)] = -up / denom;
    dp[static_cast<size_t>(i)] = (x[i] + (i > 0 ? lo * dp[static_cast<size_t>(i - 1)] : 0.0)) / denom;
  }
  y[n - 1] = dp[static_cast<size_t>(n - 1)];
  for (int i = n - 2; i >= 0; --i) y[i] = dp[static_cast<size_t>(i)] - cp[static_cast<size_t>(i)] * y[i + 1];
}

namespace {
double BetaOf(double a, double b) { return std::min(a, b); }
}  // namespace

std::vector<double> ReferenceDiffusionRows(const std::vector<double>& plane, const std::vector<double>& cc2, int w,
                                           int h) {
  std::vector<double> rows(plane.size());
  std::vector<double> x(static_cast<size_t>(w)), b(x.size() + 1), y(x.size());
  for (int r = 0; r < h; ++r) {
    for (int i = 0; i < w; ++i) {
      x[static_cast<size_t>(i)] = plane[static_cast<size_t>(r) * w + i];
      b[static_cast<size_t>(i)] = i > 0 ? BetaOf(cc2[static_cast<size_t>(r) * w + i - 1], cc2[static_cast<size_t>(r) * w + i]) : 0.0;
    }
    ReferenceSolveLine(x.data(), b.data(), w, y.data());
    for (int i = 0; i < w; ++i) rows[static_cast<size_t>(r) * w + i] = y[static_cast<size_t>(i)];
  }
  return rows;
}

std::vector<double> ReferenceDiffusionColumns(const std::vector<double>& rows, const std::vector<double>& cc2, int w,
                                              int h, int window, int block) {
  std::vector<double> out(rows.size());
  std::vector<double> x(static_cast<size_t>(h)), b(x.size() + 1), y(x.size());
  for (int c = 0; c < w; ++c) {
    auto at = [&](const std::vector<double>& v, int r) { return v[static_cast<size_t>(r) * w + c]; };
    if (window < 0) {
      for (int i = 0; i < h; ++i) {
        x[static_cast<size_t>(i)] = at(rows, i);
        b[static_cast<size_t>(i)] = i > 0 ? BetaOf(at(cc2, i - 1), at(cc2, i)) : 0.0;
      }
      ReferenceSolveLine(x.data(), b.data(), h, y.data());
      for (int i = 0; i < h; ++i) out[static_cast<size_t>(i) * w + c] = y[static_cast<size_t>(i)];
      continue;
    }
    for (int r = 0; r < h; ++r) {
      const int yb = r - r % block;
      const int lo = std::max(0, yb - window), hi = std::min(h - 1, yb + block - 1 + window), n = hi - lo + 1;
      for (int i = 0; i < n; ++i) {
        x[static_cast<size_t>(i)] = at(rows, lo + i);
        b[static_cast<size_t>(i)] = i > 0 ? BetaOf(at(cc2, lo + i - 1), at(cc2, lo + i)) : 0.0;
      }
      ReferenceSolveLine(x.data(), b.data(), n, y.data());
      out[static_cast<size_t>(r) * w + c] = y[static_cast<size_t>(r - lo)];
    }
  }
  return out;
}

std::vector<double> ReferenceDiffusion(const std::vector<double>& plane, const std::vector<double>& cc2, int w, int h,
                                       int window, int block) {
  return ReferenceDiffusionColumns(ReferenceDiffusionRows(plane, cc2, w, h), cc2, w, h, window, block);
}

namespace {
double DepthOf(uint32_t iz) {
  if (iz == kInvalidInverseDepth) return -1.0;
  if (iz == 0) return INFINITY;
  return 1048576.0 / iz;  // 2^20 / iz
}
}  // namespace

std::vector<double> ReferenceCc2(const DofConfig& c, double n, const uint32_t* iz, int w, int h, bool use_depth) {
  std::vector<double> cc2(static_cast<size_t>(w) * h, 0.0);
  double poly_sum = 0;
  for (double a : c.structural_poly) poly_sum += std::fabs(a);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      double v = 0;
      if (use_depth) {
        const double coc = c.diffusion_scale * ReferenceCocPixels(c, n, DepthOf(iz[i]));
        v = coc * coc;
      }
      if (poly_sum > 0) {
        const double dx = 2.0 * x - (w - 1), dy = 2.0 * y - (h - 1);
        const double den = double(w - 1) * (w - 1) + double(h - 1) * (h - 1);
        const double r = den > 0 ? std::sqrt((dx * dx + dy * dy) / den) : 0.0;
        double d = 0, rk = 1;
        for (double a : c.structural_poly) {
          d += a * rk;
          rk *= r;
        }
        d = std::min(std::max(d, 0.0), c.max_coc_px);
        if (d < c.min_coc_px) d = 0;
        v += (c.diffusion_scale * d) * (c.diffusion_scale * d);
      }
      cc2[i] = std::min(v, 1048575.0);
    }
  return cc2;
}

std::vector<double> ReferenceGatherRadius(const DofConfig& c, double n, const uint32_t* iz, int w, int h) {
  std::vector<double> r(static_cast<size_t>(w) * h);
  for (size_t i = 0; i < r.size(); ++i) r[i] = std::min(ReferenceCocPixels(c, n, DepthOf(iz[i])) / 2, double(c.max_radius_px));
  return r;
}

std::vector<double> ReferenceGather(const std::vector<double>& plane, const std::vector<double>& radius, int w, int h) {
  std::vector<double> sum(plane.size(), 0.0), wsum(plane.size(), 0.0);
  for (int qy = 0; qy < h; ++qy)
    for (int qx = 0; qx < w; ++qx) {
      const double r = radius[static_cast<size_t>(qy) * w + qx];
      const int ri = static_cast<int>(std::floor(r));
      double area = 0;
      for (int dy = -ri; dy <= ri; ++dy)
        for (int dx = -ri; dx <= ri; ++dx) area += dx * dx + dy * dy <= r * r;
      const double wt = 1.0 / area, v = plane[static_cast<size_t>(qy) * w + qx];
      for (int dy = -ri; dy <= ri; ++dy)
        for (int dx = -ri; dx <= ri; ++dx) {
          const int px = qx + dx, py = qy + dy;
          if (dx * dx + dy * dy > r * r || px < 0 || py < 0 || px >= w || py >= h) continue;
          sum[static_cast<size_t>(py) * w + px] += wt * v;
          wsum[static_cast<size_t>(py) * w + px] += wt;
        }
    }
  for (size_t i = 0; i < sum.size(); ++i) sum[i] /= wsum[i];
  return sum;
}

}  // namespace camsim
