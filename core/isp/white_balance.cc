#include "core/isp/white_balance.h"

namespace camsim {
namespace {

constexpr uint32_t kMaxQ16 = 65535;

uint32_t Sat16(uint32_t v) { return v < kMaxQ16 ? v : kMaxQ16; }

}  // namespace

Status WhiteBalanceStage::Configure(const WhiteBalanceConfig& c, const SensorGeometry& g) {
  for (double gain : c.gain)
    if (!(gain >= 0.0 && gain <= kMaxGain))
      return InvalidArgument("white_balance.gain", "must be in [0, 16]");
  for (int i = 0; i < 3; ++i) {
    Result<UScale> s = UScale::FromDouble(c.gain[i], "white_balance.gain");
    if (!s.ok()) return s.status();
    gain_[i] = s.value();
  }
  cfa_ = g.cfa;
  return Status::Ok();
}

Result<LineFormat> WhiteBalanceStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kLinear)
    return InvalidArgument("white_balance", "needs linear input (after black_level)");
  return in;
}

const char* WhiteBalanceStage::IdentityReason() const {
  // A UScale of exactly 1 (2^31 * 2^-31) returns every sample unchanged.
  const UScale one = UScale::FromDouble(1.0, "").value();
  for (const UScale& s : gain_)
    if (s.mant != one.mant || s.shift != one.shift) return nullptr;
  return "white-balance gains are all 1";
}

void WhiteBalanceStage::ProcessRow(const RowArgs& a) const {
  if (a.out[1] != nullptr) {
    for (int c = 0; c < 3; ++c) {
      const uint32_t* in = a.rows[0].ch[c];
      uint32_t* out = a.out[c];
      const UScale s = gain_[c];
      for (int x = 0; x < a.width; ++x) out[x] = Sat16(s.Apply(in[x]));
    }
    return;
  }
  // One channel: the colour alternates with x parity along a row.
  const UScale s[2] = {gain_[CfaColour(cfa_, 0, a.y)], gain_[CfaColour(cfa_, 1, a.y)]};
  const uint32_t* in = a.rows[0].ch[0];
  uint32_t* out = a.out[0];
  for (int x = 0; x < a.width; ++x) out[x] = Sat16(s[x & 1].Apply(in[x]));
}

}  // namespace camsim
