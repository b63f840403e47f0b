#include "core/isp/color_matrix.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

using Coefficient = Q<5, ColorMatrixStage::kFracBits, true>;
using RowSum = Q<7, ColorMatrixStage::kFracBits, true>;  // 3 * 16 < 2^7; 7 + 24 + sign = 32 bits
constexpr int32_t kMaxRaw = 16 << ColorMatrixStage::kFracBits;
constexpr int32_t kOneRaw = 1 << ColorMatrixStage::kFracBits;

// One output channel of a row: Clamp(RoundShift(mr r + mg g + mb b, 24), 0,
// 65535). Coefficients are at most 2^28 and samples at most 65535 in
// magnitude (color_matrix.h), so each product is one of two int32 factors
// (a 32x32->64-bit multiply, which compilers vectorise) and the sum fits
// int64. Compiled per CPU tier (CAMSIM_CPU_CLONES): integer code, the same
// bits. A function of its own, with the width a parameter: in ProcessRow a
// store through out (uint32_t) could alias a.width (an int).
CAMSIM_CPU_CLONES
void MatrixRow(int32_t mr, int32_t mg, int32_t mb, const uint32_t* __restrict r, const uint32_t* __restrict g,
               const uint32_t* __restrict b, uint32_t* __restrict out, int width) {
  for (int x = 0; x < width; ++x) {
    const int64_t sum = int64_t{mr} * static_cast<int32_t>(r[x]) + int64_t{mg} * static_cast<int32_t>(g[x]) +
                        int64_t{mb} * static_cast<int32_t>(b[x]);
    const int64_t v = RoundShift(sum, ColorMatrixStage::kFracBits);
    out[x] = static_cast<uint32_t>(v < 0 ? 0 : (v > 65535 ? 65535 : v));
  }
}

}  // namespace

Status ColorMatrixStage::Configure(const ColorMatrixConfig& c, const SensorGeometry& geometry) {
  mono_ = geometry.cfa == Cfa::kMono;
  for (double v : c.m)
    if (!(v >= -kMaxCoefficient && v <= kMaxCoefficient))
      return InvalidArgument("color_matrix.m", "each coefficient must be in [-16, 16]");
  int32_t q[9];
  for (int i = 0; i < 3; ++i) {
    const double* row = c.m + 3 * i;
    const int32_t sum = RowSum::FromDouble(row[0] + row[1] + row[2]).raw;
    int32_t off_diagonal = 0;
    for (int j = 0; j < 3; ++j) {
      if (j == i) continue;
      q[3 * i + j] = Coefficient::FromDouble(row[j]).raw;
      off_diagonal += q[3 * i + j];
    }
    const int32_t diagonal = sum - off_diagonal;
    if (diagonal < -kMaxRaw || diagonal > kMaxRaw)
      return InvalidArgument("color_matrix.m",
                             "a row is not representable: its diagonal leaves [-16, 16] once it takes "
                             "the row's rounding remainder");
    q[4 * i] = diagonal;
  }
  for (int i = 0; i < 9; ++i) q_[i] = q[i];
  return Status::Ok();
}

Result<LineFormat> ColorMatrixStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kLinear || in.channels != 3)
    return InvalidArgument("color_matrix", "needs 3-channel linear RGB (after demosaic)");
  return in;
}

const char* ColorMatrixStage::IdentityReason() const {
  if (mono_) return "sensor.cfa is Mono: there is no colour to correct";
  for (int i = 0; i < 9; ++i)
    if (q_[i] != (i % 4 == 0 ? kOneRaw : 0)) return nullptr;
  return "colour matrix is the identity";
}

void ColorMatrixStage::ProcessRow(const RowArgs& a) const {
  const uint32_t* r = a.rows[0].ch[0];
  const uint32_t* g = a.rows[0].ch[1];
  const uint32_t* b = a.rows[0].ch[2];
  for (int i = 0; i < 3; ++i) MatrixRow(q_[3 * i], q_[3 * i + 1], q_[3 * i + 2], r, g, b, a.out[i], a.width);
}

}  // namespace camsim
