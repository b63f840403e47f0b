// Colour filter array (paper eq. 18, 20-22): keeps, at each pixel, the colour
// its filter passes: a Bayer mosaic in any of the four GenICam phases, or, for
// a mono sensor, a weighted sum of R, G, B (the filter-less spectral response).
//
// Formats: in  Radiance Q16.16 or Photons Q24.8, 3 channels (a Bayer CFA
//              runs ahead of exposure and vignetting: pipeline.h)
//          out the same domain and format, 1 channel (mosaic for Bayer)
//          mono weights Q1.16 in [0, 65536] summing to exactly 65536 (the G
//          weight takes the rounding remainder; a weight of 1 is exact);
//          64-bit sum, one rounding (ties up), saturated.
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

struct CfaConfig {
  // Mono only: relative response to R, G, B (normalised to sum 1).
  // Default: Rec. 709 luma weights.
  double mono_weights[3] = {0.2126, 0.7152, 0.0722};
};

class CfaStage final : public Stage {
 public:
  Status Configure(const CfaConfig& config, const SensorGeometry& geometry);
  const char* name() const override { return "cfa"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  void ProcessRow(const RowArgs& args) const override;

 private:
  Cfa cfa_ = Cfa::kBayerRG;
  uint32_t weight_[3] = {};  // Q1.16, sum 65536
};

}  // namespace camsim
