// Black level: raw DN -> linear signal of full scale, with the sensor's offset
// removed and the remaining range stretched to Q0.16:
//
//   out = min(round(max(DN - BL, 0) * 65535 / (2^adc_bits - 1 - BL)), 65535)
//
// Formats: in  Digital DN (1 channel, mosaic or mono, or 3 channels)
//          out Linear Q0.16, same channels
//          scale s = 65535 / (max_dn - BL) as a UScale (mant * 2^-shift), and
//          offset = round(BL * mant) so that BL need not be an integer:
//            out = RoundShift(DN * mant - offset, shift), int64 (DN * mant < 2^48),
//          one rounding (ties up), clamped to [0, 65535]. DN above max_dn is
//          taken as max_dn.
// Error against the exact formula: <= 0.5 LSB + 2.3e-5 LSB: the scale's 2^-32
// relative rounding on results up to 65535 (1.53e-5) and, for a fractional
// BL, the offset's rounding (half of 2^-shift, shift >= 16: 7.6e-6).
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

struct BlackLevelConfig {
  // Offset to subtract, DN; -1 = the sensor's black level (sensor.black_level_dn).
  double black_level_dn = -1.0;
};

// The offset in use: config.black_level_dn, or the sensor's when it is -1.
inline double BlackLevelInUse(const BlackLevelConfig& config, double sensor_black_level_dn) {
  return config.black_level_dn == -1.0 ? sensor_black_level_dn : config.black_level_dn;
}

class BlackLevelStage final : public Stage {
 public:
  // sensor_black_level_dn: used when config.black_level_dn is -1.
  Status Configure(const BlackLevelConfig& config, const SensorGeometry& geometry,
                   double sensor_black_level_dn);
  const char* name() const override { return "black_level"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  // Never identity: it converts DN to the linear domain.
  void ProcessRow(const RowArgs& args) const override;

  double black_level_dn() const { return black_level_; }  // the offset in use

 private:
  double black_level_ = 0.0;
  uint32_t max_dn_ = 0;
  UScale scale_;
  int64_t offset_ = 0;  // round(BL * scale_.mant)
};

}  // namespace camsim
