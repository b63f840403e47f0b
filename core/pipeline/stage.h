// The stage contract. Every stage of the pipeline is a class derived from Stage:
//
//   1. Configure(config, geometry)  validate a plain config struct (identity
//                                   defaults) and keep it; the only place a
//                                   config value can be refused.
//   2. Plan(in) / IdentityReason()  what line format it outputs, and whether it
//                                   would change nothing (then it is left out).
//   3. InputRows (or RowsAbove/RowsBelow), Margin, CountTables, ScratchBytes
//                                   which input rows each output row reads and
//                                   how much memory it needs, known before
//                                   anything runs.
//   4. Init(tables)                 builds its read-only tables in the caller's
//                                   workspace; can fail only if that is too small.
//      InitFrom(tables, previous)   the same, copying the tables whose inputs
//                                   equal those of `previous` (a reconfiguration).
//   5. ProcessRow(args)             produces one output row from a window of
//                                   input rows. Cannot fail, allocates nothing,
//                                   is const (safe on many workers at once), and
//                                   depends only on its inputs and (frame, x, y):
//                                   never on which rows were processed before.
//                                   That is what makes every strip height and
//                                   thread count give the same bytes.
#pragma once

#include <bit>
#include <cstdint>

#include "core/base/check.h"
#include "core/base/fixed.h"
#include "core/base/span.h"
#include "core/base/status.h"
#include "core/base/workspace.h"

namespace camsim {

inline constexpr int kMaxChannels = 3;

// What the samples of a line mean. All line samples are uint32_t.
enum class Domain : uint8_t {
  kRadiance,  // scene-linear radiance, Q16.16 (1.0 = 65536)
  kPhotons,   // photons per pixel during the exposure, Q24.8
  kDigital,   // raw sensor output, integer DN in [0, 2^adc_bits - 1]
  kLinear,    // black-level-corrected linear signal, Q0.16 of full scale (0..65535)
  kEncoded,   // gamma-encoded display signal, Q0.16 of full scale (0..65535)
};
const char* DomainName(Domain d);
// Fractional bits of a domain's samples (for converting to float in tools).
int DomainFracBits(Domain d);

// Colour filter arrays by their GenICam PixelFormat names. The name gives the
// colours of the top-left 2x2 cell in reading order: BayerRG = R G / G B.
enum class Cfa : uint8_t { kMono, kBayerRG, kBayerGR, kBayerGB, kBayerBG };
const char* CfaName(Cfa cfa);
enum Colour : uint8_t { kRed = 0, kGreen = 1, kBlue = 2 };
// The colour a site samples; for kMono always kGreen (a single "luma" colour).
constexpr Colour CfaColour(Cfa cfa, int x, int y) {
  // Index = (y & 1) * 2 + (x & 1).
  constexpr Colour kRG[4] = {kRed, kGreen, kGreen, kBlue};
  constexpr Colour kGR[4] = {kGreen, kRed, kBlue, kGreen};
  constexpr Colour kGB[4] = {kGreen, kBlue, kRed, kGreen};
  constexpr Colour kBG[4] = {kBlue, kGreen, kGreen, kRed};
  const int i = (y & 1) * 2 + (x & 1);
  switch (cfa) {
    case Cfa::kBayerRG: return kRG[i];
    case Cfa::kBayerGR: return kGR[i];
    case Cfa::kBayerGB: return kGB[i];
    case Cfa::kBayerBG: return kBG[i];
    case Cfa::kMono: break;
  }
  return kGreen;
}

struct LineFormat {
  Domain domain = Domain::kRadiance;
  uint8_t channels = 3;  // 1 or 3; channel c of a 3-channel line is colour c
  bool mosaic = false;   // 1 channel holding the CFA site colour at each pixel
};

// What every stage knows about the frame it works on.
struct SensorGeometry {
  int width = 0;
  int height = 0;
  Cfa cfa = Cfa::kBayerRG;
  int adc_bits = 12;  // 8..16
  bool operator==(const SensorGeometry&) const = default;
};

// Optional per-pixel inputs besides radiance, provided by the caller per frame.
struct FrameInput;

// One input row: a pointer per channel. Pointers may be read from -Margin() to
// width - 1 + Margin(): the driver fills margins by reflection (reflect-101,
// which keeps the CFA phase).
struct RowIn {
  const uint32_t* ch[kMaxChannels];  // no initialiser: the driver's row arrays are not zero-filled per row
};

// Sums gathered while rows are hot, for the run report. Per colour (R, G, B;
// mono counts as G). aux is stage-specific (the sensor puts electrons there).
struct StageStats {
  int64_t sum[3] = {};
  int64_t count[3] = {};
  int64_t aux_sum[3] = {};
  // Pixels of running rows where the scene did not need (part of) the
  // stage's work: copied through (e.g. no blur where the circle of
  // confusion is negligible), or for flare the pixels that source no glare
  // or ghosts: the planner's savings within a frame. Counted the same with
  // Stage::set_skip_idle off, when the work is done on them anyway.
  int64_t skipped_px = 0;
  uint64_t ticks = 0;  // time spent, in the caller's clock units
};

// The input rows [first, last] that one output row reads, in the previous
// stage's row numbers. Rows outside the frame are reflected (reflect-101).
struct RowWindow {
  int first = 0;
  int last = 0;
};
// The most input rows one output row may read (last - first + 1).
inline constexpr int kMaxWindowRows = 1024;

struct RowArgs {
  int y = 0;
  int width = 0;
  uint32_t frame = 0;
  // rows[k] is input row first_row + k (reflected), 0 <= k < row_count. For a
  // stage with the default InputRows, rows[RowsAbove()] is row y.
  const RowIn* rows = nullptr;
  int first_row = 0;
  int row_count = 0;
  const FrameInput* input = nullptr;
  uint32_t* out[kMaxChannels] = {};
  uint8_t* scratch = nullptr;   // ScratchBytes() of per-worker memory, shared by all stages
  uint8_t* state = nullptr;     // this stage's own StateBytes() of per-worker memory (null if 0)
  StageStats* stats = nullptr;  // non-null when the stage should add aux stats
};

class Stage {
 public:
  virtual const char* name() const = 0;
  // The output format for input format `in`, or an error naming why the stage
  // cannot take it (e.g. demosaic after a mono CFA).
  virtual Result<LineFormat> Plan(LineFormat in) const = 0;
  // Why this stage would leave its input unchanged with its current config, or
  // nullptr when it does real work. Stages that convert domains return nullptr.
  virtual const char* IdentityReason() const { return nullptr; }
  // A stage reading a fixed neighbourhood of row y states its size; one whose
  // window moves otherwise (a remap, a gather along motion) overrides
  // InputRows. Either way first and last must not decrease as y grows, and a
  // window holds at most kMaxWindowRows rows: the driver checks both at
  // Configure and sizes its line rings from the widest window.
  virtual int RowsAbove() const { return 0; }
  virtual int RowsBelow() const { return 0; }
  virtual RowWindow InputRows(int y, int /*height*/) const { return {y - RowsAbove(), y + RowsBelow()}; }
  virtual int Margin() const { return 0; }  // columns read beyond each edge
  virtual void CountTables(WorkspaceCounter& /*counter*/) const {}
  virtual size_t ScratchBytes(int /*width*/) const { return 0; }
  // Strip state: per-worker memory of this stage alone that keeps its bytes
  // from one ProcessRow to the next within a strip (a cache of work shared by
  // several output rows, e.g. dof_columns' solved block). The scratch above is
  // shared by all stages and holds nothing between calls. Rows of a strip
  // reach a stage in increasing y. The driver calls BeginStrip(state) for
  // every running stage with StateBytes() > 0 at the start of every strip,
  // before any ProcessRow of it: the stage must mark its cache empty there, so
  // nothing is ever reused across strips, frames, workers or configurations,
  // and each output row stays a function of its input rows alone.
  virtual size_t StateBytes(int /*width*/) const { return 0; }
  virtual void BeginStrip(uint8_t* /*state*/) const {}
  virtual Status Init(Arena& /*tables*/) { return Status::Ok(); }
  // Init after a reconfiguration: `previous` is this stage (the same class)
  // of another pipeline, initialised and unchanged until this returns (this
  // stage itself is no previous: its tables are rebuilt). A
  // table whose inputs equal previous's is copied from it instead of built:
  // the same bytes as Init, without the work (the emulated camera rebuilds
  // its pipeline on every ExposureTime write). *copied counts the tables
  // copied. Stages without costly tables keep this default: Init.
  virtual Status InitFrom(Arena& tables, const Stage& /*previous*/, int* copied) {
    *copied = 0;
    return Init(tables);
  }
  virtual void ProcessRow(const RowArgs& args) const = 0;

  // Whether the stage copies the pixels that need none of its work (those
  // StageStats::skipped_px counts; default on). Off, it does the work it
  // would skip (a copy becomes a sweep, a gather, a sample) and gives the
  // same bytes: the run that `camsim run --measure-savings` times the
  // skipping against. Stages that skip nothing, and flare (its skipped
  // pixels source nothing: there is no work to run on them), ignore it.
  void set_skip_idle(bool on) { skip_idle_ = on; }

 protected:
  ~Stage() = default;
  bool skip_idle_ = true;
};

// The equality InitFrom compares configuration values with: bit for bit, so
// that 0.0 and -0.0 differ and nothing could round differently.
inline bool SameBits(double a, double b) { return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b); }

// Reflect-101 of an index into [0, n): -1 -> 1, n -> n - 2; any distance.
constexpr int Reflect101(int i, int n) {
  if (n <= 1) return 0;
  const int period = 2 * (n - 1);
  int r = i % period;
  if (r < 0) r += period;
  return r < n ? r : period - r;
}

}  // namespace camsim
