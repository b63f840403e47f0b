// White balance: multiplies each sample by the gain of its colour.
//
//   out = min(round(v * gain[colour]), 65535)
//
// Formats: in/out Linear Q0.16; 3 channels (channel c has colour c) or 1
//          channel (mosaic: the site's CFA colour; mono: the G gain)
//          gain per colour as a UScale (32 significant bits), 64-bit product,
//          one rounding (ties up), saturated at 65535.
// Error against the exact product: <= 0.5 LSB + 3e-4 LSB (the gain's 2^-32
// relative rounding on products up to 16 * 65535).
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

struct WhiteBalanceConfig {
  double gain[3] = {1.0, 1.0, 1.0};  // R, G, B multipliers, each in [0, 16]
};

class WhiteBalanceStage final : public Stage {
 public:
  static constexpr double kMaxGain = 16.0;  // 4 stops: beyond any real illuminant correction

  Status Configure(const WhiteBalanceConfig& config, const SensorGeometry& geometry);
  const char* name() const override { return "white_balance"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  // "white-balance gains are all 1" when every gain rounds to exactly 1.
  const char* IdentityReason() const override;
  void ProcessRow(const RowArgs& args) const override;

 private:
  Cfa cfa_ = Cfa::kBayerRG;
  UScale gain_[3];
};

}  // namespace camsim
