// Double-precision reference of the motion blur / rolling shutter stage
// (core/lens/motion_blur.h): the same model evaluated directly in double,
// from the formulas rather than the stage's tables. Tests use it to measure
// the fixed-point stage's error.
#pragma once

#include <vector>

#include "core/lens/motion_blur.h"

namespace camsim::ref {

struct MotionRefInput {
  int width = 0, height = 0;
  const std::vector<double>* plane[3] = {};  // samples, any unit, planes[c][y * width + x]
  const std::vector<double>* inverse_depth = nullptr;  // 1/m (camera translation)
  const std::vector<double>* vectors[2] = {};          // px per frame interval, rows downwards (vectors mode)
};

// Displacement over the exposure at pixel (x, y), pixels, before any bound.
// config's cx/cy < 0 mean the centre, as in the stage.
void RefMotionDisplacement(const MotionBlurConfig& config, const MotionRefInput& in, double exposure_us, int x,
                           int y, double* dx, double* dy);

// The stage's output, not rounded: planes [3][width * height]. With
// `continuous`, the time integral is taken with 16 samples per pixel of
// motion (at least 64) instead of the stage's n: the ideal the stage's
// sampling approximates, to measure what max_samples costs.
std::vector<std::vector<double>> RefMotionBlur(const MotionBlurConfig& config, const MotionRefInput& in,
                                               double exposure_us, bool continuous = false);

}  // namespace camsim::ref
