#include "core/lens/flare_ref.h"

#include "core/lens/flare_environment_ref.h"

#include <cmath>
#include <vector>

namespace camsim::ref {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool Inside(int dx, int dy, double r, int blades) {
  if (blades < 3) return dx * dx + dy * dy <= r * r;
  const double apothem = r * std::cos(kPi / blades);
  for (int k = 0; k < blades; ++k) {
    const double phi = kPi / 2 + kPi / blades + 2 * kPi * k / blades;
    if (dx * std::cos(phi) + dy * std::sin(phi) > apothem) return false;
  }
  return true;
}

}  // namespace

RefImage RefFlare(const FlareConfig& c, const SensorGeometry& g, const RefImage& in) {
  const int W = in.width, H = in.height, R = c.glare_radius, side = 2 * R + 1;
  RefImage out = in;
  if (!c.enabled) return out;
  // Kernel.
  const int n = c.blades, spikes = n < 3 ? 0 : (n % 2 == 0 ? n : 2 * n);
  std::vector<double> k(static_cast<size_t>(side) * side, 0.0);
  double total = 0;
  for (int dy = -R; dy <= R; ++dy)
    for (int dx = -R; dx <= R; ++dx) {
      const double d2 = double(dx) * dx + double(dy) * dy;
      if (d2 > double(R) * R) continue;
      double v = 1.0 / (1.0 + d2 / 4.0);
      for (int s = 0; s < spikes; ++s) {
        const double t = kPi / 2 + 2 * kPi * s / spikes;
        const double along = dx * std::cos(t) + dy * std::sin(t), perp = -dx * std::sin(t) + dy * std::cos(t);
        if (along > 0) v += 2.0 * std::exp(-perp * perp / 0.5) / (1.0 + along / 4.0);
      }
      k[static_cast<size_t>((dy + R) * side + dx + R)] = v;
      total += v;
    }
  for (double& v : k) v /= total;
  const double thr = c.threshold, f = c.glare_fraction;
  double sum_excess[3] = {};
  const auto at = [W](int x, int y) { return static_cast<size_t>(y) * W + x; };
  std::vector<std::vector<double>> add(3, std::vector<double>(static_cast<size_t>(W) * H, 0.0));
  // Glare and ghosts of one source at (sx, sy) with `excess` per channel.
  const auto add_source = [&](int sx, int sy, const double* excess) {
    for (int ch = 0; ch < 3; ++ch)
      for (int dy = -R; dy <= R; ++dy)
        for (int dx = -R; dx <= R; ++dx) {
          const long long x = static_cast<long long>(sx) + dx, y = static_cast<long long>(sy) + dy;
          if (x < 0 || x >= W || y < 0 || y >= H) continue;
          add[ch][at(static_cast<int>(x), static_cast<int>(y))] += f * excess[ch] * k[static_cast<size_t>((dy + R) * side + dx + R)];
        }
    for (int gi = 0; gi < c.ghost_count; ++gi) {
      const double m = c.ghost_scale[gi];
      const int gx = static_cast<int>(std::floor((W - 1) / 2.0 + m * (sx - (W - 1) / 2.0) + 0.5));
      const int gy = static_cast<int>(std::floor((H - 1) / 2.0 + m * (sy - (H - 1) / 2.0) + 0.5));
      const int r = static_cast<int>(c.ghost_radius_px[gi]);
      int area = 0;
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) area += Inside(dx, dy, c.ghost_radius_px[gi], n);
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
          const int x = gx + dx, y = gy + dy;
          if (x < 0 || x >= W || y < 0 || y >= H || !Inside(dx, dy, c.ghost_radius_px[gi], n)) continue;
          for (int ch = 0; ch < 3; ++ch)
            add[ch][at(x, y)] += c.ghost_intensity[gi] * c.ghost_tint[3 * gi + ch] * excess[ch] / area;
        }
    }
  };
  for (int ty = 0; ty < H; ty += kFlareTile)
    for (int tx = 0; tx < W; tx += kFlareTile) {
      double excess[3] = {}, weight = 0, wx = 0, wy = 0;
      for (int y = ty; y < ty + kFlareTile && y < H; ++y)
        for (int x = tx; x < tx + kFlareTile && x < W; ++x) {
          double e = 0;
          for (int ch = 0; ch < 3; ++ch) {
            const double v = in.planes[ch][at(x, y)];
            if (v <= thr) continue;
            excess[ch] += v - thr;
            e += v - thr;
            out.planes[ch][at(x, y)] -= f * (v - thr);
          }
          weight += e;
          wx += e * x;
          wy += e * y;
        }
      if (weight == 0) continue;
      const int sx = static_cast<int>(std::floor(wx / weight + 0.5)), sy = static_cast<int>(std::floor(wy / weight + 0.5));
      for (int ch = 0; ch < 3; ++ch) sum_excess[ch] += excess[ch];
      add_source(sx, sy, excess);
    }
  // The environment map's sources (outside the frame: their glare is added light).
  const RefEnvironment env = RefFlareEnvironment(c, g);
  for (const RefEnvSource& s : env.sources) add_source(s.x, s.y, s.excess);
  for (int ch = 0; ch < 3; ++ch) sum_excess[ch] += env.haze_excess[ch];
  for (int ch = 0; ch < 3; ++ch) {
    const double haze = c.haze * sum_excess[ch] / (double(g.width) * g.height);
    for (size_t i = 0; i < add[ch].size(); ++i) out.planes[ch][i] += add[ch][i] + haze;
  }
  return out;
}

}  // namespace camsim::ref
