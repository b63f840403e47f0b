// The double-precision reference of a whole pipeline, stage by stage: each
// running stage's own reference (the *Reference* functions beside the stages
// and isp_ref.h) behind one call, so tools measure any stage, or the chain
// from the scene to the output, against doubles (camsim tradeoff).
//
// Units of a RefImage: radiance and photons in physical units (the samples'
// value / 2^DomainFracBits); DN, linear and encoded in sample units (DN,
// 0 .. 65535) as isp_ref.h. References leave out randomness (they give the
// noise-free mean): compare with sensor noise, DSNU and PRNU off. They do not
// round between stages; the sensor's ADC rounding to whole DN is the one
// rounding a real camera has that the reference skips, so it sets the floor of
// the end-to-end error.
#pragma once

#include <cstdint>
#include <vector>

#include "core/isp/isp_ref.h"
#include "core/pipeline/pipeline.h"

namespace camsim::ref {

// Physical value of one sample of a domain (see the units above).
double SampleToReal(Domain d, uint32_t sample);

// Running stage `index` of `pipeline` applied in doubles to `in` (its input in
// the units above). `input` gives the per-frame planes some stages read (the
// vignetting mask).
RefImage RunStageReference(const Pipeline& pipeline, int index, const RefImage& in, const FrameInput& input);

// Pixels (row-major, 1 = yes) where the distortion stage at running `index`
// and its reference disagree on the fill (header of distortion.h) for a
// channel the stage computes: sources within the remap grid's error of the
// frame edge land on different sides of it. There the difference is a whole
// pixel value, not resampling error, so error reports count these pixels
// apart. Empty if the stage at `index` is not distortion.
std::vector<uint8_t> FillDisagreement(const Pipeline& pipeline, int index);

// The scene's radiance planes as a RefImage (3 planes).
RefImage SceneRadiance(const FrameInput& input, int width, int height);

}  // namespace camsim::ref
