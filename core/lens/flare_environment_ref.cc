#include "core/lens/flare_environment_ref.h"

#include <algorithm>
#include <cmath>

namespace camsim::ref {
namespace {

constexpr double kPi = 3.14159265358979323846;

int Round(double v) { return static_cast<int>(std::floor(v + 0.5)); }

int GhostCentre(int pos, double scale, int size) {
  const double c = (size - 1) / 2.0;
  return Round(c + scale * (pos - c));
}

}  // namespace

RefEnvironment RefFlareEnvironment(const FlareConfig& c, const SensorGeometry& g) {
  RefEnvironment out;
  const FlareEnvironment& e = c.environment;
  if (!c.enabled || e.texels == nullptr) return out;
  const double thr = std::round(c.threshold * 65536.0) / 65536.0;  // the core's Q16.16 threshold
  const double deg = kPi / 180.0;
  const double yaw = e.yaw_deg * deg, pitch = e.pitch_deg * deg, roll = e.roll_deg * deg;
  // Camera axes in the world (y up): R = Ry(yaw) Rx(-pitch) Rz(-roll) applied to right, up, forward.
  const double fwd[3] = {std::sin(yaw) * std::cos(pitch), std::sin(pitch), std::cos(yaw) * std::cos(pitch)};
  const double r0[3] = {std::cos(yaw), 0.0, -std::sin(yaw)};
  const double u0[3] = {-std::sin(yaw) * std::sin(pitch), std::cos(pitch), -std::cos(yaw) * std::sin(pitch)};
  double right[3], down[3];
  for (int k = 0; k < 3; ++k) {
    right[k] = r0[k] * std::cos(roll) - u0[k] * std::sin(roll);
    down[k] = -(u0[k] * std::cos(roll) + r0[k] * std::sin(roll));
  }
  const int W = g.width, H = g.height, R = c.glare_radius;
  std::vector<RefEnvSource> candidates;
  for (int j = 0; j < e.height; ++j) {
    const double top = kPi / 2 - kPi * j / e.height, bottom = kPi / 2 - kPi * (j + 1) / e.height;
    const double omega = 2 * kPi / e.width * (std::sin(top) - std::sin(bottom));
    const double phi = kPi / 2 - kPi * (j + 0.5) / e.height;
    for (int i = 0; i < e.width; ++i) {
      const float* t = e.texels + (static_cast<size_t>(j) * e.width + i) * 3;
      double over[3];
      bool bright = false;
      for (int ch = 0; ch < 3; ++ch) {
        over[ch] = std::max(0.0, t[ch] * e.gain - thr);
        bright = bright || over[ch] > 0;
      }
      if (!bright) continue;
      ++out.bright;
      const double lambda = 2 * kPi * (i + 0.5) / e.width - kPi;
      const double d[3] = {std::cos(phi) * std::sin(lambda), std::sin(phi), std::cos(phi) * std::cos(lambda)};
      const double X = d[0] * right[0] + d[1] * right[1] + d[2] * right[2];
      const double Y = d[0] * down[0] + d[1] * down[1] + d[2] * down[2];
      const double Z = d[0] * fwd[0] + d[1] * fwd[1] + d[2] * fwd[2];
      const bool front = Z > 0 && std::fabs(X * e.fx / Z) <= kMaxFlareOffset && std::fabs(Y * e.fy / Z) <= kMaxFlareOffset;
      double u = 0, v = 0;
      if (front) {
        u = e.cx + e.fx * X / Z;
        v = e.cy + e.fy * Y / Z;
        if (u >= -0.5 && u < W - 0.5 && v >= -0.5 && v < H - 0.5) {
          ++out.in_frame;
          continue;
        }
      }
      RefEnvSource s;
      for (int ch = 0; ch < 3; ++ch) {
        s.excess[ch] = over[ch] * omega * e.fx * e.fy;
        out.haze_excess[ch] += s.excess[ch];
      }
      bool reaches = false;
      if (front) {
        s.x = Round(u);
        s.y = Round(v);
        // Glare is on when its Q0.16 share is not 0 (flare_environment.h).
        reaches = s.x >= -R && s.x <= W - 1 + R && s.y >= -R && s.y <= H - 1 + R && c.glare_fraction * 65536 >= 0.5;
        for (int k = 0; k < c.ghost_count && !reaches; ++k) {
          const int r = static_cast<int>(c.ghost_radius_px[k]);
          const int gx = GhostCentre(s.x, c.ghost_scale[k], W), gy = GhostCentre(s.y, c.ghost_scale[k], H);
          reaches = gx >= -r && gx <= W - 1 + r && gy >= -r && gy <= H - 1 + r && c.ghost_intensity[k] > 0;
        }
      }
      if (!reaches) {
        ++out.haze_only;
        continue;
      }
      candidates.push_back(s);
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(), [](const RefEnvSource& a, const RefEnvSource& b) {
    const double sa = a.excess[0] + a.excess[1] + a.excess[2], sb = b.excess[0] + b.excess[1] + b.excess[2];
    if (sa != sb) return sa > sb;
    if (a.y != b.y) return a.y < b.y;
    if (a.x != b.x) return a.x < b.x;
    if (a.excess[0] != b.excess[0]) return a.excess[0] > b.excess[0];
    return a.excess[1] > b.excess[1];
  });
  const size_t keep = std::min(candidates.size(), static_cast<size_t>(e.max_sources));
  out.haze_only += static_cast<long long>(candidates.size() - keep);
  candidates.resize(keep);
  out.sources = candidates;
  return out;
}

}  // namespace camsim::ref
