#include "core/aperture/exposure.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

// f.Apply(v) for 1 <= f.shift <= 63, bit for bit, in a form compilers
// vectorise: the saturation is tested on the 32-bit high half (a 64-bit
// compare does not vectorise on every target, e.g. x86-64 without SSE4.2).
inline uint32_t ScaleInRange(uint32_t mant, int shift, uint32_t v) {
  const uint64_t p = uint64_t{v} * mant;
  const uint64_t r = (p >> shift) + ((p >> (shift - 1)) & 1);  // RoundShiftU(p, shift)
  const uint32_t high = static_cast<uint32_t>(r >> 32), low = static_cast<uint32_t>(r);
  return low | (0u - static_cast<uint32_t>(high != 0));  // SatU32(r)
}

// Apply's own special cases (factor >= 2^31 or < 2^-32) are left to Apply.
bool InRange(UScale f) { return f.shift >= 1 && f.shift <= 63; }

// dst[x] = f.Apply(src[x]) for a row, bit for bit (the shift is checked once
// per row).
CAMSIM_CPU_CLONES
void ScaleRow(UScale f, const uint32_t* __restrict src, uint32_t* __restrict dst, int width) {
  if (!InRange(f)) {
    for (int x = 0; x < width; ++x) dst[x] = f.Apply(src[x]);
    return;
  }
  const uint32_t mant = f.mant;
  const int shift = f.shift;
  for (int x = 0; x < width; ++x) dst[x] = ScaleInRange(mant, shift, src[x]);
}

}  // namespace

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
  if (in.domain != Domain::kRadiance) return InvalidArgument("exposure", "needs radiance input");
  return LineFormat{Domain::kPhotons, in.channels, in.mosaic};
}

void ExposureStage::ProcessRow(const RowArgs& a) const {
  const int channels = a.out[1] != nullptr ? 3 : 1;
  for (int c = 0; c < channels; ++c) ScaleRow(factor_, a.rows[0].ch[c], a.out[c], a.width);
}

}  // namespace camsim
