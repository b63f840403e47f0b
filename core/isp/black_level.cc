#include "core/isp/black_level.h"

namespace camsim {
namespace {

constexpr int64_t kMaxQ16 = 65535;

}  // namespace

Status BlackLevelStage::Configure(const BlackLevelConfig& c, const SensorGeometry& g,
                                  double sensor_black_level_dn) {
  if (g.adc_bits < 8 || g.adc_bits > 16) return InvalidArgument("sensor.adc_bits", "must be 8 to 16");
  const double max_dn = static_cast<double>((1 << g.adc_bits) - 1);
  const bool from_sensor = c.black_level_dn == -1.0;
  const double bl = from_sensor ? sensor_black_level_dn : c.black_level_dn;
  if (!(bl >= 0.0 && bl <= max_dn - 1.0)) {
    if (from_sensor) return InvalidArgument("sensor.black_level_dn", "must be in [0, 2^adc_bits - 2]");
    return InvalidArgument("black_level.black_level_dn",
                           "must be -1 (the sensor's) or in [0, 2^adc_bits - 2] DN");
  }
  // 65535 / (max - BL) is in [1, 65535]: always a valid UScale.
  Result<UScale> s =
      UScale::FromDouble(static_cast<double>(kMaxQ16) / (max_dn - bl), "black_level.black_level_dn");
  if (!s.ok()) return s.status();
  black_level_ = bl;
  max_dn_ = static_cast<uint32_t>(max_dn);
  scale_ = s.value();
  // BL * mant < 2^48: exact for an integer BL; + 0.5 and truncation round a positive value.
  offset_ = static_cast<int64_t>(bl * static_cast<double>(scale_.mant) + 0.5);
  return Status::Ok();
}

Result<LineFormat> BlackLevelStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kDigital) return InvalidArgument("black_level", "needs digital (DN) input");
  return LineFormat{Domain::kLinear, in.channels, in.mosaic};
}

void BlackLevelStage::ProcessRow(const RowArgs& a) const {
  const int channels = a.out[1] != nullptr ? 3 : 1;
  const int64_t mant = scale_.mant;
  for (int c = 0; c < channels; ++c) {
    const uint32_t* in = a.rows[0].ch[c];
    uint32_t* out = a.out[c];
    for (int x = 0; x < a.width; ++x) {
      const int64_t dn = in[x] < max_dn_ ? in[x] : max_dn_;
      out[x] = static_cast<uint32_t>(Clamp64(RoundShift(dn * mant - offset_, scale_.shift), 0, kMaxQ16));
    }
  }
}

}  // namespace camsim
