#include "core/sensor/smear_ref.h"

#include "core/aperture/exposure.h"

namespace camsim::ref {

double RefSmear(const PipelineConfig& config, const double* const radiance[3], int x, int channel,
                 const uint16_t* mask) {
  const SensorGeometry& g = config.geometry;
  const SensorConfig& s = config.sensor;
  bool cfa = false;
  for (int i = 0; i < config.order_count; ++i) cfa |= config.order[i] == StageId::kCfa;
  const double ppr = ExposurePhotonsPerRadiance(config.exposure);
  const double* w = config.cfa.mono_weights;
  const double wsum = w[0] + w[1] + w[2];
  bool vig = false;
  for (int i = 0; i < config.order_count; ++i) vig |= config.order[i] == StageId::kVignetting;
  const VignettingMode vmode = vig ? config.vignetting.mode : VignettingMode::kOff;
  double e = 0;
  for (int y = 0; y < g.height; ++y) {
    const size_t i = static_cast<size_t>(y) * g.width + x;
    const double gain = vmode == VignettingMode::kOff    ? 1.0
                        : vmode == VignettingMode::kMask ? mask[i] / 16384.0
                                                         : ReferenceVignettingGain(config.vignetting, g, x, y);
    const double before = e;
    if (!cfa) {
      e += radiance[channel][i] * ppr * s.quantum_efficiency[channel];
    } else if (g.cfa == Cfa::kMono) {
      e += (w[0] * radiance[0][i] + w[1] * radiance[1][i] + w[2] * radiance[2][i]) / wsum * ppr *
           s.quantum_efficiency[kGreen];
    } else {
      const Colour c = CfaColour(g.cfa, x, y);
      e += radiance[c][i] * ppr * s.quantum_efficiency[c];
    }
    e = before + (e - before) * gain;
  }
  return s.smear_leak * s.smear_row_transfer_us / config.exposure.exposure_time_us * e;
}

}  // namespace camsim::ref
