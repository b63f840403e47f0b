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
