#include "core/lens/vignetting.h"

#include "core/pipeline/pipeline.h"

namespace camsim {
namespace {

constexpr double kMaxGain = 4.0 - 1.0 / 16384.0;  // Q2.14 ceiling
constexpr int kGainFracBits = VignettingStage::kGainFracBits;
// Columns whose curve gains are computed at once, then applied to every
// channel: 1 KiB of stack.
constexpr int kGainBlock = 256;

uint64_t Denominator(const SensorGeometry& g) {
  const uint64_t w = static_cast<uint64_t>(g.width - 1), h = static_cast<uint64_t>(g.height - 1);
  return w * w + h * h;
}

double Rho(const SensorGeometry& g, int x, int y) {
  const uint64_t den = Denominator(g);
  if (den == 0) return 0.0;
  const double dx = 2.0 * x - (g.width - 1), dy = 2.0 * y - (g.height - 1);
  return (dx * dx + dy * dy) / static_cast<double>(den);
}

double CurveGainOf(const VignettingConfig& c, const SensorGeometry& g, double rho) {
  if (c.mode == VignettingMode::kCos4) {
    // r^2 in pixels: rho * ((W-1)^2 + (H-1)^2) / 4.
    const double r2 = rho * static_cast<double>(Denominator(g)) / 4.0;
    const double t = 1.0 + r2 / (c.focal_length_px * c.focal_length_px);
    return 1.0 / (t * t);
  }
  if (c.mode == VignettingMode::kTable) {
    const double pos = rho * (c.table_count - 1);
    int i = static_cast<int>(pos);
    if (i >= c.table_count - 1) return c.table[c.table_count - 1];
    const double f = pos - i;
    return c.table[i] + (c.table[i + 1] - c.table[i]) * f;
  }
  return 1.0;
}

// out[x] = SatU32(RoundShiftU(in[x] * g, 14)) with g = gain[x], or
// gain[n - 1 - x] when Reversed, in a form compilers vectorise: a gain is
// Q2.14 below 2^16, so the product is below 2^48 and adding the rounding half
// cannot overflow; the saturation is tested on the 32-bit high half (a 64-bit
// compare does not vectorise on every target, e.g. x86-64 without SSE4.2).
template <bool Reversed, typename Gain>
void ApplyGains(const uint32_t* __restrict in, const Gain* __restrict gain, uint32_t* __restrict out, int n) {
  for (int x = 0; x < n; ++x) {
    const uint64_t t = uint64_t{in[x]} * gain[Reversed ? n - 1 - x : x] + (1u << (kGainFracBits - 1));
    const uint32_t high = static_cast<uint32_t>(t >> (32 + kGainFracBits));
    const uint32_t low = static_cast<uint32_t>(t >> kGainFracBits);
    out[x] = low | (0u - static_cast<uint32_t>(high != 0));
  }
}

}  // namespace

double ReferenceVignettingGain(const VignettingConfig& c, const SensorGeometry& g, int x, int y) {
  return CurveGainOf(c, g, Rho(g, x, y));
}

Status BuildVignettingCurve(const VignettingConfig& c, const SensorGeometry& g, uint16_t* curve,
                            UScale* rho_to_index) {
  constexpr int kPoints = VignettingStage::kCurvePoints;
  for (int i = 0; i < kPoints; ++i) {
    const double gain = CurveGainOf(c, g, static_cast<double>(i) / (kPoints - 1));
    curve[i] = static_cast<uint16_t>(Q<2, 14>::FromDouble(gain).raw);
  }
  curve[kPoints] = curve[kPoints - 1];  // lets rho == 1 interpolate without a branch
  *rho_to_index = UScale{};
  // Index scale: (kCurvePoints - 1) * 2^16 / denominator; denominator < 2^31 for frames < 32768 px.
  const uint64_t den = Denominator(g);
  if (den > 0) {
    Result<UScale> s = UScale::FromDouble((kPoints - 1) * 65536.0 / static_cast<double>(den), "sensor.width");
    if (!s.ok()) return s.status();
    *rho_to_index = s.value();
  }
  return Status::Ok();
}

double VignettingStage::CurveGain(double rho) const { return CurveGainOf(config_, geometry_, rho); }

Status VignettingStage::Configure(const VignettingConfig& c, const SensorGeometry& g, bool has_mask) {
  config_ = c;
  geometry_ = g;
  switch (c.mode) {
    case VignettingMode::kOff:
      break;
    case VignettingMode::kCos4:
      if (!(c.focal_length_px >= 1.0 && c.focal_length_px <= 1e6))
        return InvalidArgument("vignetting.focal_length_px", "must be in [1, 1e6] pixels for cos4");
      break;
    case VignettingMode::kTable:
      if (c.table_count < 2 || c.table_count > VignettingConfig::kMaxTable)
        return InvalidArgument("vignetting.table", "needs 2 to 64 gains (centre to corner)");
      for (int i = 0; i < c.table_count; ++i)
        if (!(c.table[i] >= 0.0 && c.table[i] <= kMaxGain))
          return InvalidArgument("vignetting.table", "gains must be in [0, 3.9999]");
      break;
    case VignettingMode::kMask:
      if (!has_mask) return InvalidArgument("vignetting.mask", "mode 'mask' needs a mask image");
      break;
    default: return InvalidArgument("vignetting.mode", "must be off, cos4, table or mask");
  }
  // Index scale: (kCurvePoints - 1) * 2^16 / denominator; denominator < 2^31 for frames < 32768 px.
  const uint64_t den = Denominator(g);
  if (den > 0) {
    Result<UScale> s = UScale::FromDouble((kCurvePoints - 1) * 65536.0 / static_cast<double>(den),
                                          "sensor.width");
    if (!s.ok()) return s.status();
    rho_to_index_ = s.value();
  }
  return Status::Ok();
}

Result<LineFormat> VignettingStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kPhotons) return InvalidArgument("vignetting", "needs photons input");
  return in;
}

const char* VignettingStage::IdentityReason() const {
  if (config_.mode == VignettingMode::kOff) return "vignetting.mode is off";
  if (config_.mode == VignettingMode::kTable) {
    for (int i = 0; i < config_.table_count; ++i)
      if (config_.table[i] != 1.0) return nullptr;
    return "vignetting table is flat 1.0";
  }
  return nullptr;
}

void VignettingStage::CountTables(WorkspaceCounter& counter) const {
  counter.Add<uint16_t>(kCurvePoints + 1);
  counter.Add<uint32_t>(static_cast<size_t>(geometry_.width));
}

Status VignettingStage::Init(Arena& tables) {
  curve_ = tables.Take<uint16_t>(kCurvePoints + 1);
  dx2_ = tables.Take<uint32_t>(static_cast<size_t>(geometry_.width));
  if (curve_ == nullptr || dx2_ == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for vignetting tables");
  UScale unused;
  CAMSIM_TRY(BuildVignettingCurve(config_, geometry_, curve_, &unused));
  for (int x = 0; x < geometry_.width; ++x) {
    const int64_t d = 2 * static_cast<int64_t>(x) - (geometry_.width - 1);
    dx2_[x] = static_cast<uint32_t>(d * d);
  }
  return Status::Ok();
}

void VignettingStage::ProcessRow(const RowArgs& a) const {
  const RowIn& in = a.rows[0];
  // Channels: 3 (colour) or 1 (mosaic); the gain does not depend on colour.
  int channels = 0;
  while (channels < kMaxChannels && a.out[channels] != nullptr) ++channels;
  if (config_.mode == VignettingMode::kMask) {
    const uint16_t* mask = a.input->vignetting_mask.row(a.y);
    for (int c = 0; c < channels; ++c) ApplyGains<false>(in.ch[c], mask, a.out[c], a.width);
    return;
  }
  // The curve gain depends on x only through dx2, which is symmetric about
  // the centre: gains are computed for blocks of the left half [0, half) and
  // applied to each block and to its mirror image in the right half (for an
  // odd width the centre column is its own mirror, written twice alike).
  CAMSIM_DCHECK(a.width == geometry_.width);
  const int64_t dy = 2 * static_cast<int64_t>(a.y) - (geometry_.height - 1);
  const uint32_t dy2 = static_cast<uint32_t>(dy * dy);
  const int width = a.width, half = (a.width + 1) / 2;
  uint32_t gain[kGainBlock];
  for (int x0 = 0; x0 < half; x0 += kGainBlock) {
    const int n = half - x0 < kGainBlock ? half - x0 : kGainBlock;
    for (int k = 0; k < n; ++k) {
      gain[k] = VignettingCurveGain(curve_, rho_to_index_, dx2_[x0 + k] + dy2);
    }
    const int mirror = width - x0 - n;  // columns mirror .. width - 1 - x0, gains reversed
    for (int c = 0; c < channels; ++c) {
      ApplyGains<false>(in.ch[c] + x0, gain, a.out[c] + x0, n);
      ApplyGains<true>(in.ch[c] + mirror, gain, a.out[c] + mirror, n);
    }
  }
}

}  // namespace camsim
