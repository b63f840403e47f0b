#include "core/isp/demosaic.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

constexpr int kBilinearRadius = 1;
constexpr int kMalvarRadius = 2;
constexpr int kCentre = 2;  // index of row y in the 5-row window

// Both methods run one unit-stride loop over the row: at every column they
// compute what a green site needs (own colour, other colour) and what a
// red/blue site needs (green, other colour), then keep one by the column's
// parity. That is twice the arithmetic of visiting each site type in its own
// strided loop, but compilers vectorise it, which they cannot do with strided
// stores. The rows are __restrict parameters: an output row never overlaps an
// input row, so no store forces the inputs to be reloaded.
//
// The loop runs in blocks of kBlock columns with the green-site masks of one
// block in a small array: blocks start at even columns, so every block has
// the same masks and the vectorised loop loads them once instead of
// computing them from x at every column (a third of the instructions of the
// bilinear loop). The last width % kBlock columns take the same pixel
// function with the mask computed from x: the same bits either way.
// CAMSIM_CPU_CLONES adds AVX2 and AVX-512 copies (8 and 16 columns per
// vector) of each row function on x86-64; integer code, so all copies give
// the same bits.
//
// Samples are Linear Q0.16, at most 65535 (see demosaic.h): every sum below
// fits its 32-bit type.

// Columns per block: one AVX-512 vector of uint32, two AVX2 vectors, four
// SSE2/NEON vectors. Blocks of 8 kept the AVX-512 copy eight lanes wide
// (docs/performance.md, "The demosaic in blocks of sixteen"). Even, so that
// the green-site parity is the same in every block.
constexpr int kBlock = 16;

// A sample as int32 (exact: it is at most 65535).
inline int32_t S(uint32_t v) { return static_cast<int32_t>(v); }

// All ones at a green site (x of green_x's parity), else zero.
template <typename T>
T GreenMask(int x, int green_x) {
  const bool at_green = ((x ^ green_x) & 1) == 0;
  return static_cast<T>(0u - static_cast<uint32_t>(at_green));
}
// a where mask is all ones, b where it is zero. Bitwise, not ?:, so that
// compilers cannot move a load under a branch (which stops vectorisation).
template <typename T>
T Select(T mask, T a, T b) {
  return (a & mask) | (b & ~mask);
}

// One bilinear output pixel at column x; at_green = GreenMask(x, green_x).
inline void BilinearPixel(const uint32_t* __restrict up1, const uint32_t* __restrict mid,
                          const uint32_t* __restrict down1, int x, uint32_t at_green, uint32_t* __restrict own,
                          uint32_t* __restrict green, uint32_t* __restrict other) {
  const uint32_t c = mid[x];
  const uint32_t w1 = mid[x - 1] + mid[x + 1];
  const uint32_t n1 = up1[x] + down1[x];
  const uint32_t diagonals = up1[x - 1] + up1[x + 1] + down1[x - 1] + down1[x + 1];
  // Green site: own colour from W/E, other from N/S (a mean of 2 as
  // (2 sum + 2) >> 2, i.e. (sum + 1) >> 1). Red/blue site: green from the 4
  // nearest, other colour from the diagonals.
  const uint32_t first = (Select(at_green, 2 * w1, w1 + n1) + 2) >> 2;
  const uint32_t second = (Select(at_green, 2 * n1, diagonals) + 2) >> 2;
  own[x] = Select(at_green, first, c);
  green[x] = Select(at_green, c, first);
  other[x] = second;
}

CAMSIM_CPU_CLONES
void BilinearRow(const uint32_t* /*up2*/, const uint32_t* __restrict up1, const uint32_t* __restrict mid,
                 const uint32_t* __restrict down1, const uint32_t* /*down2*/, int width, int green_x,
                 uint32_t* __restrict own, uint32_t* __restrict green, uint32_t* __restrict other) {
  uint32_t mask[kBlock];
  for (int k = 0; k < kBlock; ++k) mask[k] = GreenMask<uint32_t>(k, green_x);
  int x0 = 0;
  for (; x0 + kBlock <= width; x0 += kBlock)
    for (int k = 0; k < kBlock; ++k) BilinearPixel(up1, mid, down1, x0 + k, mask[k], own, green, other);
  for (int x = x0; x < width; ++x)
    BilinearPixel(up1, mid, down1, x, GreenMask<uint32_t>(x, green_x), own, green, other);
}

// Malvar: weights are 16 times the estimate; one rounding, then the Q0.16 range.
inline uint32_t Finish(int32_t sum16) {
  const int32_t v = (sum16 + 8) >> 4;  // RoundShift by 4; >> of a negative int is floor in C++20
  return static_cast<uint32_t>(v < 0 ? 0 : (v > 65535 ? 65535 : v));
}

// One Malvar output pixel at column x; at_green = GreenMask(x, green_x).
inline void MalvarPixel(const uint32_t* __restrict up2, const uint32_t* __restrict up1,
                        const uint32_t* __restrict mid, const uint32_t* __restrict down1,
                        const uint32_t* __restrict down2, int x, int32_t at_green, uint32_t* __restrict own,
                        uint32_t* __restrict green, uint32_t* __restrict other) {
  // The sums the kernels are made of (each at most 4 * 65535).
  const int32_t c = S(mid[x]);
  const int32_t w1 = S(mid[x - 1]) + S(mid[x + 1]);
  const int32_t w2 = S(mid[x - 2]) + S(mid[x + 2]);
  const int32_t n1 = S(up1[x]) + S(down1[x]);
  const int32_t n2 = S(up2[x]) + S(down2[x]);
  const int32_t diagonals = S(up1[x - 1]) + S(up1[x + 1]) + S(down1[x - 1]) + S(down1[x + 1]);
  // Green site: own colour along the row, other colour along the column.
  // Red/blue site: green, and the other colour from the diagonals.
  const int32_t first = Select(at_green, 10 * c + 8 * w1 - 2 * w2 - 2 * diagonals + n2,
                               8 * c + 4 * (n1 + w1) - 2 * (n2 + w2));
  const int32_t second = Select(at_green, 10 * c + 8 * n1 - 2 * n2 - 2 * diagonals + w2,
                                12 * c + 4 * diagonals - 3 * (n2 + w2));
  const uint32_t estimate = Finish(first);
  own[x] = Select(static_cast<uint32_t>(at_green), estimate, mid[x]);
  green[x] = Select(static_cast<uint32_t>(at_green), mid[x], estimate);
  other[x] = Finish(second);
}

CAMSIM_CPU_CLONES
void MalvarRow(const uint32_t* __restrict up2, const uint32_t* __restrict up1, const uint32_t* __restrict mid,
               const uint32_t* __restrict down1, const uint32_t* __restrict down2, int width, int green_x,
               uint32_t* __restrict own, uint32_t* __restrict green, uint32_t* __restrict other) {
  int32_t mask[kBlock];
  for (int k = 0; k < kBlock; ++k) mask[k] = GreenMask<int32_t>(k, green_x);
  int x0 = 0;
  for (; x0 + kBlock <= width; x0 += kBlock)
    for (int k = 0; k < kBlock; ++k) MalvarPixel(up2, up1, mid, down1, down2, x0 + k, mask[k], own, green, other);
  for (int x = x0; x < width; ++x)
    MalvarPixel(up2, up1, mid, down1, down2, x, GreenMask<int32_t>(x, green_x), own, green, other);
}

}  // namespace

Status DemosaicStage::Configure(const DemosaicConfig& c, const SensorGeometry& g) {
  // A value outside the enum would map every site to green, and the row
  // functions' three __restrict output rows to the same row.
  if (g.cfa > Cfa::kBayerBG)
    return InvalidArgument("sensor.cfa", "must be Mono, BayerRG, BayerGR, BayerGB or BayerBG");
  switch (c.method) {
    case DemosaicMethod::kBilinear:
      radius_ = kBilinearRadius;
      row_fn_ = BilinearRow;
      break;
    case DemosaicMethod::kMalvar:
      radius_ = kMalvarRadius;
      row_fn_ = MalvarRow;
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
  row_fn_(rows[0], rows[1], rows[2], rows[3], rows[4], a.width, green_x, a.out[own], a.out[kGreen], a.out[other]);
}

}  // namespace camsim
