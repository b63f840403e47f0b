// Turns a loaded scene (float planes) into the core's input: fitted to the
// sensor size and converted to fixed point.
//
// Fit: crop takes the centre W x H window (offset floor((in - out) / 2));
// scale averages the input over each output pixel's footprint (area
// weighting, exact for integer ratios). Radiance becomes Q16.16 with
// round-to-nearest and saturation at 65535.99998 (the loader has already
// replaced NaN/Inf/negatives). A vignetting mask becomes Q2.14 gains the same way.
// Depth becomes inverse depth before fitting (area averages of 1/z stay
// meaningful next to a 1e10 m sky), Q8.24 saturating at 255.99 1/m (depth
// under 4 mm). Blender's Vector.X/Y point from the pixel to its position in
// the previous frame with y upwards; the core takes the velocity with rows
// downwards: (-X, +Y), scaled by the fit's size ratio, Q16.16 saturating.
#pragma once

#include <cstdint>
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
  std::vector<uint32_t> inverse_depth;  // 1 / depth, Q8.24 1/m; depth <= 0, NaN or inf -> 0
  std::vector<int32_t> motion[2];       // x, y velocity in px per frame interval, Q16.16, rows downwards
  FrameInput View() const;
};

// Resamples a float plane to width x height by the fit rule.
io::FloatPlane FitPlane(const io::FloatPlane& in, int width, int height, SceneFit fit);

void PrepareInput(const io::SceneFrame& scene, int width, int height, SceneFit fit, CoreInput* out);
void PrepareMask(const io::FloatPlane& mask, int width, int height, CoreInput* out);

}  // namespace camsim::host
