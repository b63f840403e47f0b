#include "core/sensor/cfa.h"

#include "core/base/simd.h"

namespace camsim {

Status CfaStage::Configure(const CfaConfig& c, const SensorGeometry& g) {
  cfa_ = g.cfa;
  double sum = 0.0;
  for (double w : c.mono_weights) {
    if (!(w >= 0.0 && w <= 1.0)) return InvalidArgument("cfa.mono_weights", "each weight must be in [0, 1]");
    sum += w;
  }
  if (!(sum > 0.0)) return InvalidArgument("cfa.mono_weights", "weights must not all be 0");
  // Q1.16: a weight of exactly 1 (one colour alone) is 65536, which Q0.16 cannot hold.
  weight_[0] = static_cast<uint32_t>(Q<1, 16>::FromDouble(c.mono_weights[0] / sum).raw);
  weight_[2] = static_cast<uint32_t>(Q<1, 16>::FromDouble(c.mono_weights[2] / sum).raw);
  // R and B round on their own, so both can round up a half: with no G weight
  // they could sum to 65537. B gives way then, so G (the remainder) is never
  // negative.
  if (weight_[0] + weight_[2] > 65536u) weight_[2] = 65536u - weight_[0];
  weight_[1] = 65536u - weight_[0] - weight_[2];  // a flat grey stays exactly grey
  return Status::Ok();
}

Result<LineFormat> CfaStage::Plan(LineFormat in) const {
  if ((in.domain != Domain::kRadiance && in.domain != Domain::kPhotons) || in.channels != 3)
    return InvalidArgument("cfa", "needs RGB radiance or photons input");
  return LineFormat{in.domain, 1, cfa_ != Cfa::kMono};
}

namespace {

// Bayer: each row alternates two colours; a bitwise select by column parity.
// Compiled once per CPU tier (CAMSIM_CPU_CLONES): integer code, the same bits.
CAMSIM_CPU_CLONES
void BayerRow(const uint32_t* __restrict even, const uint32_t* __restrict odd, uint32_t* __restrict out, int width) {
  for (int x = 0; x < width; ++x) {
    const uint32_t odd_mask = 0u - static_cast<uint32_t>(x & 1);
    out[x] = (odd[x] & odd_mask) | (even[x] & ~odd_mask);
  }
}

}  // namespace

// Both loops are unit-stride and branch-free, with the width in a local (a
// store through out, uint32_t, could alias a.width, an int, and would make
// the compiler reload it every sample), so compilers vectorise them.
void CfaStage::ProcessRow(const RowArgs& a) const {
  const RowIn& in = a.rows[0];
  uint32_t* out = a.out[0];
  const int width = a.width;
  if (cfa_ == Cfa::kMono) {
    const uint32_t* r = in.ch[0];
    const uint32_t* g = in.ch[1];
    const uint32_t* b = in.ch[2];
    const uint64_t wr = weight_[0], wg = weight_[1], wb = weight_[2];
    for (int x = 0; x < width; ++x) {
      const uint64_t s = r[x] * wr + g[x] * wg + b[x] * wb;
      const uint64_t rounded = (s >> 16) + ((s >> 15) & 1);  // RoundShiftU(s, 16)
      // SatU32, tested on the 32-bit high half (a 64-bit compare does not
      // vectorise on every target, e.g. x86-64 without SSE4.2).
      const uint32_t high = static_cast<uint32_t>(rounded >> 32), low = static_cast<uint32_t>(rounded);
      out[x] = low | (0u - static_cast<uint32_t>(high != 0));
    }
    return;
  }
  BayerRow(in.ch[CfaColour(cfa_, 0, a.y)], in.ch[CfaColour(cfa_, 1, a.y)], out, width);
}

}  // namespace camsim
