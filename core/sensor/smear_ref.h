// Double reference of CCD smear (core/sensor/smear.h).
#pragma once

#include "core/pipeline/pipeline.h"

namespace camsim::ref {

// Smear electrons of column x: channel `channel` of a 3-channel sensor, or the
// single channel (mosaic or mono) when the configuration has a CFA stage.
// radiance[c][y * width + x] in radiance units.
double RefSmear(const PipelineConfig& config, const double* const radiance[3], int x, int channel);

}  // namespace camsim::ref
