// Lens flare (paper eq. 5-6; docs/model-notes.md): light from very bright
// pixels scattered inside the lens. Three parts, all driven by the radiance
// above a threshold (the "excess") of the frame's bright pixels:
//   glare    a share glare_fraction of each bright pixel's excess is taken
//            from it and spread by a normalised aperture kernel (a glow and
//            diffraction spikes: `blades` spikes if even, 2 x blades if odd)
//            of radius glare_radius around its tile's centroid (eq. 5 as a
//            sparse convolution: cost follows the number of bright tiles);
//            the glare conserves energy (kernel weights sum to exactly 2^32;
//            what falls outside the frame is lost);
//   ghosts   up to 4 reflections of each bright tile at
//            centre + scale * (source - centre) (eq. 6; scale -1 is the
//            mirror through the centre, x -> width - 1 - x), each a disc
//            (blades = 0) or regular polygon of ghost_radius_px, holding
//            ghost_intensity * tint[c] of the tile's excess, spread evenly;
//   haze     veiling glare: haze * (the frame's total excess) / pixels added
//            everywhere.
// Ghosts and haze add light (the reflections' loss from the image is
// neglected: it is below 1 % for the defaults).
//
// Streaming: which pixels are bright is known only after the whole frame, so
// a per-frame pre-pass over the input (ComputeFlare, run by the host before
// the frame, like the smear pre-pass) lists the bright 16 x 16 tiles with
// their excess, glare share and excess-weighted centroid, into caller memory
// passed through FrameInput::flare. The stage then needs no row context.
// With no bright pixel the stage copies its input (the planner leaves it out
// only when flare is off: which frames have bright pixels is not known at
// configure time).
//
// Formats: in/out Radiance Q16.16, 3 channels; excess and sums uint64 Q16.16;
//          glare share per pixel RoundShift(excess * f_q16, 16) (the pre-pass
//          and the stage compute the same value); kernel Q0.32 (sum 2^32);
//          spreads via MulScaleU64 (rounded ties up); adds saturate at 2^32 - 1.
#pragma once

#include "core/base/span.h"
#include "core/pipeline/stage.h"

namespace camsim {

inline constexpr int kMaxGhosts = 4;
inline constexpr int kFlareTile = 16;
inline constexpr int kMaxGlareRadius = 32;
inline constexpr int kMaxGhostRadius = 64;

struct FlareConfig {
  bool enabled = false;
  double threshold = 8.0;         // radiance above which a pixel sources flare (1.0 ~ white paper)
  double glare_fraction = 0.05;   // share of the excess spread by the glare kernel
  int glare_radius = 16;          // pixels, 1 .. 32
  int blades = 6;                 // aperture blades (spikes and ghost polygons); 0 = round
  double haze = 1e-3;             // veiling glare: share of the total excess spread over the frame
  int ghost_count = 2;            // 0 .. 4
  double ghost_scale[kMaxGhosts] = {-1.0, -0.5, 0.5, -1.5};
  double ghost_radius_px[kMaxGhosts] = {24.0, 10.0, 6.0, 40.0};
  double ghost_intensity[kMaxGhosts] = {2e-3, 4e-3, 4e-3, 1e-3};
  double ghost_tint[3 * kMaxGhosts] = {0.6, 1.0, 0.8, 1.0, 0.7, 0.4, 0.5, 0.8, 1.0, 1.0, 1.0, 1.0};
};

// One bright tile of a frame.
struct FlareSource {
  int32_t x = 0, y = 0;     // excess-weighted centroid, pixels
  uint64_t excess[3] = {};  // sum of radiance above the threshold, Q16.16
  uint64_t glare[3] = {};   // the glare share taken from its pixels, Q16.16
};

// A frame's flare statistics (ComputeFlare), read by the stage.
struct FlareFrame {
  const FlareSource* sources = nullptr;
  int count = 0;
  uint32_t haze[3] = {};  // veiling glare added to every pixel, Q16.16
};

class FlareStage final : public Stage {
 public:
  Status Configure(const FlareConfig& config, const SensorGeometry& geometry);
  const char* name() const override { return "flare"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override;
  void CountTables(WorkspaceCounter& counter) const override;
  Status Init(Arena& tables) override;
  void ProcessRow(const RowArgs& args) const override;

  // The pre-pass's part of the model (shared so both compute the same values).
  uint32_t threshold_q16() const { return threshold_; }
  uint32_t glare_q16() const { return glare_q16_; }

 private:
  FlareConfig config_;
  SensorGeometry geometry_;
  uint32_t threshold_ = 0;
  uint32_t glare_q16_ = 0;   // glare fraction, Q0.16
  int kernel_side_ = 0;
  const uint32_t* kernel_ = nullptr;            // Q0.32, kernel_side_^2, sums to 2^32
  const int16_t* ghost_half_width_[kMaxGhosts] = {};  // per row of the ghost, -1 = none
  int ghost_radius_[kMaxGhosts] = {};
  UScale ghost_factor_[kMaxGhosts][3];          // intensity * tint / area
  int32_t ghost_scale_q16_[kMaxGhosts] = {};
};

// Entries ComputeFlare may fill (one per tile).
int FlareMaxSources(const SensorGeometry& geometry);
// The pre-pass: bright tiles of `input` into `storage`, and the haze. The
// config must have passed Pipeline::Configure.
void ComputeFlare(const FlareConfig& config, const SensorGeometry& geometry, const FrameInput& input,
                  Span<FlareSource> storage, FlareFrame* out);

}  // namespace camsim
