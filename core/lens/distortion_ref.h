// Double-precision reference for the distortion stage: the exact inverse of
// the lens model at every pixel (no grid), the exact chromatic scale, and the
// filter's continuous kernel at the exact position (no phases), with the
// stage's rules for reflection, fill and the ringing clamp. Tests measure the
// stage's table and resampling error against it.
#pragma once

#include "core/base/span.h"
#include "core/lens/distortion.h"

namespace camsim {

class ReferenceDistortion {
 public:
  ReferenceDistortion(const DistortionConfig& config, const SensorGeometry& geometry);
  // Source position (pixels) of output pixel (u, v) for channel c; false: fill.
  bool Source(double u, double v, int c, double* sx, double* sy) const;
  // The resampled value of output pixel (x, y) from plane (channel c).
  double Sample(const ImageView<const uint32_t>& plane, int x, int y, int c) const;
  // The filtered value of a plane at source position (sx, sy) (no fill test).
  double Filter(const ImageView<const uint32_t>& plane, double sx, double sy) const;
  // The same for a plane of doubles (width x height of the geometry, row-major).
  double Sample(const double* plane, int x, int y, int c) const;

 private:
  template <typename At>
  double FilterAt(const At& at, double sx, double sy) const;
  DistortionConfig config_;
  SensorGeometry geometry_;
  LensBranch branch_;
};

}  // namespace camsim
