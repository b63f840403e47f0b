// White balance: multiplies each sample by the gain of its colour, and
// clips highlights where the sensor saturates.
//
//   out = min(round(v * gain[colour]), clip)
//   clip = min(round(min_gain * white * 65535), 65535)
//
// white is the linear level of a full well (SensorSaturationDn through the
// black level's mapping, 0 .. 1) and min_gain the smallest gain above 0 of
// the colours the sensor has (a mono sensor: the G gain).
// A channel saturated at the sensor comes out at `clip` whatever its gain,
// so a blown highlight stays neutral (dcraw's highlight clipping). Without
// the clip, gains above 1 lifted a saturated R and B to 65535 while G
// stayed at the white level (64023 for the demo camera): magenta highlights.
//
// Formats: in/out Linear Q0.16; 3 channels (channel c has colour c) or 1
//          channel (mosaic: the site's CFA colour; mono: the G gain)
//          gain per colour as a UScale (32 significant bits), 64-bit product,
//          one rounding (ties up), saturated at clip (an integer <= 65535).
// Error against the exact product: <= 0.5 LSB + 3e-4 LSB (the gain's 2^-32
// relative rounding on products up to 16 * 65535), and against the exact
// clip <= 0.5 LSB (its rounding). The stage is left out when every gain is
// 1: then nothing is clipped, and a stuck pixel or the noise tail above the
// full well keeps its value (every channel of a full well is already equal).
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

struct WhiteBalanceConfig {
  double gain[3] = {1.0, 1.0, 1.0};  // R, G, B multipliers, each in [0, 16]
};

class WhiteBalanceStage final : public Stage {
 public:
  static constexpr double kMaxGain = 16.0;  // 4 stops: beyond any real illuminant correction

  // white_level: the linear level of a full well (WhiteLevel), 0 .. 1.
  Status Configure(const WhiteBalanceConfig& config, const SensorGeometry& geometry, double white_level);
  const char* name() const override { return "white_balance"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  // "white-balance gains are all 1" when every gain rounds to exactly 1.
  const char* IdentityReason() const override;
  void ProcessRow(const RowArgs& args) const override;

 private:
  Cfa cfa_ = Cfa::kBayerRG;
  UScale gain_[3];
  uint32_t clip_ = 65535;
};

// The linear level (fraction of full scale) of a sensor saturation of
// saturation_dn after the black level's mapping, (dn - BL) / (2^bits - 1 - BL),
// clamped to [0, 1].
double WhiteLevel(double saturation_dn, double black_level_dn, int adc_bits);
// The clip for gains and a white level: min_gain * white in Q0.16, unrounded
// (min_gain over the colours the sensor has: G alone for mono).
double WhiteBalanceClip(const WhiteBalanceConfig& config, Cfa cfa, double white_level);

}  // namespace camsim
