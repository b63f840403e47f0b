// Exposure (paper eq. 7): scene radiance -> photons per pixel.
//
//   photons = radiance * c * t / N^2
//
// c: calibration constant, photons per pixel per unit radiance per millisecond
//    at f/1 (it folds in pixel area, lens transmission and the spectral
//    integral); t: exposure time; N: f-number. The ISO-like gain of eq. 7 is
//    not here: it is the sensor's analog gain (SensorConfig::gain_db), because
//    a real gain amplifies the signal *and* its shot noise.
//
// Formats: in  Radiance Q16.16 (3 channels, or 1 mosaic channel: the
//              planner runs a Bayer CFA ahead of this stage, see pipeline.h)
//          out Photons  Q24.8, the same channels
//          factor c*t/N^2 * 2^-8 as a UScale (32 significant bits);
//          64-bit product, round to nearest (ties up), saturate at 2^32 - 1
//          (16.7 M photons).
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

struct ExposureConfig {
  double exposure_time_us = 10000.0;       // t, microseconds (SFNC ExposureTime unit)
  double f_number = 2.8;                   // N
  // c: with the defaults, radiance 1.0 (a white diffuse surface under the
  // bundled scene's light) gives ~10 000 photons, ~70 % of the default full well.
  double photons_per_radiance_ms = 8000.0;
};

// photons per unit radiance for a config (the double model; also the reference).
double ExposurePhotonsPerRadiance(const ExposureConfig& config);

class ExposureStage final : public Stage {
 public:
  Status Configure(const ExposureConfig& config);
  const char* name() const override { return "exposure"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  void ProcessRow(const RowArgs& args) const override;

  const UScale& factor() const { return factor_; }

 private:
  UScale factor_;  // radiance Q16.16 -> photons Q24.8
};

// Double-precision reference: photons for a radiance value.
double ReferenceExposure(const ExposureConfig& config, double radiance);

}  // namespace camsim
