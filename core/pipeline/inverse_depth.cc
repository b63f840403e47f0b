#include "core/pipeline/inverse_depth.h"

namespace camsim {

uint32_t InverseDepthFromMetres(double z) {
  if (z != z) return 0;                       // NaN: as +inf (the loader's rule)
  if (z < 0.0) return kInvalidInverseDepth;   // behind the camera / -inf: no depth
  if (z == 0.0) return kMaxInverseDepth;
  const double iz = static_cast<double>(1u << kInverseDepthFracBits) / z;  // +inf -> 0
  if (iz >= static_cast<double>(kMaxInverseDepth)) return kMaxInverseDepth;
  return static_cast<uint32_t>(iz + 0.5);     // round to nearest, ties up (iz >= 0)
}

}  // namespace camsim
