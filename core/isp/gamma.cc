#include "core/isp/gamma.h"

#include "core/base/detmath.h"

namespace camsim {
namespace {

constexpr double kFullScale = 65535.0;
constexpr uint32_t kMaxCode = 65535;

// IEC 61966-2-1 (sRGB) encoding constants.
constexpr double kSrgbLinearLimit = 0.0031308;
constexpr double kSrgbSlope = 12.92;
constexpr double kSrgbScale = 1.055;
constexpr double kSrgbOffset = 0.055;
constexpr double kSrgbExponent = 1.0 / 2.4;

}  // namespace

Status GammaStage::Configure(const GammaConfig& c, const SensorGeometry& /*geometry*/) {
  if (c.curve != GammaCurve::kLinear && c.curve != GammaCurve::kSrgb && c.curve != GammaCurve::kPower)
    return InvalidArgument("gamma.curve", "must be linear, srgb or power");
  if (!(c.gamma >= kMinGamma && c.gamma <= kMaxGamma))
    return InvalidArgument("gamma.gamma", "must be in [0.1, 10]");
  config_ = c;
  return Status::Ok();
}

Result<LineFormat> GammaStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kLinear) return InvalidArgument("gamma", "needs linear input");
  return LineFormat{Domain::kEncoded, in.channels, in.mosaic};
}

const char* GammaStage::IdentityReason() const {
  return config_.curve == GammaCurve::kLinear ? "gamma curve is linear" : nullptr;
}

double GammaStage::Curve(double v) const {
  switch (config_.curve) {
    case GammaCurve::kLinear: return v;
    case GammaCurve::kSrgb:
      return v <= kSrgbLinearLimit ? kSrgbSlope * v
                                   : kSrgbScale * detmath::Pow(v, kSrgbExponent) - kSrgbOffset;
    case GammaCurve::kPower: return detmath::Pow(v, 1.0 / config_.gamma);
  }
  return v;
}

void GammaStage::CountTables(WorkspaceCounter& counter) const { counter.Add<uint16_t>(kTableSize); }

Status GammaStage::Init(Arena& tables) {
  table_ = tables.Take<uint16_t>(kTableSize);
  if (table_ == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for the gamma table");
  for (size_t i = 0; i < kTableSize; ++i) {
    double t = Curve(static_cast<double>(i) / kFullScale) * kFullScale;
    t = t < 0.0 ? 0.0 : (t > kFullScale ? kFullScale : t);
    table_[i] = static_cast<uint16_t>(t + 0.5);  // round to nearest, ties up
  }
  return Status::Ok();
}

void GammaStage::ProcessRow(const RowArgs& a) const {
  const int channels = a.out[1] != nullptr ? 3 : 1;
  // Locals: a store through out (uint32_t) could alias a.width (int), and
  // would make the compiler reload it every sample.
  const uint16_t* table = table_;
  const int width = a.width;
  for (int c = 0; c < channels; ++c) {
    const uint32_t* in = a.rows[0].ch[c];
    uint32_t* out = a.out[c];
    for (int x = 0; x < width; ++x) out[x] = table[in[x] < kMaxCode ? in[x] : kMaxCode];
  }
}

}  // namespace camsim
