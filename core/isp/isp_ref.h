// Double-precision references of the ISP stages, on whole images: what the
// tests measure the fixed-point stages against. Values are in the stages'
// sample units (DN for black-level input, 0..65535 otherwise), not rounded.
// Borders are reflect-101, as the pipeline's driver pads rows and columns.
#pragma once

#include <vector>

#include "core/isp/black_level.h"
#include "core/isp/color_matrix.h"
#include "core/isp/demosaic.h"
#include "core/isp/gamma.h"
#include "core/isp/white_balance.h"

namespace camsim::ref {

// planes[c][y * width + x]; 1 plane (mosaic or mono) or 3 (R, G, B).
struct RefImage {
  int width = 0;
  int height = 0;
  std::vector<std::vector<double>> planes;
};

// clamp(max(DN - BL, 0) * 65535 / (2^adc_bits - 1 - BL), 0, 65535)
RefImage RefBlackLevel(const RefImage& dn, double black_level_dn, int adc_bits);
// min(v * gain, 65535); one plane takes the gain of each site's CFA colour.
// white_level: as WhiteBalanceStage::Configure's (highlights clip at min gain * white).
RefImage RefWhiteBalance(const RefImage& in, Cfa cfa, const WhiteBalanceConfig& config, double white_level);
// Eq. 23-24: zero-filled colour planes convolved with K_rb and K_g. A padded
// site has the CFA colour of its own (unreflected) position.
RefImage RefDemosaicBilinear(const RefImage& mosaic, Cfa cfa);
// Malvar-He-Cutler 2004: the paper's 5x5 kernels (/ 8), clamped to [0, 65535].
RefImage RefDemosaicMalvar(const RefImage& mosaic, Cfa cfa);
// clamp(m * rgb, 0, 65535) with the given coefficients.
RefImage RefColorMatrix(const RefImage& rgb, const double m[9]);
// 65535 * curve(v / 65535) for v clamped to [0, 65535] (libm pow).
RefImage RefGamma(const RefImage& in, const GammaConfig& config);

}  // namespace camsim::ref
