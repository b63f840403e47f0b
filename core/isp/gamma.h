// Gamma: linear signal -> display encoding through a 65536-entry table.
//
//   kSrgb:  IEC 61966-2-1: 12.92 v for v <= 0.0031308, else 1.055 v^(1/2.4) - 0.055
//   kPower: v^(1/gamma)
//   kLinear: v (the stage is then left out, and the output stays linear)
//
// Formats: in  Linear  Q0.16 (1 channel, mosaic or mono, or 3 channels)
//          out Encoded Q0.16, same channels
//          table: uint16_t per input code 0..65535 (and one spare), each entry
//          round(65535 * curve(i / 65535)) from the double curve (detmath::Pow),
//          ties up; inputs above 65535 read the last entry. (Init reaches the
//          same entries mostly through detmath::PowFast: see gamma.cc.)
// Error against the exact curve: <= 0.5 LSB (one rounding per entry) plus
// detmath::Pow's error.
#pragma once

#include "core/pipeline/stage.h"

namespace camsim {

enum class GammaCurve : uint8_t { kLinear, kSrgb, kPower };

struct GammaConfig {
  GammaCurve curve = GammaCurve::kLinear;
  double gamma = 2.2;  // kPower: encodes v^(1/gamma); in [0.1, 10]
};

class GammaStage final : public Stage {
 public:
  static constexpr size_t kTableSize = 65536;  // one entry per Q0.16 code
  static constexpr double kMinGamma = 0.1;
  static constexpr double kMaxGamma = 10.0;

  Status Configure(const GammaConfig& config, const SensorGeometry& geometry);
  const char* name() const override { return "gamma"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  // "gamma curve is linear" for kLinear.
  const char* IdentityReason() const override;
  void CountTables(WorkspaceCounter& counter) const override;
  Status Init(Arena& tables) override;  // builds the table
  Status InitFrom(Arena& tables, const Stage& previous, int* copied) override;  // copies it for the same curve
  void ProcessRow(const RowArgs& args) const override;

  // The curve in double, v and result in [0, 1] (what the table samples).
  double Curve(double v) const;
  const uint16_t* table() const { return table_; }  // after Init

 private:
  double CurveWith(double v, double (*pow)(double, double)) const;  // Curve with another Pow

  GammaConfig config_;
  uint16_t* table_ = nullptr;
  bool avx2_ = false;    // the lookup in gathers (chosen at Init)
  bool avx512_ = false;
};

}  // namespace camsim
