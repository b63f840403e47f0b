// Fixtures shared by the unit tests, the OpenCV tests, the benchmarks and the
// core-only cross golden: core headers only, header-only.
#pragma once

#include "core/pipeline/pipeline.h"

namespace camsim::test {

// Every random term of the sensor off (shot and read noise, DSNU, PRNU, dark
// current), so that flat inputs have exact answers.
inline void NoiseOff(SensorConfig* s) {
  s->shot_noise = false;
  s->dark_noise_e = 0;
  s->dsnu_e = 0;
  s->prnu_percent = 0;
  s->dark_current_e_per_s = 0;
}

// A mono w x h sensor behind exposure and the CFA stage only (exposure ->
// cfa -> sensor), 12 bit; 10 ms at f/1 with 100 photons per unit radiance
// and ms: 1000 photons per unit radiance.
inline PipelineConfig MonoSensorPath(int w, int h) {
  PipelineConfig c;
  c.geometry = {w, h, Cfa::kMono, 12};
  c.exposure.exposure_time_us = 10000.0;
  c.exposure.f_number = 1.0;
  c.exposure.photons_per_radiance_ms = 100.0;
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kCfa;
  c.order[2] = StageId::kSensor;
  c.order_count = 3;
  return c;
}

// A typical wide-angle industrial lens for a w x h sensor: Brown barrel
// k1 -0.28, k2 0.07, k3 0.01, small tangential terms, fx = fy = 0.78 w (a
// 28 mm lens on a 36 mm wide sensor), the principal point (3.25, -2.5) px
// off the frame centre.
inline LensModel TypicalLens(int w, int h) {
  LensModel m;
  m.model = DistortionModel::kBrown;
  m.fx = m.fy = 0.78 * w;
  m.cx = (w - 1) / 2.0 + 3.25;
  m.cy = (h - 1) / 2.0 - 2.5;
  m.k[0] = -0.28;
  m.k[1] = 0.07;
  m.k[2] = 0.01;
  m.p1 = 0.0012;
  m.p2 = -0.0007;
  return m;
}

}  // namespace camsim::test
