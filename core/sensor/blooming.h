// Blooming: charge above the full well spills along its column (the vertical
// direction of a CCD or of a CMOS column without anti-blooming drain) into
// neighbours that still have room. Runs on photons just before the sensor.
//
// Model, on a column's mean charge m(k) = photons(k) * QE(colour at k)
// (without PRNU and dark charge: they are small beside a saturating signal):
//   level(k) = min(m(k), W), excess(k) = m(k) - level(k), W = full well
//   down pass, k increasing:  pixel k takes min(W - level(k), carry) from the
//     carry, then adds floor(excess(k) / 2) to it
//   up pass, k decreasing:    the same with the other half, excess - floor(excess / 2)
//   charge carried past the frame's first or last row is lost (a drain).
// Total charge is conserved except what leaves the frame. The output is the
// photon count that gives the resulting charge, level(k) / QE(colour at k),
// except at a full well: a pixel whose charge blooming changed to W (its own
// excess spilled, or filled by a spill) comes out as kFullWellPhotons, the
// format's maximum, so that the sensor reads it saturated (whenever QE * PRNU
// gain * 2^24 photons >= W, i.e. for any QE above 0.06 at the largest full
// well). A full well holds W electrons, not W on average: as W / QE photons,
// PRNU below 1 and the shot noise drawn on them would put about half of the
// full pixels below saturation. A pixel at exactly W that nothing changed
// passes through, as without blooming. (The run report's mean of this stage
// averages these markers.)
//
// Streaming: output row y runs the two passes on the window [y - R, y + R]
// (R = rows) of its column, with no carry entering the window. That equals the
// whole-column model wherever no spill that reaches y starts, or travels, more
// than R rows away; the reference (blooming_ref.h) is the whole-column model,
// and the tests check that they agree where spills stay inside the window.
// Columns go in groups of 16. A group whose windows hold no pixel above the
// full well is passed through unchanged (exactly); such pixels are found by
// comparing photons with a per-colour threshold (a vectorisable pass),
// keeping per column the last row over it in the strip's state: the first
// row of a strip scans its whole window, each following row only the row
// that enters it. The other groups run the two passes in 64-bit lanes, one
// column per lane (the same integers as column by column).
//
// Formats: in/out Photons Q24.8, 1 channel (mosaic or mono) or 3.
//          charge Q.8 electrons in uint64: photons * QE (Q1.16), rounded ties up;
//          back to photons: level * 2^16 / QE, rounded ties up, saturated at 2^32 - 1.
//          A colour with QE 0 never saturates and receives no charge (spill into it is lost).
// Scratch: the lanes' charge and excess, 2 x 8 x 16 bytes per window row, and
// a partial last group's columns, 4 x 16 bytes per window row (2R + 1 rows).
#pragma once

#include "core/pipeline/stage.h"
#include "core/sensor/emva.h"

namespace camsim {

struct BloomingConfig {
  bool enabled = false;
  int rows = 16;  // R: how far (rows) a spill is followed each way, 1 .. kMaxBloomingRows
};

inline constexpr int kMaxBloomingRows = 64;  // = kMaxContextRows
// A full well's output (see above): Photons Q24.8 saturated.
inline constexpr uint32_t kFullWellPhotons = 0xFFFFFFFFu;

class BloomingStage final : public Stage {
 public:
  Status Configure(const BloomingConfig& config, const SensorConfig& sensor, const SensorGeometry& geometry);
  const char* name() const override { return "blooming"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override;
  int RowsAbove() const override { return config_.enabled ? config_.rows : 0; }
  int RowsBelow() const override { return config_.enabled ? config_.rows : 0; }
  size_t ScratchBytes(int width) const override;
  size_t StateBytes(int width) const override;
  void BeginStrip(uint8_t* state) const override;
  void ProcessRow(const RowArgs& args) const override;

 private:
  BloomingConfig config_;
  uint32_t over_[3] = {};  // per colour: photons at or above which the charge exceeds the well
  SensorGeometry geometry_;
  uint32_t qe_q16_[3] = {};
  uint64_t full_well_q8_ = 0;
};

}  // namespace camsim
