#include "core/isp/white_balance.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

constexpr uint32_t kMaxQ16 = 65535;

uint32_t Sat16(uint32_t v) { return v < kMaxQ16 ? v : kMaxQ16; }

// Sat16(UScale{mant, shift}.Apply(v)) for a shift in [1, 63], bit for bit,
// with the saturation tests on 32-bit halves (a 64-bit compare does not
// vectorise on every target, e.g. x86-64 without SSE4.2).
inline uint32_t ApplySat(uint32_t v, uint32_t mant, int shift, uint32_t clip) {
  const uint64_t p = uint64_t{v} * mant;
  const uint64_t r = (p >> shift) + ((p >> (shift - 1)) & 1);  // RoundShiftU(p, shift)
  const uint32_t high = static_cast<uint32_t>(r >> 32), low = static_cast<uint32_t>(r);
  return high != 0 || low > clip ? clip : low;
}

// out[x] = min(gain.Apply(in[x]), clip), gain = even at even x and odd at odd
// x. One loop over column pairs: each of its two statements has a uniform
// shift, so compilers vectorise it (with an even/odd interleave). Also
// compiled for AVX2 (CAMSIM_CPU_CLONES; integer code, same bits).
CAMSIM_CPU_CLONES
void GainRow(UScale even, UScale odd, uint32_t clip, const uint32_t* __restrict in, uint32_t* __restrict out,
             int width) {
  if (even.shift < 1 || even.shift > 63 || odd.shift < 1 || odd.shift > 63) {  // gain 0 or < 2^-32
    for (int x = 0; x < width; ++x) {
      const uint32_t v = Sat16(((x & 1) != 0 ? odd : even).Apply(in[x]));
      out[x] = v < clip ? v : clip;
    }
    return;
  }
  int x = 0;
  for (; x + 1 < width; x += 2) {
    out[x] = ApplySat(in[x], even.mant, even.shift, clip);
    out[x + 1] = ApplySat(in[x + 1], odd.mant, odd.shift, clip);
  }
  if (x < width) out[x] = ApplySat(in[x], even.mant, even.shift, clip);
}

}  // namespace

double WhiteLevel(double saturation_dn, double black_level_dn, int adc_bits) {
  const double range = ((1 << adc_bits) - 1) - black_level_dn;
  if (!(range > 0.0)) return 1.0;
  const double w = (saturation_dn - black_level_dn) / range;
  return w < 0.0 ? 0.0 : (w > 1.0 ? 1.0 : w);
}

double WhiteBalanceClip(const WhiteBalanceConfig& c, Cfa cfa, double white_level) {
  double min_gain = 0.0;
  for (int colour = 0; colour < 3; ++colour) {
    const double gain = c.gain[colour];
    if (cfa == Cfa::kMono && colour != kGreen) continue;  // a mono sensor takes the G gain only
    if (gain > 0.0 && (min_gain == 0.0 || gain < min_gain)) min_gain = gain;
  }
  const double clip = (min_gain > 0.0 ? min_gain : 1.0) * white_level * kMaxQ16;
  return clip < kMaxQ16 ? clip : kMaxQ16;
}

Status WhiteBalanceStage::Configure(const WhiteBalanceConfig& c, const SensorGeometry& g, double white_level) {
  for (double gain : c.gain)
    if (!(gain >= 0.0 && gain <= kMaxGain))
      return InvalidArgument("white_balance.gain", "must be in [0, 16]");
  for (int i = 0; i < 3; ++i) {
    Result<UScale> s = UScale::FromDouble(c.gain[i], "white_balance.gain");
    if (!s.ok()) return s.status();
    gain_[i] = s.value();
  }
  // Round half up; the clip is at most 65535 (WhiteBalanceClip caps it).
  clip_ = static_cast<uint32_t>(WhiteBalanceClip(c, g.cfa, white_level) + 0.5);
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
    for (int c = 0; c < 3; ++c) GainRow(gain_[c], gain_[c], clip_, a.rows[0].ch[c], a.out[c], a.width);
    return;
  }
  // One channel: the colour alternates with x parity along a row.
  GainRow(gain_[CfaColour(cfa_, 0, a.y)], gain_[CfaColour(cfa_, 1, a.y)], clip_, a.rows[0].ch[0], a.out[0], a.width);
}

}  // namespace camsim
