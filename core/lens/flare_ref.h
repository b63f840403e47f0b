// Double reference of lens flare (core/lens/flare.h), from scratch on a whole
// image: the same tiles, centroids (rounded to pixels as the core does),
// kernel shape and ghost shapes, without fixed-point rounding.
#pragma once

#include "core/isp/isp_ref.h"
#include "core/lens/flare.h"

namespace camsim::ref {

RefImage RefFlare(const FlareConfig& config, const SensorGeometry& geometry, const RefImage& radiance);

}  // namespace camsim::ref
