#include "core/lens/flare_environment.h"

#include "core/base/detmath.h"
#include "core/base/fixed.h"
#include "core/lens/flare.h"

namespace camsim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

bool InRange(double v, double lo, double hi) { return v >= lo && v <= hi; }

// Nearest integer, ties up (as RoundShift), for |v| < 2^62.
int64_t RoundHalfUp(double v) {
  const double s = v + 0.5;
  int64_t t = static_cast<int64_t>(s);  // truncates towards zero
  if (static_cast<double>(t) > s) --t;  // floor for negative s
  return t;
}

// Camera axes in world coordinates (y up), camera-to-world yaw, pitch, roll.
struct Basis {
  double right[3], down[3], forward[3];
};

Basis CameraBasis(const FlareEnvironment& e) {
  const double sy = detmath::Sin(e.yaw_deg * kDeg), cy = detmath::Cos(e.yaw_deg * kDeg);
  const double sp = detmath::Sin(e.pitch_deg * kDeg), cp = detmath::Cos(e.pitch_deg * kDeg);
  const double sr = detmath::Sin(e.roll_deg * kDeg), cr = detmath::Cos(e.roll_deg * kDeg);
  const double fwd[3] = {sy * cp, sp, cy * cp};
  const double right0[3] = {cy, 0.0, -sy};
  const double up0[3] = {-sy * sp, cp, -cy * sp};
  Basis b;
  for (int k = 0; k < 3; ++k) {
    // Clockwise roll seen from behind: the right side goes down.
    const double right = right0[k] * cr - up0[k] * sr;
    const double up = up0[k] * cr + right0[k] * sr;
    b.right[k] = right;
    b.down[k] = -up;
    b.forward[k] = fwd[k];
  }
  return b;
}

// a is a stronger source than b (the order of flare_environment.h).
bool Stronger(const FlareSource& a, const FlareSource& b) {
  const uint64_t sa = a.excess[0] + a.excess[1] + a.excess[2], sb = b.excess[0] + b.excess[1] + b.excess[2];
  if (sa != sb) return sa > sb;
  if (a.y != b.y) return a.y < b.y;
  if (a.x != b.x) return a.x < b.x;
  if (a.excess[0] != b.excess[0]) return a.excess[0] > b.excess[0];
  return a.excess[1] > b.excess[1];
}

// Min-heap on strength (the weakest at the root) of n entries.
void SiftDown(FlareSource* h, int n, int i) {
  for (;;) {
    const int l = 2 * i + 1, r = l + 1;
    int w = i;
    if (l < n && Stronger(h[w], h[l])) w = l;
    if (r < n && Stronger(h[w], h[r])) w = r;
    if (w == i) return;
    const FlareSource t = h[i];
    h[i] = h[w];
    h[w] = t;
    i = w;
  }
}

void SiftUp(FlareSource* h, int i) {
  while (i > 0) {
    const int p = (i - 1) / 2;
    if (!Stronger(h[p], h[i])) return;
    const FlareSource t = h[i];
    h[i] = h[p];
    h[p] = t;
    i = p;
  }
}

uint64_t SatAdd(uint64_t a, uint64_t b) { return a + b < a ? ~uint64_t{0} : a + b; }

}  // namespace

Status ValidateFlareEnvironment(const FlareEnvironment& e, const SensorGeometry& g) {
  (void)g;
  if (!InRange(e.yaw_deg, -360.0, 360.0)) return InvalidArgument("flare.environment_yaw_deg", "must be in [-360, 360]");
  if (!InRange(e.pitch_deg, -90.0, 90.0)) return InvalidArgument("flare.environment_pitch_deg", "must be in [-90, 90]");
  if (!InRange(e.roll_deg, -360.0, 360.0))
    return InvalidArgument("flare.environment_roll_deg", "must be in [-360, 360]");
  if (!InRange(e.gain, 0.0, 1e6)) return InvalidArgument("flare.environment_gain", "must be in [0, 1e6]");
  if (e.max_sources < 1 || e.max_sources > kMaxEnvironmentSources)
    return InvalidArgument("flare.environment_max_sources", "must be in [1, 1024]");
  if (e.texels == nullptr) return Status::Ok();
  if (e.width < 4 || e.width > kMaxEnvironmentWidth || e.height < 2 || e.width != 2 * e.height ||
      int64_t{e.width} * e.height > kMaxEnvironmentTexels)
    return InvalidArgument("flare.environment_map",
                           "must be a lat-long map twice as wide as high, 4 x 2 to 8192 x 4096 texels");
  if (!InRange(e.fx, 1e-3, 1e7) || !InRange(e.fy, 1e-3, 1e7))
    return InvalidArgument("lens.focal_length_mm", "the environment map needs focal lengths fx, fy in (0, 1e7] pixels");
  if (!InRange(e.cx, -1e6, 1e6) || !InRange(e.cy, -1e6, 1e6))
    return InvalidArgument("distortion.cx", "the environment map needs a principal point within 1e6 pixels");
  const size_t n = static_cast<size_t>(e.width) * static_cast<size_t>(e.height) * 3;
  for (size_t i = 0; i < n; ++i) {
    const float v = e.texels[i];
    if (!(v >= 0.0f && v <= 3.4e38f))  // NaN, infinite or negative
      return InvalidArgument("flare.environment_map", "holds a NaN, infinite or negative texel (sanitise it)");
  }
  return Status::Ok();
}

int FlareEnvironmentCapacity(const FlareConfig& c) {
  return c.enabled && c.environment.texels != nullptr ? c.environment.max_sources : 0;
}

void ComputeFlareEnvironment(const FlareConfig& c, const SensorGeometry& g, Span<FlareSource> storage,
                             FlareEnvironmentSummary* out) {
  *out = FlareEnvironmentSummary{};
  const FlareEnvironment& e = c.environment;
  const int capacity = FlareEnvironmentCapacity(c) < static_cast<int>(storage.size)
                           ? FlareEnvironmentCapacity(c)
                           : static_cast<int>(storage.size);
  if (!c.enabled || e.texels == nullptr) return;
  const uint32_t threshold_q16 = Q<16, 16>::FromDouble(c.threshold).raw;
  const double threshold = threshold_q16 / 65536.0;  // exact: the frame's threshold
  const uint32_t glare_q16 = Q<1, 16>::FromDouble(c.glare_fraction).raw;
  const Basis b = CameraBasis(e);
  const int W = g.width, H = g.height, R = c.glare_radius;
  int32_t ghost_scale[kMaxGhosts] = {};
  for (int k = 0; k < c.ghost_count; ++k) ghost_scale[k] = Q<15, 16, true>::FromDouble(c.ghost_scale[k]).raw;
  const double dlambda = 2 * kPi / e.width, dphi = kPi / e.height;
  const double pixels_per_sr = e.fx * e.fy;  // on-axis pixels per steradian
  FlareSource* heap = storage.data;
  int count = 0;
  for (int j = 0; j < e.height; ++j) {
    const float* row = e.texels + static_cast<size_t>(j) * static_cast<size_t>(e.width) * 3;
    bool bright_row = false;
    for (int i = 0; i < 3 * e.width && !bright_row; ++i) bright_row = row[i] * e.gain > threshold;
    if (!bright_row) continue;
    const double phi = kPi / 2 - dphi * (j + 0.5);
    const double sin_top = detmath::Sin(kPi / 2 - dphi * j), sin_bottom = detmath::Sin(kPi / 2 - dphi * (j + 1));
    const double omega = dlambda * (sin_top - sin_bottom);
    const double sp = detmath::Sin(phi), cp = detmath::Cos(phi);
    for (int i = 0; i < e.width; ++i) {
      const float* t = row + 3 * i;
      double over[3];
      bool bright = false;
      for (int ch = 0; ch < 3; ++ch) {
        const double l = t[ch] * e.gain;
        over[ch] = l > threshold ? l - threshold : 0.0;
        bright = bright || over[ch] > 0.0;
      }
      if (!bright) continue;
      ++out->bright_texels;
      const double lambda = dlambda * (i + 0.5) - kPi;
      const double d[3] = {cp * detmath::Sin(lambda), sp, cp * detmath::Cos(lambda)};
      const double X = d[0] * b.right[0] + d[1] * b.right[1] + d[2] * b.right[2];
      const double Y = d[0] * b.down[0] + d[1] * b.down[1] + d[2] * b.down[2];
      const double Z = d[0] * b.forward[0] + d[1] * b.forward[1] + d[2] * b.forward[2];
      // Projectable: in front and within kMaxFlareOffset of the principal point.
      const double lim = kMaxFlareOffset;
      const bool front = Z > 0.0 && X * e.fx <= lim * Z && -X * e.fx <= lim * Z && Y * e.fy <= lim * Z &&
                         -Y * e.fy <= lim * Z;
      double u = 0.0, v = 0.0;
      if (front) {
        u = e.cx + e.fx * X / Z;
        v = e.cy + e.fy * Y / Z;
        if (u >= -0.5 && u < W - 0.5 && v >= -0.5 && v < H - 0.5) {
          ++out->in_frame;
          continue;
        }
      }
      FlareSource s;
      for (int ch = 0; ch < 3; ++ch) {
        const double q = over[ch] * omega * pixels_per_sr * 65536.0;
        s.excess[ch] = q >= static_cast<double>(kMaxEnvironmentExcess) ? kMaxEnvironmentExcess
                                                                         : static_cast<uint64_t>(RoundHalfUp(q));
        // The exact glare fraction (the frame's Q0.16 share must match what its
        // pixels lose; these texels lose nothing from the frame).
        const double gq = q * c.glare_fraction;
        s.glare[ch] = gq >= static_cast<double>(kMaxEnvironmentExcess) ? kMaxEnvironmentExcess
                                                                        : static_cast<uint64_t>(RoundHalfUp(gq));
        out->haze_excess[ch] = SatAdd(out->haze_excess[ch], s.excess[ch]);
      }
      bool reaches = false;
      if (front) {
        s.x = static_cast<int32_t>(RoundHalfUp(u));
        s.y = static_cast<int32_t>(RoundHalfUp(v));
        reaches = s.x >= -R && s.x <= W - 1 + R && s.y >= -R && s.y <= H - 1 + R && glare_q16 != 0;
        for (int k = 0; k < c.ghost_count && !reaches; ++k) {
          const int r = static_cast<int>(c.ghost_radius_px[k]);
          const int32_t gx = FlareGhostCentre(s.x, ghost_scale[k], W), gy = FlareGhostCentre(s.y, ghost_scale[k], H);
          reaches = gx >= -r && gx <= W - 1 + r && gy >= -r && gy <= H - 1 + r && c.ghost_intensity[k] > 0.0;
        }
      }
      if (!reaches || (s.excess[0] | s.excess[1] | s.excess[2]) == 0 || capacity == 0) {
        ++out->haze_only;
        continue;
      }
      if (count < capacity) {
        heap[count] = s;
        SiftUp(heap, count++);
      } else {
        ++out->haze_only;  // one of the two drops out of the list
        if (Stronger(s, heap[0])) {
          heap[0] = s;
          SiftDown(heap, count, 0);
        }
      }
    }
  }
  // Strongest first (insertion sort: at most 1024 entries, once).
  for (int i = 1; i < count; ++i) {
    const FlareSource s = heap[i];
    int k = i;
    while (k > 0 && Stronger(s, heap[k - 1])) {
      heap[k] = heap[k - 1];
      --k;
    }
    heap[k] = s;
  }
  out->sources = count;
}

}  // namespace camsim
