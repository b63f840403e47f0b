// Turns a loaded scene (float planes) into the core's input: fitted to the
// sensor size and converted to fixed point.
//
// Fit: crop takes the centre W x H window (offset floor((in - out) / 2));
// scale averages the input over each output pixel's footprint (area
// weighting, exact for integer ratios). Radiance becomes Q16.16 with
// round-to-nearest and saturation at 65535.99998 (the loader has already
// replaced NaN/Inf/negatives). A vignetting mask becomes Q2.14 gains the same way.
// Depth (when the scene has it) becomes inverse depth by InverseDepthFromMetres
// (core/pipeline/inverse_depth.h: z = 0: nearest; +inf, 1e10, NaN: 0; z < 0,
// -inf: invalid). Crop copies each pixel's depth; scale averages inverse depth
// (1/z, the quantity the CoC and the parallax are linear in) over the
// footprint, and a footprint holding an invalid depth is invalid.
// Blender's Vector.X/Y point from the pixel to its position in the previous
// frame with y upwards; the core takes the velocity with rows downwards:
// (-X, +Y), scaled by the fit's size ratio, Q16.16 saturating.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/pipeline/pipeline.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"

namespace camsim::host {

struct CoreInput {
  int width = 0, height = 0;
  std::vector<uint32_t> radiance[3];
  std::vector<uint16_t> mask;
  // From the scene's depth and motion planes when it has them (else empty):
  std::vector<uint32_t> inverse_depth;  // Q12.20 1/m (core/pipeline/inverse_depth.h)
  std::vector<int32_t> motion[2];       // x, y velocity in px per frame interval, Q16.16, rows downwards
  FrameInput View() const;
};

// Resamples a float plane to width x height by the fit rule.
io::FloatPlane FitPlane(const io::FloatPlane& in, int width, int height, SceneFit fit);

void PrepareInput(const io::SceneFrame& scene, int width, int height, SceneFit fit, CoreInput* out);
void PrepareMask(const io::FloatPlane& mask, int width, int height, CoreInput* out);

// The largest gain a vignetting mask can hold (the core's Q2.14 mask: 65535 / 2^14).
inline constexpr double kMaxMaskGain = 65535.0 / 16384.0;
// Reads a per-pixel image for `key` (vignetting.mask, auto_exposure.metering_image)
// and checks that every value is a number in [0, max]; errors name the key,
// the file and the first bad pixel.
bool ReadWeightImage(const std::string& key, const std::string& path, double max, io::FloatPlane* out,
                     std::string* error);

}  // namespace camsim::host
