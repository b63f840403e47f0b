#include "core/sensor/cfa.h"

namespace camsim {

Status CfaStage::Configure(const CfaConfig& c, const SensorGeometry& g) {
  cfa_ = g.cfa;
  double sum = 0.0;
  for (double w : c.mono_weights) {
    if (!(w >= 0.0 && w <= 1.0)) return InvalidArgument("cfa.mono_weights", "each weight must be in [0, 1]");
    sum += w;
  }
  if (!(sum > 0.0)) return InvalidArgument("cfa.mono_weights", "weights must not all be 0");
  weight_[0] = Q<0, 16>::FromDouble(c.mono_weights[0] / sum).raw;
  weight_[2] = Q<0, 16>::FromDouble(c.mono_weights[2] / sum).raw;
  weight_[1] = 65536u - weight_[0] - weight_[2];  // a flat grey stays exactly grey
  return Status::Ok();
}

Result<LineFormat> CfaStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kPhotons || in.channels != 3)
    return InvalidArgument("cfa", "needs RGB photons input");
  return LineFormat{Domain::kPhotons, 1, cfa_ != Cfa::kMono};
}

void CfaStage::ProcessRow(const RowArgs& a) const {
  const RowIn& in = a.rows[0];
  uint32_t* out = a.out[0];
  if (cfa_ == Cfa::kMono) {
    for (int x = 0; x < a.width; ++x) {
      const uint64_t s = static_cast<uint64_t>(in.ch[0][x]) * weight_[0] +
                         static_cast<uint64_t>(in.ch[1][x]) * weight_[1] +
                         static_cast<uint64_t>(in.ch[2][x]) * weight_[2];
      out[x] = SatU32(RoundShiftU(s, 16));
    }
    return;
  }
  // Bayer: each row alternates two colours; copy even and odd columns.
  const uint32_t* even = in.ch[CfaColour(cfa_, 0, a.y)];
  const uint32_t* odd = in.ch[CfaColour(cfa_, 1, a.y)];
  int x = 0;
  for (; x + 1 < a.width; x += 2) {
    out[x] = even[x];
    out[x + 1] = odd[x + 1];
  }
  if (x < a.width) out[x] = even[x];
}

}  // namespace camsim
