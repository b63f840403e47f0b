#include "core/isp/black_level.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

constexpr uint32_t kMaxQ16 = 65535;

}  // namespace

Status BlackLevelStage::Configure(const BlackLevelConfig& c, const SensorGeometry& g,
                                  double sensor_black_level_dn) {
  if (g.adc_bits < 8 || g.adc_bits > 16) return InvalidArgument("sensor.adc_bits", "must be 8 to 16");
  const double max_dn = static_cast<double>((1 << g.adc_bits) - 1);
  const bool from_sensor = c.black_level_dn == -1.0;
  const double bl = BlackLevelInUse(c, sensor_black_level_dn);
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

// out = Clamp(RoundShift(min(in, max) * mant - offset, shift), 0, 65535), as
// one loop compilers vectorise: 64-bit unsigned arithmetic and 32-bit
// compares only (64-bit compares and arithmetic shifts do not vectorise on
// every target, e.g. x86-64 without SSE4.2). Bounds: dn <= 65535 (adc_bits
// <= 16) and mant < 2^32, so dn * mant < 2^48 and offset < 2^48; the shift is
// in [16, 31] (the scale 65535 / (max - BL) is in [1, 65535] and its mantissa
// in [2^31, 2^32)).
namespace {

// One channel's row (see ProcessRow); a free function so that it can be
// compiled also for AVX2 (CAMSIM_CPU_CLONES; integer code, same bits).
CAMSIM_CPU_CLONES
void BlackLevelRow(const uint32_t* __restrict in, uint32_t* __restrict out, int width, uint32_t max_dn,
                   uint64_t mant, int shift, uint64_t bias) {
  for (int x = 0; x < width; ++x) {
    const uint32_t dn = in[x] < max_dn ? in[x] : max_dn;
    // dn * mant - offset + half, in (-2^48, 2^48) as a signed value, here
    // modulo 2^64: bit 63 is set exactly when it is negative, and when it
    // is not, >> shift (>= 16) leaves less than 2^32.
    const uint64_t v = dn * mant + bias;
    const uint32_t negative = static_cast<uint32_t>(v >> 63);
    const uint32_t q = static_cast<uint32_t>(v >> shift);
    out[x] = (q < kMaxQ16 ? q : kMaxQ16) & (negative - 1u);  // 0 when negative
  }
}

}  // namespace

void BlackLevelStage::ProcessRow(const RowArgs& a) const {
  CAMSIM_DCHECK(scale_.shift >= 16 && scale_.shift <= 31);
  const int channels = a.out[1] != nullptr ? 3 : 1;
  const int shift = scale_.shift;
  // The rounding half minus the offset, modulo 2^64.
  const uint64_t bias = (uint64_t{1} << (shift - 1)) - static_cast<uint64_t>(offset_);
  for (int c = 0; c < channels; ++c) BlackLevelRow(a.rows[0].ch[c], a.out[c], a.width, max_dn_, scale_.mant, shift, bias);
}

}  // namespace camsim
