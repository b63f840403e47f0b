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
// An optional environment map (core/lens/flare_environment.h) adds bright
// sources outside the field of view: built once at Init into the stage's
// tables, they get glare and ghosts like the frame's tiles (their positions
// may lie far outside the frame: rectangles are clipped per row), and their
// haze is added to the frame's.
// Ghosts and haze add light (the reflections' loss from the image is
// neglected: it is below 1 % for the defaults).
//
// Streaming: which pixels are bright is known only after the whole frame, so
// a per-frame pre-pass over the input (ComputeFlare, run by the host before
// the frame, like the smear pre-pass) lists the bright 16 x 16 tiles with
// their excess, glare share and excess-weighted centroid, into caller memory
// passed through FrameInput::flare. The stage then needs no row context. It
// must see the image the pre-pass read, so it runs first (Pipeline::Configure
// refuses a plan with a running stage before it).
// With no bright pixel the stage copies its input (the planner leaves it out
// only when flare is off: which frames have bright pixels is not known at
// configure time). The pixels of tiles without a bright pixel source no glare
// or ghosts: the stage counts them as skipped (StageStats::skipped_px).
//
// Formats: in/out Radiance Q16.16, 3 channels; excess and sums uint64 Q16.16;
//          glare share per pixel RoundShift(excess * f_q16, 16) (the pre-pass
//          and the stage compute the same value); kernel Q0.32 (sum 2^32);
//          spreads via MulScaleU64 (rounded ties up); adds saturate at 2^32 - 1.
#pragma once

#include "core/base/fixed.h"
#include "core/base/span.h"
#include "core/lens/flare_environment.h"
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
  FlareEnvironment environment;   // bright light from outside the field of view (no map by default)
};

// A ghost's centre on one axis of `size` pixels: centre + scale * (pos - centre),
// in half pixels, rounded ties up. |pos| <= 2^22 and |scale| <= 4 (Q16.16)
// keep it within 64-bit arithmetic and its result within +-2^25.
inline int32_t FlareGhostCentre(int32_t pos, int32_t scale_q16, int size) {
  const int64_t c2 = size - 1;  // twice the optical centre
  return static_cast<int32_t>(RoundShift(c2 * 65536 + int64_t{scale_q16} * (2 * int64_t{pos} - c2), 17));
}

// One bright tile of a frame.
struct FlareSource {
  int32_t x = 0, y = 0;     // excess-weighted centroid, pixels
  uint64_t excess[3] = {};  // sum of radiance above the threshold, Q16.16
  uint64_t glare[3] = {};   // the glare share taken from its pixels, Q16.16
};

// A frame's flare statistics (ComputeFlare), read by the stage.
struct FlareFrame {
  const FlareSource* sources = nullptr;  // in ComputeFlare's order: tile rows top to bottom
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
  // Copies the glare kernel when glare_radius and blades are previous's.
  Status InitFrom(Arena& tables, const Stage& previous, int* copied) override;
  void ProcessRow(const RowArgs& args) const override;

  // The pre-pass's part of the model (shared so both compute the same values).
  uint32_t threshold_q16() const { return threshold_; }
  uint32_t glare_q16() const { return glare_q16_; }
  // The environment map's sources (after Init) and what the map gave.
  Span<const FlareSource> environment_sources() const { return {env_sources_, static_cast<size_t>(env_count_)}; }
  const FlareEnvironmentSummary& environment_summary() const { return env_summary_; }
  // ProcessRow visits only the frame's sources whose glare or ghosts can
  // reach the row (found by tile row); tests can make it visit every source
  // to compare the two (the same bytes).
  void ForceEverySourceForTest(bool force) { every_source_ = force; }
  // Pixels of row y in tiles without a bright pixel: no glare or ghosts come
  // from them. ProcessRow adds them to StageStats::skipped_px.
  static int PixelsOutsideSources(const FlareFrame& frame, int y, int width);

 private:
  FlareConfig config_;
  SensorGeometry geometry_;
  uint32_t threshold_ = 0;
  uint32_t glare_q16_ = 0;   // glare fraction, Q0.16
  int kernel_side_ = 0;
  const uint32_t* kernel_ = nullptr;            // Q0.32, kernel_side_^2, sums to 2^32
  // Init; the glare kernel is copied from `same_kernel` when it is not null.
  Status Build(Arena& tables, const FlareStage* same_kernel);
  Status BuildGhostsAndEnvironment(Arena& tables);  // Init after the kernel
  const int16_t* ghost_half_width_[kMaxGhosts] = {};  // per row of the ghost, -1 = none
  int ghost_radius_[kMaxGhosts] = {};
  UScale ghost_factor_[kMaxGhosts][3];          // intensity * tint / area
  int32_t ghost_scale_q16_[kMaxGhosts] = {};
  const FlareSource* env_sources_ = nullptr;    // tables, FlareEnvironmentCapacity entries
  int env_count_ = 0;
  uint32_t env_haze_[3] = {};                   // Q16.16 added to every pixel
  FlareEnvironmentSummary env_summary_;
  bool every_source_ = false;  // tests only
  void AddSource(const FlareSource& src, const RowArgs& a) const;
  // AddSource for the frame's sources that can reach row a.y, in their order.
  void AddFrameSources(const FlareFrame& frame, const RowArgs& a) const;
  // The tile rows whose sources' ghost g can reach row y (a superset); false if none.
  bool GhostTileRows(int g, int y, int* first, int* last) const;
};

// Entries ComputeFlare may fill (one per tile).
int FlareMaxSources(const SensorGeometry& geometry);
// The pre-pass: bright tiles of `input` into `storage`, and the haze. The
// config must have passed Pipeline::Configure.
void ComputeFlare(const FlareConfig& config, const SensorGeometry& geometry, const FrameInput& input,
                  Span<FlareSource> storage, FlareFrame* out);

}  // namespace camsim
