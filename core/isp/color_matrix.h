// Colour matrix (CCM): a 3x3 linear map of R, G, B.
//
//   out_i = clamp(round(sum_j m[3i + j] * in_j), 0, 65535)
//
// Formats: in/out Linear Q0.16, 3 channels
//          coefficients Q5.24 signed (int32; [-16, 16] needs 5 integer bits).
//          Each row keeps its sum: the off-diagonal coefficients are rounded
//          (ties up) and the diagonal one takes the row's rounding remainder,
//          so a row summing to 1 maps grey to exactly the same grey.
//          accumulator int64: |q| <= 2^28 and samples <= 65535 give |sum| < 2^46;
//          one rounding (RoundShift by 24, ties up), clamped to [0, 65535].
// Error: <= 0.5 LSB against the same matrix with the quantised coefficients;
// against the configured doubles at most 0.5 + 3 * 2^-25 * 65535 = 0.506 LSB
// (the row sum's and the two off-diagonal coefficients' roundings).
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

struct ColorMatrixConfig {
  // Row-major: out_r = m[0] r + m[1] g + m[2] b, out_g = m[3] r + ..., each in [-16, 16].
  double m[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
};

class ColorMatrixStage final : public Stage {
 public:
  static constexpr int kFracBits = 24;  // Q5.24
  static constexpr double kMaxCoefficient = 16.0;

  Status Configure(const ColorMatrixConfig& config, const SensorGeometry& geometry);
  const char* name() const override { return "color_matrix"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  // "colour matrix is the identity" when the quantised matrix is.
  const char* IdentityReason() const override;
  void ProcessRow(const RowArgs& args) const override;

  int32_t coefficient(int i) const { return q_[i]; }  // Q5.24, row-major

 private:
  int32_t q_[9] = {};
  bool mono_ = false;
};

}  // namespace camsim
