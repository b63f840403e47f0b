#include "core/aperture/exposure.h"

namespace camsim {

double ExposurePhotonsPerRadiance(const ExposureConfig& c) {
  return c.photons_per_radiance_ms * (c.exposure_time_us / 1000.0) / (c.f_number * c.f_number);
}

double ReferenceExposure(const ExposureConfig& config, double radiance) {
  return radiance * ExposurePhotonsPerRadiance(config);
}

Status ExposureStage::Configure(const ExposureConfig& c) {
  // Limits: 1 us .. 100 s; f/0.5 .. f/128 (wider than any real lens).
  if (!(c.exposure_time_us >= 1.0 && c.exposure_time_us <= 1e8))
    return InvalidArgument("exposure.exposure_time_us", "must be in [1, 1e8] microseconds");
  if (!(c.f_number >= 0.5 && c.f_number <= 128.0))
    return InvalidArgument("exposure.f_number", "must be in [0.5, 128]");
  if (!(c.photons_per_radiance_ms > 0.0 && c.photons_per_radiance_ms <= 1e9))
    return InvalidArgument("exposure.photons_per_radiance_ms", "must be in (0, 1e9]");
  // Q16.16 in, Q24.8 out: the raw factor is the physical one times 2^-8.
  Result<UScale> f = UScale::FromDouble(ExposurePhotonsPerRadiance(c) / 256.0,
                                        "exposure.photons_per_radiance_ms");
  if (!f.ok()) return f.status();
  factor_ = f.value();
  return Status::Ok();
}

Result<LineFormat> ExposureStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kRadiance || in.channels != 3)
    return InvalidArgument("exposure", "needs RGB radiance input");
  return LineFormat{Domain::kPhotons, 3, false};
}

void ExposureStage::ProcessRow(const RowArgs& a) const {
  const RowIn& in = a.rows[0];
  const UScale f = factor_;
  for (int c = 0; c < 3; ++c) {
    const uint32_t* src = in.ch[c];
    uint32_t* dst = a.out[c];
    for (int x = 0; x < a.width; ++x) dst[x] = f.Apply(src[x]);
  }
}

}  // namespace camsim
