// Vignetting (paper eq. 3-4): photons times a gain that falls towards the
// corners, from a curve over the normalised squared radius or from a measured
// mask image.
//
// Normalised squared radius of pixel (x, y) in a W x H frame, with the optical
// centre at the frame centre ((W-1)/2, (H-1)/2) for 0-based pixel centres:
//   rho = ((2x - (W-1))^2 + (2y - (H-1))^2) / ((W-1)^2 + (H-1)^2)
// rho is 0 at the centre and exactly 1 at the corner pixels. (Eq. 4 writes
// x - W/2, which puts the centre half a pixel off and is not symmetric.)
//
// Curve: kCurvePoints gains at rho = i / (kCurvePoints - 1), interpolated
// linearly. Cos4 builds it as cos^4 of the field angle, 1 / (1 + r^2/f^2)^2,
// with r the radius in pixels and f the focal length in pixels (basic IEEE
// operations only). A table from config is resampled onto the same points.
//
// Formats: in/out Photons Q24.8 (3 channels, or 1 mosaic channel: the
//                 planner runs a Bayer CFA ahead of this stage, see pipeline.h).
//          rho index: Q?.16 position in the curve, computed as
//            (dx2 + dy2) * R >> s with R = (kCurvePoints-1) * 2^16 / denom
//            as a UScale (exact integer inputs, one rounding);
//          gain: Q2.14 (0 .. 3.99994), linear interpolation rounded (ties up);
//          product: 32 x 16 bits in 64, rounded, saturated at 2^32 - 1.
// Mask mode: a caller image of Q2.14 gains, one per pixel (FrameInput).
//
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

enum class VignettingMode : uint8_t { kOff, kCos4, kTable, kMask };

struct VignettingConfig {
  VignettingMode mode = VignettingMode::kOff;
  double focal_length_px = 0.0;     // Cos4: focal length in pixels (> 0)
  // Table: gains at evenly spaced rho from 0 (centre) to 1 (corner), 2..64 values.
  static constexpr int kMaxTable = 64;
  double table[kMaxTable] = {};
  int table_count = 0;
};

class VignettingStage final : public Stage {
 public:
  static constexpr int kCurvePoints = 257;  // 256 segments: < 1e-4 interpolation error for cos4
  static constexpr int kGainFracBits = 14;  // Q2.14

  Status Configure(const VignettingConfig& config, const SensorGeometry& geometry, bool has_mask);
  const char* name() const override { return "vignetting"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override;
  void CountTables(WorkspaceCounter& counter) const override;
  Status Init(Arena& tables) override;
  void ProcessRow(const RowArgs& args) const override;

  // The curve gain (double) at normalised squared radius rho (for tests/reference).
  double CurveGain(double rho) const;
  // Tests: compute the curve gains by the portable loop even where the CPU
  // has AVX2 lanes for them. Takes effect at the next Init().
  void ForcePortablePathForTest(bool force) { force_portable_ = force; }

 private:
  VignettingConfig config_;
  SensorGeometry geometry_;
  UScale rho_to_index_;       // (dx2 + dy2) -> curve position Q.16
  uint16_t* curve_ = nullptr; // kCurvePoints + 1 gains, Q2.14 (last repeated)
  uint32_t* dx2_ = nullptr;   // (2x - (W-1))^2 per column
  bool avx2_ = false;             // curve gains in AVX2 lanes (set by Init)
  bool force_portable_ = false;
};

// The stage's curve gains for callers outside the stream (the smear
// pre-pass): BuildVignettingCurve fills kCurvePoints + 1 Q2.14 gains and the
// squared-radius scale, VignettingCurveGain interpolates them exactly as
// ProcessRow does, for dx2 + dy2 = (2x - (W-1))^2 + (2y - (H-1))^2.
Status BuildVignettingCurve(const VignettingConfig& config, const SensorGeometry& geometry, uint16_t* curve,
                            UScale* rho_to_index);
inline uint32_t VignettingCurveGain(const uint16_t* curve, UScale rho_to_index, uint32_t dx2_plus_dy2) {
  // Curve position, Q.16: integer part selects the segment, fraction interpolates.
  const uint32_t pos = rho_to_index.Apply(dx2_plus_dy2);
  const uint32_t i = pos >> 16, f = pos & 0xFFFF;
  const uint32_t g0 = curve[i], g1 = curve[i + 1];
  // g0 + RoundShift((g1 - g0) f, 16) as one non-negative sum: the gains
  // are below 2^16, so g0 (2^16 - f) + g1 f + 2^15 < 2^32.
  return (g0 * (0x10000 - f) + g1 * f + 0x8000) >> 16;  // Q2.14
}

// VignettingCurveGain for n columns, gain[k] for dx2[k] + dy2, in AVX2
// lanes where the CPU has them (the same integers).
void VignettingCurveGains(const uint16_t* curve, UScale rho_to_index, const uint32_t* dx2, uint32_t dy2, int n,
                          uint32_t* gain);

// Double reference: the gain at pixel (x, y) for this config (curve modes).
double ReferenceVignettingGain(const VignettingConfig& config, const SensorGeometry& g, int x, int y);

}  // namespace camsim
