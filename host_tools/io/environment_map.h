// Loading a lat-long (equirectangular) HDR environment map for lens flare
// (flare.environment_map, core/lens/flare_environment.h). Host-side only.
//
// The colour channels are found and read as for scene frames (exr_scene.h:
// Blender <Layer>.Combined.R/G/B, plain R/G/B, or luminance Y; any
// compression, HALF or FLOAT), and sanitised the same way: NaN, -inf and
// negative texels become 0 and +inf becomes 65504, each counted in `stats`.
// The map must be twice as wide as high (lat-long), 4 x 2 to 8192 x 4096.
//
// Errors (false, *error names the file and what is wrong): missing or not a
// readable OpenEXR file; no colour channels (lists those present); a size
// that is not 2:1 or out of range (names the size).
#pragma once

#include <string>
#include <vector>

#include "host_tools/io/exr_scene.h"

namespace camsim::io {

struct EnvironmentMap {
  std::string path;
  int width = 0, height = 0;
  std::vector<float> rgb;     // R, G, B interleaved, row 0 = the zenith
  InputSanitizeStats stats;   // texel samples replaced while loading
  std::vector<std::string> warnings;  // as SceneFrame::warnings: one line naming the file if any was
  std::string layout;         // as SceneFrame::layout
};

bool LoadEnvironmentMap(const std::string& path, EnvironmentMap* out, std::string* error);

}  // namespace camsim::io
