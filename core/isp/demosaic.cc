#include "core/isp/demosaic.h"

namespace camsim {
namespace {

using Rows = const uint32_t* const*;  // rows[2] is the output row

constexpr int kBilinearRadius = 1;
constexpr int kMalvarRadius = 2;
constexpr int kCentre = 2;  // index of row y in the 5-row window

struct Bilinear {
  static uint32_t GreenAtRb(Rows r, int x) {
    const int64_t sum = int64_t{r[1][x]} + r[3][x] + r[2][x - 1] + r[2][x + 1];
    return static_cast<uint32_t>(RoundShift(sum, 2));
  }
  static uint32_t Horizontal(Rows r, int x) {
    return static_cast<uint32_t>(RoundShift(int64_t{r[2][x - 1]} + r[2][x + 1], 1));
  }
  static uint32_t Vertical(Rows r, int x) {
    return static_cast<uint32_t>(RoundShift(int64_t{r[1][x]} + r[3][x], 1));
  }
  static uint32_t Diagonal(Rows r, int x) {
    const int64_t sum = int64_t{r[1][x - 1]} + r[1][x + 1] + r[3][x - 1] + r[3][x + 1];
    return static_cast<uint32_t>(RoundShift(sum, 2));
  }
};

struct Malvar {
  // Weights are 16 times the estimate: one rounding, then the Q0.16 range.
  static uint32_t Finish(int64_t sum16) {
    return static_cast<uint32_t>(Clamp64(RoundShift(sum16, 4), 0, 65535));
  }
  static int64_t Diagonals(Rows r, int x) {
    return int64_t{r[1][x - 1]} + r[1][x + 1] + r[3][x - 1] + r[3][x + 1];
  }
  static uint32_t GreenAtRb(Rows r, int x) {
    const int64_t near = int64_t{r[1][x]} + r[3][x] + r[2][x - 1] + r[2][x + 1];
    const int64_t far = int64_t{r[0][x]} + r[4][x] + r[2][x - 2] + r[2][x + 2];
    return Finish(8 * int64_t{r[2][x]} + 4 * near - 2 * far);
  }
  static uint32_t Horizontal(Rows r, int x) {
    const int64_t along = int64_t{r[2][x - 1]} + r[2][x + 1];
    const int64_t along2 = int64_t{r[2][x - 2]} + r[2][x + 2];
    const int64_t across2 = int64_t{r[0][x]} + r[4][x];
    return Finish(10 * int64_t{r[2][x]} + 8 * along - 2 * along2 - 2 * Diagonals(r, x) + across2);
  }
  static uint32_t Vertical(Rows r, int x) {
    const int64_t along = int64_t{r[1][x]} + r[3][x];
    const int64_t along2 = int64_t{r[0][x]} + r[4][x];
    const int64_t across2 = int64_t{r[2][x - 2]} + r[2][x + 2];
    return Finish(10 * int64_t{r[2][x]} + 8 * along - 2 * along2 - 2 * Diagonals(r, x) + across2);
  }
  static uint32_t Diagonal(Rows r, int x) {
    const int64_t far = int64_t{r[0][x]} + r[4][x] + r[2][x - 2] + r[2][x + 2];
    return Finish(12 * int64_t{r[2][x]} + 4 * Diagonals(r, x) - 3 * far);
  }
};

// Green sites and non-green sites in two strided loops: no per-pixel branch.
template <typename K>
void DemosaicRow(Rows r, int width, int green_x, uint32_t* own, uint32_t* green, uint32_t* other) {
  for (int x = green_x; x < width; x += 2) {
    green[x] = r[kCentre][x];
    own[x] = K::Horizontal(r, x);
    other[x] = K::Vertical(r, x);
  }
  for (int x = 1 - green_x; x < width; x += 2) {
    own[x] = r[kCentre][x];
    green[x] = K::GreenAtRb(r, x);
    other[x] = K::Diagonal(r, x);
  }
}

}  // namespace

Status DemosaicStage::Configure(const DemosaicConfig& c, const SensorGeometry& g) {
  switch (c.method) {
    case DemosaicMethod::kBilinear:
      radius_ = kBilinearRadius;
      row_fn_ = DemosaicRow<Bilinear>;
      break;
    case DemosaicMethod::kMalvar:
      radius_ = kMalvarRadius;
      row_fn_ = DemosaicRow<Malvar>;
      break;
    default: return InvalidArgument("demosaic.method", "must be bilinear or malvar");
  }
  cfa_ = g.cfa;
  return Status::Ok();
}

const char* DemosaicStage::IdentityReason() const {
  return cfa_ == Cfa::kMono ? "sensor.cfa is Mono: there is no mosaic to interpolate" : nullptr;
}

Result<LineFormat> DemosaicStage::Plan(LineFormat in) const {
  if (cfa_ == Cfa::kMono)
    return InvalidArgument("demosaic", "demosaic needs a Bayer mosaic; the CFA is mono");
  if (in.channels != 1 || !in.mosaic)
    return InvalidArgument("demosaic", "demosaic needs a 1-channel Bayer mosaic input");
  if (in.domain != Domain::kLinear)
    return InvalidArgument("demosaic", "demosaic needs linear input (after black_level)");
  return LineFormat{Domain::kLinear, 3, false};
}

void DemosaicStage::ProcessRow(const RowArgs& a) const {
  const uint32_t* rows[2 * kMalvarRadius + 1] = {};
  for (int k = -radius_; k <= radius_; ++k) rows[kCentre + k] = a.rows[radius_ + k].ch[0];
  const int green_x = CfaColour(cfa_, 0, a.y) == kGreen ? 0 : 1;
  const Colour own = CfaColour(cfa_, 1 - green_x, a.y);
  const Colour other = own == kRed ? kBlue : kRed;
  row_fn_(rows, a.width, green_x, a.out[own], a.out[kGreen], a.out[other]);
}

}  // namespace camsim
