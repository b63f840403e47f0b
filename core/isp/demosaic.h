// Demosaic: a Bayer mosaic -> R, G, B at every pixel. Two methods:
//
// Bilinear (paper eq. 23-24): the zero-filled colour planes convolved with
//   K_rb = [1 2 1; 2 4 2; 1 2 1] / 4 and K_g = [0 1 0; 1 4 1; 0 1 0] / 4,
//   computed per site type: the native colour is copied, a missing colour is
//   the mean of its 2 or 4 nearest samples: (sum + 1) >> 1 or (sum + 2) >> 2.
// Malvar-He-Cutler 2004 (gradient-corrected bilinear): the paper's 5x5
//   kernels (weights / 8, some halves), here doubled to integers / 16:
//     G at R/B:            8 c + 4 (N1+S1+W1+E1) - 2 (N2+S2+W2+E2)
//     own colour at G      10 c + 8 (W1+E1) - 2 (W2+E2) - 2 (diagonals) + (N2+S2)
//       (R at G in an R row, B at G in a B row; the other colour is the transpose)
//     R at B, B at R:      12 c + 4 (diagonals) - 3 (N2+S2+W2+E2)
//   (N1 = one row up, N2 = two rows up, ...), signed sum, RoundShift by 4,
//   clamped to [0, 65535].
//
// Formats: in  Linear Q0.16, 1 channel Bayer mosaic (any of the four phases)
//          out Linear Q0.16, 3 channels
//          sums in 32 bits: linear samples are at most 65535 (every stage
//          that makes them saturates there), so a Malvar sum lies in
//          [-12, 28] * 65535 and a bilinear one in [0, 4 * 65535]. One rounding
//          (ties up): exactly the rounded convolution, error <= 0.5 LSB.
// Context: 1 row / column each side for bilinear, 2 for Malvar, reflect-101
// (which keeps the CFA phase for sizes >= 2). A flat field comes out flat and
// exact with both methods, since every kernel's weights sum to 1.
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

enum class DemosaicMethod : uint8_t { kBilinear, kMalvar };

struct DemosaicConfig {
  DemosaicMethod method = DemosaicMethod::kBilinear;
};

class DemosaicStage final : public Stage {
 public:
  Status Configure(const DemosaicConfig& config, const SensorGeometry& geometry);
  const char* name() const override { return "demosaic"; }
  // Refuses anything but a 1-channel linear Bayer mosaic (e.g. a mono CFA).
  Result<LineFormat> Plan(LineFormat in) const override;
  // Left out only for a mono sensor (nothing to interpolate); otherwise it
  // changes 1 channel into 3.
  const char* IdentityReason() const override;
  int RowsAbove() const override { return radius_; }
  int RowsBelow() const override { return radius_; }
  int Margin() const override { return radius_; }
  void ProcessRow(const RowArgs& args) const override;

 private:
  // One output row for either method, chosen at Configure. up2 .. down2: input
  // rows y-2 .. y+2 (bilinear reads only up1 .. down1; up2 and down2 are then
  // null); green_x: parity of the G sites in this row; own: output of the
  // row's non-green colour, other: of the remaining one. No two rows overlap.
  using RowFn = void (*)(const uint32_t* up2, const uint32_t* up1, const uint32_t* mid, const uint32_t* down1,
                         const uint32_t* down2, int width, int green_x, uint32_t* own, uint32_t* green,
                         uint32_t* other);

  Cfa cfa_ = Cfa::kBayerRG;
  int radius_ = 1;
  RowFn row_fn_ = nullptr;
};

}  // namespace camsim
