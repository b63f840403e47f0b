// Double reference of CCD smear (core/sensor/smear.h).
#pragma once

#include "core/pipeline/pipeline.h"

namespace camsim::ref {

// Smear electrons of column x: channel `channel` of a 3-channel sensor, or the
// single channel (mosaic or mono) when the configuration has a CFA stage.
// radiance[c][y * width + x] in radiance units. With a vignetting stage in
// the order each pixel's light is scaled by its double gain (curve modes) or
// by mask[y * width + x] / 2^14 (mask mode; mask needed then).
double RefSmear(const PipelineConfig& config, const double* const radiance[3], int x, int channel,
                const uint16_t* mask = nullptr);

}  // namespace camsim::ref
