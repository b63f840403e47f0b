#include "core/isp/isp_ref.h"

#include <algorithm>
#include <cmath>

namespace camsim::ref {
namespace {

constexpr double kFullScale = 65535.0;

double Clamp16(double v) { return std::clamp(v, 0.0, kFullScale); }

RefImage SameSize(const RefImage& in, size_t planes) {
  RefImage out;
  out.width = in.width;
  out.height = in.height;
  out.planes.assign(planes, std::vector<double>(static_cast<size_t>(in.width) * in.height, 0.0));
  return out;
}

// The mosaic at (x, y), reflect-101 outside the frame.
double At(const RefImage& m, int x, int y) {
  const int rx = Reflect101(x, m.width), ry = Reflect101(y, m.height);
  return m.planes[0][static_cast<size_t>(ry) * m.width + rx];
}

// Eq. 23-24 kernels, / 4.
constexpr double kKernelRb[3][3] = {{1, 2, 1}, {2, 4, 2}, {1, 2, 1}};
constexpr double kKernelG[3][3] = {{0, 1, 0}, {1, 4, 1}, {0, 1, 0}};

// Malvar-He-Cutler 2004, figure 2, / 8.
using Kernel5 = double[5][5];
constexpr Kernel5 kGreenAtRb = {
    {0, 0, -1, 0, 0}, {0, 0, 2, 0, 0}, {-1, 2, 4, 2, -1}, {0, 0, 2, 0, 0}, {0, 0, -1, 0, 0}};
// R at G in an R row (the target colour is left and right); B likewise.
constexpr Kernel5 kAtGreenHorizontal = {
    {0, 0, 0.5, 0, 0}, {0, -1, 0, -1, 0}, {-1, 4, 5, 4, -1}, {0, -1, 0, -1, 0}, {0, 0, 0.5, 0, 0}};
// R at G in a B row (the target colour is above and below); B likewise.
constexpr Kernel5 kAtGreenVertical = {
    {0, 0, -1, 0, 0}, {0, -1, 4, -1, 0}, {0.5, 0, 5, 0, 0.5}, {0, -1, 4, -1, 0}, {0, 0, -1, 0, 0}};
// R at B, B at R.
constexpr Kernel5 kRbAtBr = {
    {0, 0, -1.5, 0, 0}, {0, 2, 0, 2, 0}, {-1.5, 0, 6, 0, -1.5}, {0, 2, 0, 2, 0}, {0, 0, -1.5, 0, 0}};

double Convolve5(const RefImage& m, int x, int y, const Kernel5& k) {
  double sum = 0.0;
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx) sum += k[dy + 2][dx + 2] * At(m, x + dx, y + dy);
  return sum / 8.0;
}

double GammaCurve01(const GammaConfig& c, double v) {
  switch (c.curve) {
    case GammaCurve::kLinear: return v;
    case GammaCurve::kSrgb: return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
    case GammaCurve::kPower: return std::pow(v, 1.0 / c.gamma);
  }
  return v;
}

}  // namespace

RefImage RefBlackLevel(const RefImage& dn, double black_level_dn, int adc_bits) {
  RefImage out = SameSize(dn, dn.planes.size());
  const double range = std::ldexp(1.0, adc_bits) - 1.0 - black_level_dn;
  for (size_t c = 0; c < dn.planes.size(); ++c)
    for (size_t i = 0; i < dn.planes[c].size(); ++i)
      out.planes[c][i] = Clamp16(std::max(dn.planes[c][i] - black_level_dn, 0.0) * kFullScale / range);
  return out;
}

RefImage RefWhiteBalance(const RefImage& in, Cfa cfa, const WhiteBalanceConfig& config, double white_level) {
  RefImage out = SameSize(in, in.planes.size());
  // Highlights clip at the smallest positive gain times the white level.
  double min_gain = 1e300;
  for (int colour = 0; colour < 3; ++colour)
    if (config.gain[colour] > 0.0 && (cfa != Cfa::kMono || colour == kGreen))
      min_gain = std::min(min_gain, config.gain[colour]);
  const double clip = std::min((min_gain < 1e300 ? min_gain : 1.0) * white_level * kFullScale, kFullScale);
  for (size_t c = 0; c < in.planes.size(); ++c)
    for (int y = 0; y < in.height; ++y)
      for (int x = 0; x < in.width; ++x) {
        const size_t i = static_cast<size_t>(y) * in.width + x;
        const Colour colour = in.planes.size() == 3 ? static_cast<Colour>(c) : CfaColour(cfa, x, y);
        out.planes[c][i] = std::min(in.planes[c][i] * config.gain[colour], clip);
      }
  return out;
}

RefImage RefDemosaicBilinear(const RefImage& mosaic, Cfa cfa) {
  RefImage out = SameSize(mosaic, 3);
  for (int y = 0; y < mosaic.height; ++y)
    for (int x = 0; x < mosaic.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const auto& k = c == kGreen ? kKernelG : kKernelRb;
        double sum = 0.0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx)
            if (CfaColour(cfa, x + dx, y + dy) == c) sum += k[dy + 1][dx + 1] * At(mosaic, x + dx, y + dy);
        out.planes[c][static_cast<size_t>(y) * mosaic.width + x] = sum / 4.0;
      }
  return out;
}

RefImage RefDemosaicMalvar(const RefImage& mosaic, Cfa cfa) {
  RefImage out = SameSize(mosaic, 3);
  for (int y = 0; y < mosaic.height; ++y)
    for (int x = 0; x < mosaic.width; ++x) {
      const Colour site = CfaColour(cfa, x, y);
      for (int c = 0; c < 3; ++c) {
        double v;
        if (c == site) {
          v = At(mosaic, x, y);
        } else if (c == kGreen) {
          v = Convolve5(mosaic, x, y, kGreenAtRb);
        } else if (site == kGreen) {
          const bool horizontal = CfaColour(cfa, x + 1, y) == c;
          v = Convolve5(mosaic, x, y, horizontal ? kAtGreenHorizontal : kAtGreenVertical);
        } else {
          v = Convolve5(mosaic, x, y, kRbAtBr);
        }
        out.planes[c][static_cast<size_t>(y) * mosaic.width + x] = Clamp16(v);
      }
    }
  return out;
}

RefImage RefColorMatrix(const RefImage& rgb, const double m[9]) {
  RefImage out = SameSize(rgb, 3);
  for (size_t i = 0; i < rgb.planes[0].size(); ++i)
    for (int r = 0; r < 3; ++r)
      out.planes[r][i] = Clamp16(m[3 * r] * rgb.planes[0][i] + m[3 * r + 1] * rgb.planes[1][i] +
                                 m[3 * r + 2] * rgb.planes[2][i]);
  return out;
}

RefImage RefGamma(const RefImage& in, const GammaConfig& config) {
  RefImage out = SameSize(in, in.planes.size());
  for (size_t c = 0; c < in.planes.size(); ++c)
    for (size_t i = 0; i < in.planes[c].size(); ++i)
      out.planes[c][i] = Clamp16(kFullScale * GammaCurve01(config, Clamp16(in.planes[c][i]) / kFullScale));
  return out;
}

}  // namespace camsim::ref
