#include "host_tools/scene_input.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "host_tools/io/image_read.h"

namespace camsim::host {

FrameInput CoreInput::View() const {
  FrameInput in;
  for (int c = 0; c < 3; ++c) in.radiance[c] = MakeImageView<const uint32_t>(radiance[c].data(), width, height);
  if (!mask.empty()) in.vignetting_mask = MakeImageView<const uint16_t>(mask.data(), width, height);
  if (!inverse_depth.empty()) in.inverse_depth = MakeImageView<const uint32_t>(inverse_depth.data(), width, height);
  for (int c = 0; c < 2; ++c)
    if (!motion[c].empty()) in.motion_vectors[c] = MakeImageView<const int32_t>(motion[c].data(), width, height);
  return in;
}

io::FloatPlane FitPlane(const io::FloatPlane& in, int width, int height, SceneFit fit) {
  io::FloatPlane out;
  out.width = width;
  out.height = height;
  out.data.assign(static_cast<size_t>(width) * height, 0.0f);
  if (in.width == width && in.height == height) return in;
  if (fit == SceneFit::kCrop) {
    const int ox = (in.width - width) / 2, oy = (in.height - height) / 2;
    for (int y = 0; y < height; ++y)
      std::copy_n(&in.data[static_cast<size_t>(y + oy) * in.width + ox], width, &out.data[static_cast<size_t>(y) * width]);
    return out;
  }
  // Area average: output pixel x covers input [x * sx, (x + 1) * sx).
  const double sx = static_cast<double>(in.width) / width, sy = static_cast<double>(in.height) / height;
  for (int y = 0; y < height; ++y) {
    const double y0 = y * sy, y1 = (y + 1) * sy;
    for (int x = 0; x < width; ++x) {
      const double x0 = x * sx, x1 = (x + 1) * sx;
      double sum = 0.0, area = 0.0;
      for (int iy = static_cast<int>(y0); iy < std::min<double>(y1, in.height); ++iy) {
        const double wy = std::min<double>(iy + 1, y1) - std::max<double>(iy, y0);
        for (int ix = static_cast<int>(x0); ix < std::min<double>(x1, in.width); ++ix) {
          const double wx = std::min<double>(ix + 1, x1) - std::max<double>(ix, x0);
          sum += wx * wy * in.data[static_cast<size_t>(iy) * in.width + ix];
          area += wx * wy;
        }
      }
      out.data[static_cast<size_t>(y) * width + x] = static_cast<float>(area > 0 ? sum / area : 0.0);
    }
  }
  return out;
}

namespace {

// round(v * 2^frac), clamped to [0, max].
uint32_t ToFixed(float v, int frac, double max) {
  const double s = std::ldexp(static_cast<double>(v), frac);
  if (!(s > 0.0)) return 0;
  if (s >= max) return static_cast<uint32_t>(max);
  return static_cast<uint32_t>(std::floor(s + 0.5));
}

// Crop copies each pixel's depth; scale averages 1/z in 1/m (float), with NaN
// marking an invalid depth so that it spreads to its footprint.
void PrepareInverseDepth(const io::SceneFrame& scene, int width, int height, SceneFit fit, CoreInput* out) {
  const bool same = scene.depth.width == width && scene.depth.height == height;
  if (same || fit == SceneFit::kCrop) {
    const io::FloatPlane fitted = FitPlane(scene.depth, width, height, fit);
    out->inverse_depth.resize(fitted.data.size());
    for (size_t i = 0; i < fitted.data.size(); ++i) out->inverse_depth[i] = InverseDepthFromMetres(fitted.data[i]);
    return;
  }
  io::FloatPlane iz = scene.depth;
  for (float& v : iz.data) v = v < 0.0f ? std::nanf("") : (v == 0.0f ? INFINITY : 1.0f / v);
  const io::FloatPlane fitted = FitPlane(iz, width, height, fit);
  out->inverse_depth.resize(fitted.data.size());
  for (size_t i = 0; i < fitted.data.size(); ++i) {
    const float v = fitted.data[i];
    out->inverse_depth[i] = v != v ? kInvalidInverseDepth : InverseDepthFromMetres(v == 0.0f ? INFINITY : 1.0 / v);
  }
}

}  // namespace

void PrepareInput(const io::SceneFrame& scene, int width, int height, SceneFit fit, CoreInput* out) {
  out->width = width;
  out->height = height;
  const io::FloatPlane* planes[3] = {&scene.r, &scene.g, &scene.b};
  for (int c = 0; c < 3; ++c) {
    const io::FloatPlane fitted = FitPlane(*planes[c], width, height, fit);
    out->radiance[c].resize(fitted.data.size());
    for (size_t i = 0; i < fitted.data.size(); ++i) out->radiance[c][i] = ToFixed(fitted.data[i], 16, 4294967295.0);
  }
  out->inverse_depth.clear();
  if (scene.has_depth) PrepareInverseDepth(scene, width, height, fit, out);
  for (int c = 0; c < 2; ++c) out->motion[c].clear();
  if (scene.has_motion) {
    // Velocity, rows downwards: x = -Vector.X, y = +Vector.Y (see the header).
    const double ratio[2] = {static_cast<double>(width) / scene.width, static_cast<double>(height) / scene.height};
    const io::FloatPlane* vectors[2] = {&scene.motion_x, &scene.motion_y};
    for (int c = 0; c < 2; ++c) {
      const io::FloatPlane fitted = FitPlane(*vectors[c], width, height, fit);
      const double scale = (c == 0 ? -1.0 : 1.0) * (fit == SceneFit::kScale ? ratio[c] : 1.0) * 65536.0;
      out->motion[c].resize(fitted.data.size());
      for (size_t i = 0; i < fitted.data.size(); ++i) {
        const double v = std::floor(fitted.data[i] * scale + 0.5);
        out->motion[c][i] = static_cast<int32_t>(std::clamp(v, -2147483648.0, 2147483647.0));
      }
    }
  }
}

bool ReadWeightImage(const std::string& key, const std::string& path, double max, io::FloatPlane* out,
                     std::string* error) {
  io::FloatPlane plane;
  if (!io::ReadMaskImage(path, &plane, error)) {
    *error = key + ": " + *error;
    return false;
  }
  for (size_t i = 0; i < plane.data.size(); ++i) {
    const double v = plane.data[i];
    if (v >= 0.0 && v <= max) continue;  // false for NaN
    char what[160];
    std::snprintf(what, sizeof what, "pixel (%zu, %zu) is %g; values must be numbers in [0, %g]",
                  i % static_cast<size_t>(plane.width), i / static_cast<size_t>(plane.width), v, max);
    *error = key + ": " + path + ": " + what;
    return false;
  }
  *out = std::move(plane);
  return true;
}

void PrepareMask(const io::FloatPlane& mask, int width, int height, CoreInput* out) {
  const io::FloatPlane fitted = FitPlane(mask, width, height, SceneFit::kScale);
  out->mask.resize(fitted.data.size());
  for (size_t i = 0; i < fitted.data.size(); ++i) out->mask[i] = static_cast<uint16_t>(ToFixed(fitted.data[i], 14, 65535.0));
}

}  // namespace camsim::host
