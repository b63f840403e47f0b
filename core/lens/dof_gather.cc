// Reverse-mapped z-buffer depth of field (eq. 11): see dof.h.
//
// Per output row y, every source pixel q of rows y - R .. y + R (R =
// max_radius_px, clipped to the frame) whose disc reaches row y adds its
// weighted radiance to the run of output columns its disc covers on that row:
// x_q - h .. x_q + h, h = floor(sqrt(R_q^2 - dy^2)). The runs are added to
// difference arrays (one entry at each end) and a prefix sum turns them into
// the per-pixel sums, so the cost per output row is O((2R + 1) * width),
// independent of the disc areas.
//
// Formats: radius R_q in quarter pixels, round(coc / 2 * 4), capped at 4 R;
//          weight of a disc = round(2^26 / A(R_q)), A the disc's pixel count
//          (A <= 204 282 for R = 255: weight >= 328, relative rounding error
//          <= 0.15 %; for R <= 16, A <= 797 and the error is <= 6e-6). Sums
//          int64: the discs covering a pixel have weights adding up to at most
//          sum over rings d of (pixels at d) / A(d) ~ 2 + 2 ln R < 16 (R <= 255)
//          times 2^26 = 2^30, times samples < 2^32: below 2^62.
//          out = round(sum(w x) / sum(w)) (ties up), within [min, max] of the
//          sources. The pixel's own disc always covers it, so sum(w) > 0.

#include "core/lens/dof.h"

#include <cstring>

#include "core/pipeline/pipeline.h"

namespace camsim {
namespace {
constexpr int kWeightBits = 26;
}  // namespace

Status DofGatherStage::Configure(const DofConfig& c, const SensorGeometry& g, double f_number) {
  config_ = c;
  geometry_ = g;
  if (c.max_radius_px < 1 || c.max_radius_px > kMaxRadius)
    return InvalidArgument("dof.max_radius_px", "must be in [1, 255] pixels");
  if (c.method == DofMethod::kGather) {
    if (c.structural_only) return InvalidArgument("dof.structural_only", "needs dof.method = \"diffusion\"");
    CAMSIM_TRY(coc_.Configure(c, f_number));
  }
  return Status::Ok();
}

Result<LineFormat> DofGatherStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kRadiance || in.channels != 3)
    return InvalidArgument("dof", "depth of field needs 3-channel radiance input (run it before exposure)");
  return in;
}

const char* DofGatherStage::IdentityReason() const {
  return config_.method == DofMethod::kGather ? nullptr : "dof.method is not gather";
}

RowWindow DofGatherStage::InputRows(int y, int height) const {
  const int lo = y - config_.max_radius_px, hi = y + config_.max_radius_px;
  return {lo < 0 ? 0 : lo, hi > height - 1 ? height - 1 : hi};
}

void DofGatherStage::CountTables(WorkspaceCounter& counter) const {
  const size_t radii = 4 * static_cast<size_t>(config_.max_radius_px) + 1;
  counter.Add<uint32_t>(radii);
  counter.Add<int16_t>(radii * static_cast<size_t>(config_.max_radius_px + 1));
}

Status DofGatherStage::Init(Arena& tables) {
  const int rmax = config_.max_radius_px;
  const size_t radii = 4 * static_cast<size_t>(rmax) + 1;
  weight_ = tables.Take<uint32_t>(radii);
  half_width_ = tables.Take<int16_t>(radii * static_cast<size_t>(rmax + 1));
  if (weight_ == nullptr || half_width_ == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for gather tables");
  for (size_t q = 0; q < radii; ++q) {
    // Half widths of the disc of radius q / 4 at row offsets dy: integer
    // offsets (dx, dy) with 16 (dx^2 + dy^2) <= q^2.
    uint64_t area = 0;
    for (int dy = 0; dy <= rmax; ++dy) {
      const int64_t rem = static_cast<int64_t>(q * q) - 16 * static_cast<int64_t>(dy) * dy;
      const int16_t h = rem < 0 ? int16_t{-1} : static_cast<int16_t>(ISqrt64(static_cast<uint64_t>(rem)) >> 2);
      half_width_[q * static_cast<size_t>(rmax + 1) + dy] = h;
      if (h >= 0) area += static_cast<uint64_t>(2 * h + 1) * (dy == 0 ? 1u : 2u);
    }
    weight_[q] = static_cast<uint32_t>(((uint64_t{1} << kWeightBits) + area / 2) / area);
  }
  return Status::Ok();
}

size_t DofGatherStage::ScratchBytes(int width) const {
  return 4 * AlignUp(sizeof(int64_t) * static_cast<size_t>(width + 1)) + AlignUp(sizeof(uint16_t) * static_cast<size_t>(width));
}

size_t DofGatherStage::StateBytes(int /*width*/) const { return AlignUp(static_cast<size_t>(geometry_.height)); }

void DofGatherStage::BeginStrip(uint8_t* state) const {
  std::memset(state, kRowUnknown, static_cast<size_t>(geometry_.height));
}

void DofGatherStage::ProcessRow(const RowArgs& a) const {
  const int w = a.width, y = a.y, rmax = config_.max_radius_px;
  const size_t n1 = static_cast<size_t>(w + 1);
  int64_t* acc[4];
  for (int k = 0; k < 4; ++k) acc[k] = reinterpret_cast<int64_t*>(a.scratch + k * AlignUp(sizeof(int64_t) * n1));
  uint16_t* radius = reinterpret_cast<uint16_t*>(a.scratch + 4 * AlignUp(sizeof(int64_t) * n1));
  for (int k = 0; k < 4; ++k)
    for (int x = 0; x <= w; ++x) acc[k][x] = 0;
  const uint32_t rcap = 4u * static_cast<uint32_t>(rmax);
  // Skip: no disc in the window reaches beyond its own pixel (radius < 1 px,
  // i.e. quarter-pixel radius (coc + 64) >> 7 < 4, coc < 448 in Q.8).
  bool blur = false;
  for (int k = 0; k < a.row_count && !blur; ++k) {
    uint8_t& row_blurs = a.state[a.first_row + k];
    if (row_blurs == kRowUnknown) {
      const uint32_t* iz = a.input->inverse_depth.row(a.first_row + k);
      bool b = false;
      for (int x = 0; x < w && !b; ++x) b = coc_.Coc(iz[x]) >= 448;
      row_blurs = b ? 1 : 0;
    }
    blur = row_blurs == 1;
  }
  if (!blur && a.stats != nullptr) a.stats->skipped_px += w;
  if (!blur && skip_idle_) {
    const RowIn& in = a.rows[y - a.first_row];
    for (int c = 0; c < 3; ++c)
      for (int x = 0; x < w; ++x) a.out[c][x] = in.ch[c][x];
    return;
  }
  for (int k = 0; k < a.row_count; ++k) {
    const int sy = a.first_row + k;
    const int dy = sy > y ? sy - y : y - sy;
    const uint32_t* iz = a.input->inverse_depth.row(sy);
    for (int x = 0; x < w; ++x) {
      const uint32_t q = (coc_.Coc(iz[x]) + 64) >> 7;  // diameter Q.8 -> radius in quarter pixels
      radius[x] = static_cast<uint16_t>(q < rcap ? q : rcap);
    }
    const RowIn& in = a.rows[k];
    for (int x = 0; x < w; ++x) {
      const size_t q = radius[x];
      const int h = half_width_[q * static_cast<size_t>(rmax + 1) + dy];
      if (h < 0) continue;
      const int x0 = x - h < 0 ? 0 : x - h, x1 = x + h + 1 > w ? w : x + h + 1;
      const int64_t wt = weight_[q];
      acc[3][x0] += wt;
      acc[3][x1] -= wt;
      for (int c = 0; c < 3; ++c) {
        const int64_t v = wt * in.ch[c][x];
        acc[c][x0] += v;
        acc[c][x1] -= v;
      }
    }
  }
  int64_t s[4] = {};
  for (int x = 0; x < w; ++x) {
    for (int k = 0; k < 4; ++k) s[k] += acc[k][x];
    const uint64_t ws = static_cast<uint64_t>(s[3]);
    for (int c = 0; c < 3; ++c) a.out[c][x] = SatU32((static_cast<uint64_t>(s[c]) + ws / 2) / ws);
  }
}

}  // namespace camsim
