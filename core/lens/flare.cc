#include "core/lens/flare.h"

#include <cstring>

#include "core/base/detmath.h"
#include "core/base/simd.h"
#include "core/base/wide.h"
#include "core/pipeline/pipeline.h"  // FrameInput

namespace camsim {
namespace {

constexpr double kPi = 3.14159265358979323846;

uint32_t ThresholdQ16(const FlareConfig& c) { return Q<16, 16>::FromDouble(c.threshold).raw; }
uint32_t GlareQ16(const FlareConfig& c) { return Q<1, 16>::FromDouble(c.glare_fraction).raw; }

bool InRange(double v, double lo, double hi) { return v >= lo && v <= hi; }

// The glare share of one sample: RoundShift(excess * f, 16), 0 below the threshold.
inline uint32_t GlareShare(uint32_t v, uint32_t threshold, uint32_t f_q16) {
  return v > threshold ? static_cast<uint32_t>(RoundShiftU(static_cast<uint64_t>(v - threshold) * f_q16, 16)) : 0;
}

// out[x] = SatU32(out[x] + MulScaleU64(glare, UScale{k[x], 32})) for x < n.
// With glare = gh 2^32 + gl, round(glare k / 2^32) (ties up) is
// gh k + (gl k + 2^31) >> 32, as gl k + 2^31 < 2^64. For glare < 2^63 the
// sum with out[x] stays below 2^63 + 2^33, and saturating it once gives
// what saturating the product and then the sum gives. A source's glare is
// below 2^47 (a tile's 256 shares below 2^32 each; an environment source's
// at most kMaxEnvironmentExcess). In lanes per CPU tier (the same bits).
CAMSIM_CPU_CLONES
void AddGlareRow(uint32_t* out, const uint32_t* k, uint64_t glare, int n) {
  const uint64_t gh = glare >> 32, gl = glare & 0xFFFFFFFFu;
  for (int x = 0; x < n; ++x) {
    const uint64_t kw = k[x];
    const uint64_t sum = uint64_t{out[x]} + gh * kw + ((gl * kw + 0x80000000u) >> 32);
    out[x] = sum > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<uint32_t>(sum);
  }
}

// out[x] = SatU32(in[x] - GlareShare(in[x]) + haze) for x < n: the pixel's
// own part. The share is at most in[x] - threshold (f <= 1.0, Q1.16), so
// the difference fits 32 bits and one saturating add follows.
CAMSIM_CPU_CLONES
void OwnPartRow(const uint32_t* in, uint32_t* out, uint32_t threshold, uint32_t f_q16, uint32_t haze, int n) {
  for (int x = 0; x < n; ++x) {
    const uint32_t own = in[x] - GlareShare(in[x], threshold, f_q16);
    const uint32_t sum = own + haze;
    out[x] = sum < haze ? 0xFFFFFFFFu : sum;
  }
}

// Up to kPeakTiles tiles of one tile row at a time: its rows are read
// row by row, each over kPeakTiles * kFlareTile contiguous samples.
constexpr int kPeakTiles = 64;

// peak[t] = the largest sample of tile t of the kPeakTiles tiles from
// column x0 in the rows [y0, y0 + h) (the last tile may end at `width`):
// compares only, in lanes, so that a tile's sums are made only when it has
// a sample above the threshold.
CAMSIM_CPU_CLONES
void TilePeaks(const FrameInput& in, int x0, int y0, int h, int width, uint32_t* peak) {
  constexpr int tiles = kPeakTiles;
  for (int t = 0; t < tiles; ++t) peak[t] = 0;
  const int full = (width - x0) / kFlareTile < tiles ? (width - x0) / kFlareTile : tiles;
  for (int ch = 0; ch < 3; ++ch)
    for (int y = y0; y < y0 + h; ++y) {
      const uint32_t* row = in.radiance[ch].row(y) + x0;
      for (int t = 0; t < full; ++t) {
        uint32_t m = peak[t];
        for (int i = 0; i < kFlareTile; ++i) m = row[t * kFlareTile + i] > m ? row[t * kFlareTile + i] : m;
        peak[t] = m;
      }
      for (int x = full * kFlareTile; full < tiles && x0 + x < width; ++x)
        peak[full] = row[x] > peak[full] ? row[x] : peak[full];
    }
}

// out[x] = SatU32(out[x] + v) for x < n, in 32-bit lanes.
CAMSIM_CPU_CLONES
void AddConstantRow(uint32_t* out, uint32_t v, int n) {
  for (int x = 0; x < n; ++x) {
    const uint32_t sum = out[x] + v;
    out[x] = sum < v ? 0xFFFFFFFFu : sum;
  }
}

constexpr int kMaxBlades = 16;

// The aperture shape of circumradius r: a disc (blades < 3) or a regular
// polygon with a vertex straight up, its edge normals' sines and cosines
// computed once (Init asks for every pixel of each ghost).
struct Aperture {
  Aperture(double radius, int n) : r(radius), blades(n) {
    if (n < 3) return;
    apothem = r * detmath::Cos(kPi / n);
    for (int k = 0; k < n; ++k) {
      const double phi = kPi / 2 + kPi / n + 2 * kPi * k / n;  // edge normals, between the vertices
      cos_phi[k] = detmath::Cos(phi);
      sin_phi[k] = detmath::Sin(phi);
    }
  }
  // Is (dx, dy) inside?
  bool Inside(int dx, int dy) const {
    if (blades < 3) return dx * dx + dy * dy <= r * r;
    for (int k = 0; k < blades; ++k)
      if (dx * cos_phi[k] + dy * sin_phi[k] > apothem) return false;
    return true;
  }
  double r;
  int blades;
  double apothem = 0.0;
  double cos_phi[kMaxBlades] = {}, sin_phi[kMaxBlades] = {};
};

}  // namespace

Status FlareStage::Configure(const FlareConfig& c, const SensorGeometry& g) {
  if (!InRange(c.threshold, 0.01, 60000.0)) return InvalidArgument("flare.threshold", "must be in [0.01, 60000]");
  if (!InRange(c.glare_fraction, 0.0, 1.0)) return InvalidArgument("flare.glare_fraction", "must be in [0, 1]");
  if (c.glare_radius < 1 || c.glare_radius > kMaxGlareRadius)
    return InvalidArgument("flare.glare_radius", "must be in [1, 32] pixels");
  if (c.blades < 0 || c.blades > kMaxBlades || c.blades == 1 || c.blades == 2)
    return InvalidArgument("flare.blades", "must be 0 (round) or 3 .. 16");
  if (!InRange(c.haze, 0.0, 1.0)) return InvalidArgument("flare.haze", "must be in [0, 1]");
  if (c.ghost_count < 0 || c.ghost_count > kMaxGhosts) return InvalidArgument("flare.ghost_count", "must be 0 .. 4");
  for (int i = 0; i < c.ghost_count; ++i) {
    if (!InRange(c.ghost_scale[i], -4.0, 4.0)) return InvalidArgument("flare.ghost_scale", "must be in [-4, 4]");
    if (!InRange(c.ghost_radius_px[i], 1.0, kMaxGhostRadius))
      return InvalidArgument("flare.ghost_radius_px", "must be in [1, 64] pixels");
    if (!InRange(c.ghost_intensity[i], 0.0, 1.0)) return InvalidArgument("flare.ghost_intensity", "must be in [0, 1]");
    for (int k = 0; k < 3; ++k)
      if (!InRange(c.ghost_tint[3 * i + k], 0.0, 1.0)) return InvalidArgument("flare.ghost_tint", "must be in [0, 1]");
  }
  CAMSIM_TRY(ValidateFlareEnvironment(c.environment, g));
  config_ = c;
  geometry_ = g;
  threshold_ = ThresholdQ16(c);
  glare_q16_ = GlareQ16(c);
  kernel_side_ = 2 * c.glare_radius + 1;
  for (int i = 0; i < c.ghost_count; ++i) {
    ghost_radius_[i] = static_cast<int>(c.ghost_radius_px[i]);
    ghost_scale_q16_[i] = Q<15, 16, true>::FromDouble(c.ghost_scale[i]).raw;
  }
  return Status::Ok();
}

Result<LineFormat> FlareStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kRadiance || in.channels != 3)
    return InvalidArgument("flare", "needs 3-channel radiance input (put it first)");
  return in;
}

const char* FlareStage::IdentityReason() const {
  return config_.enabled ? nullptr : "flare off (flare.enabled = false)";
}

void FlareStage::CountTables(WorkspaceCounter& counter) const {
  counter.Add<uint32_t>(static_cast<size_t>(kernel_side_) * kernel_side_);
  for (int i = 0; i < config_.ghost_count; ++i) counter.Add<int16_t>(static_cast<size_t>(2 * ghost_radius_[i] + 1));
  counter.Add<FlareSource>(static_cast<size_t>(FlareEnvironmentCapacity(config_)));
}

Status FlareStage::Init(Arena& tables) { return Build(tables, nullptr); }

Status FlareStage::InitFrom(Arena& tables, const Stage& previous, int* copied) {
  const FlareStage& p = static_cast<const FlareStage&>(previous);  // the same class (Stage::InitFrom)
  const bool same = &p != this && p.kernel_ != nullptr && p.config_.glare_radius == config_.glare_radius &&
                    p.config_.blades == config_.blades;
  *copied = same ? 1 : 0;
  return Build(tables, same ? &p : nullptr);
}

Status FlareStage::Build(Arena& tables, const FlareStage* same_kernel) {
  // Glare kernel: a glow 1 / (1 + (d / 2)^2) plus diffraction spikes, then
  // normalised to Q0.32 summing to exactly 2^32 (the remainder at the centre).
  const int R = config_.glare_radius, side = kernel_side_;
  uint32_t* k = tables.Take<uint32_t>(static_cast<size_t>(side) * side);
  if (k == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for flare tables");
  if (same_kernel != nullptr) {
    std::memcpy(k, same_kernel->kernel_, static_cast<size_t>(side) * side * sizeof(uint32_t));
    kernel_ = k;
    return BuildGhostsAndEnvironment(tables);
  }
  const int n = config_.blades;
  const int spikes = n < 3 ? 0 : (n % 2 == 0 ? n : 2 * n);
  double cos_theta[2 * kMaxBlades], sin_theta[2 * kMaxBlades];  // each spike's direction
  for (int s = 0; s < spikes; ++s) {
    const double theta = kPi / 2 + 2 * kPi * s / spikes;
    cos_theta[s] = detmath::Cos(theta);
    sin_theta[s] = detmath::Sin(theta);
  }
  // Two passes (total, then the quantised weights) so no double table sits on
  // the stack (33 KB at R = 32 would not suit small targets).
  const auto weight = [&](int dx, int dy) {
    const double d2 = double(dx) * dx + double(dy) * dy;
    if (d2 > double(R) * R) return 0.0;
    double v = 1.0 / (1.0 + d2 / 4.0);
    for (int s = 0; s < spikes; ++s) {
      const double along = dx * cos_theta[s] + dy * sin_theta[s];
      const double perp = -dx * sin_theta[s] + dy * cos_theta[s];
      if (along > 0) v += 2.0 * detmath::Exp(-perp * perp / 0.5) / (1.0 + along / 4.0);
    }
    return v;
  };
  double total = 0;
  for (int dy = -R; dy <= R; ++dy)
    for (int dx = -R; dx <= R; ++dx) total += weight(dx, dy);
  uint64_t sum = 0;
  for (int dy = -R; dy <= R; ++dy)
    for (int dx = -R; dx <= R; ++dx) {
      uint32_t& q = k[(dy + R) * side + dx + R];
      q = static_cast<uint32_t>(weight(dx, dy) / total * 4294967296.0);  // floor: the sum stays <= 2^32
      sum += q;
    }
  k[R * side + R] += static_cast<uint32_t>(4294967296ull - sum);
  kernel_ = k;
  return BuildGhostsAndEnvironment(tables);
}

Status FlareStage::BuildGhostsAndEnvironment(Arena& tables) {
  const int n = config_.blades;
  // Ghost shapes: the half-width of each row of the aperture polygon (or disc), and its area.
  for (int i = 0; i < config_.ghost_count; ++i) {
    const int r = ghost_radius_[i];
    const Aperture aperture(config_.ghost_radius_px[i], n);
    int16_t* hw = tables.Take<int16_t>(static_cast<size_t>(2 * r + 1));
    if (hw == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for flare tables");
    int64_t area = 0;
    for (int dy = -r; dy <= r; ++dy) {
      int half = -1;
      for (int dx = 0; dx <= r; ++dx)
        if (aperture.Inside(dx, dy)) half = dx;
      hw[dy + r] = static_cast<int16_t>(half);
      area += half >= 0 ? 2 * half + 1 : 0;
    }
    ghost_half_width_[i] = hw;
    for (int c = 0; c < 3; ++c) {
      Result<UScale> f = UScale::FromDouble(
          area > 0 ? config_.ghost_intensity[i] * config_.ghost_tint[3 * i + c] / double(area) : 0.0, "flare.ghost_intensity");
      if (!f.ok()) return f.status();
      ghost_factor_[i][c] = f.value();
    }
  }
  // The environment map's sources and haze (none without a map).
  env_sources_ = nullptr;
  env_count_ = 0;
  env_summary_ = FlareEnvironmentSummary{};
  for (uint32_t& h : env_haze_) h = 0;
  const int capacity = FlareEnvironmentCapacity(config_);
  if (capacity > 0) {
    FlareSource* env = tables.Take<FlareSource>(static_cast<size_t>(capacity));
    if (env == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for flare tables");
    ComputeFlareEnvironment(config_, geometry_, Span<FlareSource>{env, static_cast<size_t>(capacity)}, &env_summary_);
    env_sources_ = env;
    env_count_ = env_summary_.sources;
    Result<UScale> h = UScale::FromDouble(config_.haze / (double(geometry_.width) * geometry_.height), "flare.haze");
    if (!h.ok()) return h.status();
    for (int c = 0; c < 3; ++c) env_haze_[c] = MulScaleU64(env_summary_.haze_excess[c], h.value());
  }
  return Status::Ok();
}

void FlareStage::ProcessRow(const RowArgs& a) const {
  const FlareFrame* frame = a.input != nullptr ? a.input->flare : nullptr;
  const int W = a.width;
  // The pixel's own part: minus its glare share, plus the haze (the frame's and the environment's).
  for (int c = 0; c < 3; ++c) {
    const uint32_t* in = a.rows[0].ch[c];
    uint32_t* out = a.out[c];
    const uint32_t haze = SatU32(uint64_t{frame != nullptr ? frame->haze[c] : 0u} + env_haze_[c]);
    OwnPartRow(in, out, threshold_, glare_q16_, haze, W);
  }
  if (frame != nullptr && every_source_)
    for (int s = 0; s < frame->count; ++s) AddSource(frame->sources[s], a);
  else if (frame != nullptr)
    AddFrameSources(*frame, a);
  for (int s = 0; s < env_count_; ++s) AddSource(env_sources_[s], a);
  if (a.stats != nullptr && frame != nullptr) a.stats->skipped_px += PixelsOutsideSources(*frame, a.y, W);
}

// The frame's sources are its bright tiles, one each, listed tile row by
// tile row: those of y's tile row by binary search, then their widths.
int FlareStage::PixelsOutsideSources(const FlareFrame& frame, int y, int width) {
  const int row = y / kFlareTile;
  const FlareSource* src = frame.sources;
  int lo = 0, hi = frame.count;
  while (lo < hi) {
    const int mid = lo + (hi - lo) / 2;
    if (src[mid].y / kFlareTile < row) lo = mid + 1;
    else hi = mid;
  }
  int inside = 0;
  for (int i = lo; i < frame.count && src[i].y / kFlareTile == row; ++i) {
    const int x0 = src[i].x / kFlareTile * kFlareTile;
    inside += width - x0 < kFlareTile ? width - x0 : kFlareTile;
  }
  return width - inside;
}

namespace {

// floor(n / d) for d != 0.
int64_t FloorDiv(int64_t n, int64_t d) {
  const int64_t q = n / d;
  return n % d != 0 && (n < 0) != (d < 0) ? q - 1 : q;
}

}  // namespace

// Ghost g of a source at row v is centred on row gy = floor((K + 2 s v) /
// 2^17) (FlareGhostCentre, K = c2 2^16 - s c2 + 2^16, c2 = height - 1, s the
// scale in Q16.16) and reaches row y when y - r <= gy <= y + r, that is when
// (y - r) 2^17 <= K + 2 s v < (y + r + 1) 2^17: an interval of v, whose ends
// are taken here one row wider than their quotients' floors.
bool FlareStage::GhostTileRows(int g, int y, int* first, int* last) const {
  const int64_t s = ghost_scale_q16_[g], c2 = geometry_.height - 1, r = ghost_radius_[g];
  const int64_t k = c2 * 65536 - s * c2 + 65536;
  const int64_t lo = (y - r) * int64_t{131072} - k, hi = (y + r + 1) * int64_t{131072} - k;
  if (s == 0) {  // every ghost at the centre
    if (lo > 0 || hi <= 0) return false;
    *first = 0;
    *last = (geometry_.height - 1) / kFlareTile;
    return true;
  }
  const int64_t a = FloorDiv(lo, 2 * s), b = FloorDiv(hi, 2 * s);
  const int64_t v0 = (a < b ? a : b) - 1, v1 = (a < b ? b : a) + 1;
  *first = static_cast<int>(FloorDiv(v0, kFlareTile));
  *last = static_cast<int>(FloorDiv(v1, kFlareTile));
  return true;
}

// The frame's sources lie in their tiles (0 <= y, y / kFlareTile = the tile
// row), listed tile row by tile row. The glare reaches row y from sources
// within glare_radius rows, each ghost from an interval of rows
// (GhostTileRows): up to 1 + kMaxGhosts intervals of tile rows, whose
// sources are found by binary search. Each source that can reach the row is
// visited once, in list order, as by a loop over all of them: the same bytes.
void FlareStage::AddFrameSources(const FlareFrame& frame, const RowArgs& a) const {
  const int y = a.y, last_row = (geometry_.height - 1) / kFlareTile, R = config_.glare_radius;
  int first[1 + kMaxGhosts], last[1 + kMaxGhosts], n = 0;
  first[n] = static_cast<int>(FloorDiv(y - R, kFlareTile));
  last[n++] = static_cast<int>(FloorDiv(y + R, kFlareTile));
  for (int g = 0; g < config_.ghost_count; ++g)
    if (GhostTileRows(g, y, &first[n], &last[n])) ++n;
  // Clip to the frame's tile rows; sort by first row (insertion: at most 5).
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const int f = first[i] < 0 ? 0 : first[i], l = last[i] > last_row ? last_row : last[i];
    if (f > l) continue;
    int j = m++;
    for (; j > 0 && first[j - 1] > f; --j) {
      first[j] = first[j - 1];
      last[j] = last[j - 1];
    }
    first[j] = f;
    last[j] = l;
  }
  // Intervals in order of their first rows, each searched from the source
  // after the last one visited: overlapping intervals visit no source twice.
  const FlareSource* src = frame.sources;
  int next = 0;  // sources before it are done
  for (int i = 0; i < m; ++i) {
    // The first source not done of tile row first[i] or later (binary search).
    int lo = next, hi = frame.count;
    while (lo < hi) {
      const int mid = lo + (hi - lo) / 2;
      if (src[mid].y / kFlareTile < first[i]) lo = mid + 1;
      else hi = mid;
    }
    for (next = lo; next < frame.count && src[next].y / kFlareTile <= last[i]; ++next) AddSource(src[next], a);
  }
}

// Glare and ghosts of one source on row a.y. Sources may lie outside the
// frame (environment map, |position| <= 2^21): every span is clipped to it.
void FlareStage::AddSource(const FlareSource& src, const RowArgs& a) const {
  const int W = a.width, y = a.y;
  const int R = config_.glare_radius, side = kernel_side_;
  // Glare around the source.
  if (y >= src.y - R && y <= src.y + R) {
    const uint32_t* krow = kernel_ + (y - src.y + R) * side;
    const int x0 = src.x - R < 0 ? 0 : src.x - R, x1 = src.x + R >= W ? W - 1 : src.x + R;
    for (int c = 0; c < 3 && x0 <= x1; ++c) {
      if (src.glare[c] == 0) continue;
      uint32_t* out = a.out[c];
      AddGlareRow(out + x0, krow + (x0 - src.x + R), src.glare[c], x1 - x0 + 1);
    }
  }
  // Ghosts: centre + scale * (source - centre).
  for (int g = 0; g < config_.ghost_count; ++g) {
    const int gx = FlareGhostCentre(src.x, ghost_scale_q16_[g], W);
    const int gy = FlareGhostCentre(src.y, ghost_scale_q16_[g], geometry_.height);
    const int r = ghost_radius_[g];
    if (y < gy - r || y > gy + r) continue;
    const int hw = ghost_half_width_[g][y - gy + r];
    if (hw < 0) continue;
    const int x0 = gx - hw < 0 ? 0 : gx - hw, x1 = gx + hw >= W ? W - 1 : gx + hw;
    if (x0 > x1) continue;
    for (int c = 0; c < 3; ++c) {
      const uint32_t v = MulScaleU64(src.excess[c], ghost_factor_[g][c]);
      if (v != 0) AddConstantRow(a.out[c] + x0, v, x1 - x0 + 1);
    }
  }
}

int FlareMaxSources(const SensorGeometry& g) {
  return ((g.width + kFlareTile - 1) / kFlareTile) * ((g.height + kFlareTile - 1) / kFlareTile);
}

void ComputeFlare(const FlareConfig& c, const SensorGeometry& g, const FrameInput& in, Span<FlareSource> storage,
                  FlareFrame* out) {
  *out = FlareFrame{};
  out->sources = storage.data;
  if (!c.enabled) return;
  const uint32_t threshold = ThresholdQ16(c), f = GlareQ16(c);
  uint64_t total[3] = {};
  int count = 0;
  uint32_t peak[kPeakTiles];
  for (int ty = 0; ty < g.height; ty += kFlareTile)
    for (int tx = 0; tx < g.width; tx += kFlareTile) {
      const int t = tx / kFlareTile % kPeakTiles;
      if (t == 0)
        TilePeaks(in, tx, ty, g.height - ty < kFlareTile ? g.height - ty : kFlareTile, g.width, peak);
      if (peak[t] <= threshold) continue;
      FlareSource s;
      uint64_t weight = 0, wx = 0, wy = 0;
      for (int y = ty; y < ty + kFlareTile && y < g.height; ++y)
        for (int x = tx; x < tx + kFlareTile && x < g.width; ++x) {
          uint64_t e = 0;
          for (int ch = 0; ch < 3; ++ch) {
            const uint32_t v = in.radiance[ch].row(y)[x];
            if (v <= threshold) continue;
            s.excess[ch] += v - threshold;
            s.glare[ch] += GlareShare(v, threshold, f);
            e += v - threshold;
          }
          weight += e;
          wx += e * static_cast<uint64_t>(x);
          wy += e * static_cast<uint64_t>(y);
        }
      if (weight == 0) continue;
      s.x = static_cast<int32_t>((wx + weight / 2) / weight);
      s.y = static_cast<int32_t>((wy + weight / 2) / weight);
      for (int ch = 0; ch < 3; ++ch) total[ch] += s.excess[ch];
      if (static_cast<size_t>(count) < storage.size) storage[static_cast<size_t>(count++)] = s;
    }
  out->count = count;
  Result<UScale> h = UScale::FromDouble(c.haze / (double(g.width) * g.height), "flare.haze");
  for (int ch = 0; ch < 3; ++ch) out->haze[ch] = h.ok() ? MulScaleU64(total[ch], h.value()) : 0;
}

}  // namespace camsim
