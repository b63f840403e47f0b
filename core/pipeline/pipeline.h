// The pipeline: an ordered list of stages from configuration, a planner that
// leaves out what the scene does not need, and a strip-streaming driver.
//
// Streaming: every stage keeps its output rows in a ring of line buffers just
// deep enough for the widest window of rows its consumer reads at once
// (Stage::InputRows; RowsAbove + RowsBelow + 1 for a fixed neighbourhood).
// A strip [y0, y1) of output rows is produced by pulling rows through the chain
// in order; rows outside the frame are reflected (reflect-101). Each worker has
// its own rings, so N workers run N strips at once. Because ProcessRow depends
// only on its input rows, every strip height and worker count gives the same
// bytes. No frame-sized buffer exists in the core.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/aperture/exposure.h"
#include "core/isp/black_level.h"
#include "core/isp/color_matrix.h"
#include "core/isp/demosaic.h"
#include "core/isp/gamma.h"
#include "core/isp/white_balance.h"
#include "core/lens/motion_blur.h"
#include "core/lens/dof.h"
#include "core/lens/distortion.h"
#include "core/lens/flare.h"
#include "core/lens/vignetting.h"
#include "core/pipeline/stage.h"
#include "core/sensor/blooming.h"
#include "core/sensor/cfa.h"
#include "core/sensor/emva.h"

namespace camsim {

// The stages in their default order (also the order of the paper's Figure 2
// for the ones it has). New stages are added here and in Pipeline's members.
enum class StageId : uint8_t {
  kDofGather,
  kDofRows,
  kDofColumns,
  kMotionBlur,
  kDistortion,
  kFlare,
  kExposure,
  kVignetting,
  kCfa,
  kBlooming,
  kSensor,
  kBlackLevel,
  kWhiteBalance,
  kDemosaic,
  kColorMatrix,
  kGamma,
  kCount
};
inline constexpr int kStageCount = static_cast<int>(StageId::kCount);
const char* StageName(StageId id);
// Looks a stage up by its name; false when there is none.
bool StageFromName(const char* name, StageId* id);

struct FrameInput {
  ImageView<const uint32_t> radiance[3];           // R, G, B; Q16.16, required
  ImageView<const uint16_t> vignetting_mask;       // Q2.14 gain, optional
  // Depth (core/pipeline/inverse_depth.h), needed by depth of field and by
  // motion blur from camera translation:
  ImageView<const uint32_t> inverse_depth;         // 1 / depth in 1/m, Q12.20
  // Renderer motion (motion blur with motion.source = vectors):
  ImageView<const int32_t> motion_vectors[2];      // x, y: px per frame interval, Q16.16, rows downwards
  const FlareFrame* flare = nullptr;               // ComputeFlare (core/lens/flare.h), when flare is on
  const uint32_t* smear_e = nullptr;               // per column, Q24.8 e-: ComputeSmear (core/sensor/smear.h),
                                                   // required when sensor smear is on
};

struct PipelineConfig {
  SensorGeometry geometry;
  uint64_t seed = 1;  // keys all randomness (with frame, x, y, channel)
  bool skip_idle = true;  // Stage::set_skip_idle of every stage: the same bytes either way

  // Stages in run order; a stage not listed does not run. The planner runs a
  // Bayer CFA ahead of the exposure and vignetting right before it (they are
  // pointwise and colour-blind, so the bytes are the same and they process one
  // plane instead of three); the plan lists the stages as run and notes the move.
  // Flare first: its pre-pass (ComputeFlare) reads the frame input, so no running stage may come before it.
  StageId order[kStageCount] = {StageId::kFlare,       StageId::kDofGather,  StageId::kDofRows,
                                StageId::kDofColumns,  StageId::kMotionBlur, StageId::kDistortion,
                                StageId::kExposure,    StageId::kVignetting, StageId::kCfa,
                                StageId::kBlooming,    StageId::kSensor,     StageId::kBlackLevel,
                                StageId::kWhiteBalance, StageId::kDemosaic,  StageId::kColorMatrix,
                                StageId::kGamma};
  int order_count = kStageCount;

  DofConfig dof;  // depth of field and structural blur (dof_gather, dof_rows, dof_columns)
  MotionBlurConfig motion_blur;
  DistortionConfig distortion;
  FlareConfig flare;
  ExposureConfig exposure;
  VignettingConfig vignetting;
  CfaConfig cfa;
  BloomingConfig blooming;
  SensorConfig sensor;
  BlackLevelConfig black_level;
  WhiteBalanceConfig white_balance;
  DemosaicConfig demosaic;
  ColorMatrixConfig color_matrix;
  GammaConfig gamma;
};

// White balance's white level for a configuration: the sensor's full well
// (SensorSaturationDn) through the black level in use (WhiteLevel).
double PipelineWhiteLevel(const PipelineConfig& config);

// The planner's verdict on one configured stage.
struct PlanEntry {
  StageId id = StageId::kExposure;
  bool runs = false;
  const char* reason = "";  // why it was left out (empty when it runs)
  const char* note = "";    // why the planner moved it from its configured place (empty when it did not)
  LineFormat out;           // its output format (when it runs)
};

struct Plan {
  PlanEntry entries[kStageCount];
  int count = 0;
  int running = 0;            // entries that run
  LineFormat input;           // format entering the first stage
  LineFormat output;          // format leaving the last running stage
};

// Where a run puts rows of a stage's output: an image in the caller's memory.
// Samples are converted on the way: kU32 copies; kU16 takes Q0.16 or DN values
// as they are (saturating); kU8 maps Q0.16 to 0..255 with round(v * 255 / 65535).
enum class TapFormat : uint8_t { kU8, kU16, kU32 };
struct Tap {
  int stage = -1;  // index among the running stages; -1 = the last one
  TapFormat format = TapFormat::kU16;
  void* data = nullptr;   // interleaved channels, height rows
  ptrdiff_t stride = 0;   // in samples
};
// Writes row y of a tap from the row's planes (channels: 1 or 3), converted
// as above. The pipeline calls it for each tapped row; tests call it directly.
void WriteTapRow(const Tap& tap, const uint32_t* const* rows, int channels, int y, int width);

// Per-worker measurements of one ProcessStrip call series.
struct WorkerStats {
  StageStats stage[kStageCount];  // indexed by running-stage index
};

// A monotonic clock the caller may lend for per-stage timing (no clock in the core).
struct Clock {
  uint64_t (*now)(void* context) = nullptr;
  void* context = nullptr;
};

class Pipeline {
 public:
  // Validates every configured stage, plans, and sizes the workspace. The only
  // step besides Init that can fail.
  // previous (optional, a reconfiguration): another pipeline, configured
  // (the lens's band ranges) or also initialised (its workspace still alive:
  // a pipeline cannot tell that its workspace was freed), and unchanged while
  // the call runs; a stage whose configuration equals its counterpart's there
  // takes what that computed instead of computing it again (Stage::InitFrom).
  // The bytes are those of a pipeline configured without it.
  Status Configure(const PipelineConfig& config, int workers, bool has_vignetting_mask,
                   const Pipeline* previous = nullptr);
  const Plan& plan() const { return plan_; }

  // Workspace: tables shared by all workers + per worker line rings and scratch.
  size_t WorkspaceBytes() const;
  size_t TableBytes() const { return table_bytes_; }
  size_t WorkerBytes() const { return worker_bytes_; }

  // Binds the caller's workspace (WorkspaceBytes() long) and builds tables;
  // previous as for Configure: the tables it built for the same inputs are copied.
  Status Init(Span<uint8_t> workspace, const Pipeline* previous = nullptr);
  // The tables running stage i copied from the previous pipeline at Init.
  int CopiedTables(int i) const { return copied_tables_[i]; }

  // Checks that a frame's inputs match the configuration (sizes, required
  // planes). Call before ProcessStrip: processing itself cannot fail.
  Status CheckInput(const FrameInput& input) const;

  // Whether stage `id` is in the plan and runs (after Configure).
  bool Runs(StageId id) const;

  // The per-frame pre-passes CheckInput asks for, each when it is on and its
  // stage runs: the flare's bright tiles and haze (ComputeFlare) and the
  // smear's column charges (ComputeSmear, for the sensor). The caller's storage holds PrepassFlareSources()
  // FlareSource and PrepassSmearEntries() uint32 entries (0 when off, then
  // empty spans do). Returns `input` with them attached; the storage and
  // *flare must outlive its use. Call after Init.
  int PrepassFlareSources() const;
  int PrepassSmearEntries() const;
  FrameInput RunPrepasses(const FrameInput& input, Span<FlareSource> flare_sources, FlareFrame* flare,
                          Span<uint32_t> smear) const;

  // Produces output rows [y0, y1) of frame `frame` with worker `worker`
  // (0 <= worker < workers). Cannot fail. Different workers may run at once on
  // disjoint strips. Taps receive rows [y0, y1) of their stage's output.
  // stats, when non-null, accumulates measurements for rows [y0, y1).
  void ProcessStrip(const FrameInput& input, uint32_t frame, int y0, int y1, int worker,
                    const Tap* taps, int tap_count, WorkerStats* stats, const Clock* clock) const;

  // Convenience: the whole frame on worker 0 in strips of strip_rows.
  void ProcessFrame(const FrameInput& input, uint32_t frame, int strip_rows, const Tap* taps,
                    int tap_count, WorkerStats* stats, const Clock* clock) const;

  // Running stage i (0 <= i < plan().running) and its output format, for
  // tools that drive one stage alone (the per-stage benchmark).
  const Stage& running_stage(int i) const { return *run_[i]; }
  LineFormat running_format(int i) const { return run_format_[i]; }

  int width() const { return config_.geometry.width; }
  int height() const { return config_.geometry.height; }
  const PipelineConfig& config() const { return config_; }
  // The flare stage, for its environment-map summary (valid after Init).
  const FlareStage& flare_stage() const { return flare_; }

 private:
  bool FlarePrepass() const;
  bool SmearPrepass() const;
  struct StripState;
  Status SizeRing(int stage, int* slots, int* widest) const;
  uint32_t* RingRow(const StripState& s, int ring, int row, int channel) const;
  void FillMargins(uint32_t* row) const;
  RowIn RowOf(const StripState& s, int ring, int row) const;
  void Produce(StripState& s, int ring, int row) const;
  Stage* StageFor(StageId id);
  const Stage* StageFor(StageId id) const;
  // Stage `id` when this pipeline is initialised and ran it, else nullptr.
  const Stage* InitialisedStage(StageId id) const;
  StageId NextRunning(const StageId* order, int from, int count) const;

  PipelineConfig config_;
  Plan plan_;
  int workers_ = 1;
  int margin_ = 0;
  bool input_direct_ = true;        // first stage reads the caller's rows directly
  const Stage* run_[kStageCount] = {};  // running stages, in order
  LineFormat run_format_[kStageCount];   // their output formats
  int run_count_ = 0;
  int ring_slots_[kStageCount + 1] = {};     // [0] = input ring, [i + 1] = stage i's output
  int ring_channels_[kStageCount + 1] = {};
  int max_window_ = 1;              // the widest InputRows window: RowIn slots per worker
  size_t scratch_bytes_ = 0;
  size_t state_bytes_ = 0;                    // all running stages' StateBytes
  size_t state_offset_[kStageCount] = {};     // each one's offset in it
  size_t table_bytes_ = 0;
  size_t worker_bytes_ = 0;
  uint8_t* workers_base_ = nullptr;
  bool configured_ = false;   // the last Configure succeeded
  bool initialised_ = false;
  int copied_tables_[kStageCount] = {};  // per running stage, at Init

  DofGatherStage dof_gather_;
  DofRowStage dof_rows_;
  DofColumnStage dof_columns_;
  MotionBlurStage motion_blur_;
  DistortionStage distortion_;
  FlareStage flare_;
  ExposureStage exposure_;
  VignettingStage vignetting_;
  CfaStage cfa_;
  BloomingStage blooming_;
  SensorStage sensor_;
  BlackLevelStage black_level_;
  WhiteBalanceStage white_balance_;
  DemosaicStage demosaic_;
  ColorMatrixStage color_matrix_;
  GammaStage gamma_;
};

}  // namespace camsim
