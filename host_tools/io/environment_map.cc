#include "host_tools/io/environment_map.h"

#include <utility>

namespace camsim::io {

bool LoadEnvironmentMap(const std::string& path, EnvironmentMap* out, std::string* error) {
  SceneFrame frame;
  if (!LoadSceneExr(path, "", &frame, error)) return false;
  const int w = frame.width, h = frame.height;
  // The core's limits (core/lens/flare_environment.h): 2:1, 4 x 2 .. 8192 x 4096.
  if (w != 2 * h || w < 4 || w > 8192) {
    *error = "'" + path + "': a lat-long environment map must be twice as wide as high, 4 x 2 to 8192 x 4096 " +
             "texels (this one is " + std::to_string(w) + " x " + std::to_string(h) + ")";
    return false;
  }
  EnvironmentMap m;
  m.path = path;
  m.width = w;
  m.height = h;
  m.stats = frame.radiance_stats;
  m.warnings = std::move(frame.warnings);
  m.layout = frame.layout;
  const size_t n = static_cast<size_t>(w) * static_cast<size_t>(h);
  m.rgb.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    m.rgb[3 * i] = frame.r.data[i];
    m.rgb[3 * i + 1] = frame.g.data[i];
    m.rgb[3 * i + 2] = frame.b.data[i];
  }
  *out = std::move(m);
  return true;
}

}  // namespace camsim::io
