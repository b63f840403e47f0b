// The core's depth input, shared by every stage that reads depth (depth of
// field, motion blur): inverse depth 1/z in 1/m, Q12.20 unsigned. Blur and
// parallax are linear in 1/z, and a 1e10 m sky is simply ~0.
//   z = +inf, 1e10 m, NaN  -> 0 (infinitely far)
//   z = 0 or z < 2^-12 m   -> kMaxInverseDepth (nearest representable)
//   z < 0, -inf            -> kInvalidInverseDepth (no depth: DoF leaves the
//                             pixel sharp, motion blur takes it as far away)
#pragma once

#include <cstdint>

namespace camsim {

inline constexpr int kInverseDepthFracBits = 20;
inline constexpr uint32_t kInvalidInverseDepth = 0xFFFFFFFFu;
inline constexpr uint32_t kMaxInverseDepth = 0xFFFFFFFEu;

// Depth in metres to the core's inverse depth by the rules above (host side,
// IEEE operations only, so it is the same everywhere).
uint32_t InverseDepthFromMetres(double z);

}  // namespace camsim
