// Double reference of the environment map's flare sources
// (core/lens/flare_environment.h), from scratch with libm: the same
// directions, solid angles, projection, frame test, reach test and ordering,
// without fixed-point rounding of the excess (positions are rounded to
// pixels as the core does). RefFlare (flare_ref.h) adds their glare, ghosts
// and haze.
#pragma once

#include <vector>

#include "core/lens/flare.h"

namespace camsim::ref {

struct RefEnvSource {
  int x = 0, y = 0;             // rounded position, pixels
  double excess[3] = {};        // radiance x pixels
};

struct RefEnvironment {
  std::vector<RefEnvSource> sources;  // strongest first, at most max_sources
  double haze_excess[3] = {};         // all bright texels outside the frame
  long long bright = 0, in_frame = 0, haze_only = 0;
};

RefEnvironment RefFlareEnvironment(const FlareConfig& config, const SensorGeometry& geometry);

}  // namespace camsim::ref
