// Double reference of metering (core/control/metering.h): the same weight
// shapes in double (centre: max(1 - r^2, 1/16) exactly; image weights as
// given, w / 65536), summed in double. The stage's error is its Q0.16
// weights' truncation: below 2^-16 a weight, at most 2^-16 / (1/16) = 2^-12
// of the smallest weight relative, so the mean moves by under 2 x 2^-12 of
// the signal's range.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/control/metering.h"

namespace camsim::ref {

double RefMeteringWeight(Metering m, int x, int y, int width, int height);

// WeightedBrightness in double; weights: kImage only, width * height values in [0, 1].
double RefWeightedBrightness(const uint16_t* raw, int width, int height, ptrdiff_t stride, int channels,
                             int black_dn, int max_dn, Metering m, const double* weights);

}  // namespace camsim::ref
