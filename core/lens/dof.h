// Depth of field (paper eq. 11-13) and structural blur, on scene radiance.
//
// Circle of confusion (thin lens, model-notes): with focal length f, f-number
// N, focus distance z_f and depth z, the blur circle's diameter on the sensor
// is c = f^2 |z - z_f| / (N z (z_f - f)) = K |1/z - 1/z_f| with
// K = f^2 z_f / (N (z_f - f)), divided by the pixel pitch for pixels. It is
// linear in inverse depth, so the core takes depth as inverse depth
// (FrameInput::inverse_depth, 1/m in Q12.20) and computes per pixel
//   coc = min(max_coc, round(K' |iz - iz_f|)),  coc in Q.8 pixels (diameter),
// K' = K / pitch * 2^8 / 2^20 as a UScale; coc < min_coc becomes 0.
// Special depths (the host's conversion, host_tools/scene_input.cc, and the
// core agree on these; tests/unit/test_dof.cc checks each):
//   z = 1e10 (the bundled sky) or +inf: iz rounds to 0, the CoC of infinity,
//                     K / pitch / z_f-independent = f^2 / (N (z_f - f) pitch).
//   z = NaN:          the loader turns it into +inf (counted): as the sky.
//   z = 0:            iz saturates at kMaxInverseDepth: the largest blur, i.e.
//                     max_coc for any real lens.
//   z < 0 or -inf:    no valid depth: kInvalidInverseDepth, CoC 0 (left sharp).
//
// Diffusion DoF (eq. 12-13, Kass, Lefohn, Owens 2006): per line the system
//   -b_i y_{i-1} + (1 + b_i + b_{i+1}) y_i - b_{i+1} y_{i+1} = x_i,
//   b_i = min(s^2 coc_{i-1}^2, s^2 coc_i^2), b = 0 across the frame border,
// first along rows (DofRowStage, a whole-line solve; eight rows at a time in
// AVX-512 lanes), then along columns (DofColumnStage). s = diffusion_scale: one row + column step has per-axis
// variance 2 b, a uniform disc of diameter c has c^2 / 16, so the default
// s = 1/sqrt(32) makes both methods blur alike (the cross-check relies on it).
// Structural blur adds (s d(r))^2 to every pixel's s^2 coc^2, d(r) a blur
// diameter polynomial in the normalised radius r (0 centre, 1 corner): two
// diffusions in sequence are about one with the summed coefficient.
//
// The solver (Thomas' algorithm rewritten so every step is a convex
// combination; see dof.cc for the derivation):
//   forward:  D_i = 1 + b_i r_{i-1},  r_i = D_i / (D_i + b_i)      (r_0 = 1)
//             u_i = u_{i-1} + r_i (x_i - u_{i-1})                  (u_0 = x_0)
//   backward: y_i = y_{i+1} + e_i (u_i - y_{i+1}),  e_i = 1 / D_{i+1}
// r, e in (0, 1]: u and y never leave [min x, max x] (maximum principle) and
// a constant line stays exactly constant, whatever the rounding. The column
// pass groups output rows in blocks of B = DofColumnStage::kBlock and solves
// block b = rows [bB, bB + B) once, over the window [bB - W, bB + B - 1 + W]
// (insulated at the window ends; W = column_window, the precision knob), by a
// twisted factorisation at the block's last row e = bB + B - 1: the forward
// sweep from the window's top down to e (keeping u and e_i of the block's
// rows), the same sweep from the window's bottom up to e + 1,
//   y_e = u_e + w (v_{e+1} - u_e),  w = b_{e+1} r_e / (D'_e + b_{e+1} r_e),
//   D'_e = 1 + b_{e+1} r'_{e+1}  (r' the upward sweep's r),
// then the backward substitution above from e up to bB. Every row keeps at
// least W window rows on each side, so the truncation error is at most that of
// a per-row window of W. Rows of the window outside the frame do not exist
// (insulated border), so the result depends only on the block, never on the
// strip or the thread count; the solved block lives in the stage's strip
// state (Stage::StateBytes), reset by BeginStrip at every strip, next to a
// ring of the window's links b (each row's CoC computed once per strip; a
// link depends on its two rows only, so caching it changes no bit).
//
// Formats: x, out: radiance Q16.16 (uint32), 3 channels.
//          u, v, y: int64 Q16.32 (16 guard bits below the input's LSB);
//                   products with weights are exact 64-bit splits (MulQ30).
//          b: uint32 Q20.12, 0 .. 2^20 - 2^-12 (so b r fits 62 bits), from
//             squared diffusion CoCs in Q.32 (s coc in Q10.16, squared).
//          r, e, w: uint32 Q2.30 in [0, 1]; D: uint64 Q.30 in [1, 2^20 + 1].
//          Divisions: round to nearest (ties up) of a normalised 64-bit
//          quotient (numerator and denominator shifted to < 2^34: relative
//          error < 2^-33). coc: Q.8 pixels, at most 1024 - 2^-8.
//          Output: RoundShift(y, 16), within [min, max] of the input line.
// Skipping: b = 0 decouples neighbours exactly (r = e = 1), so pixels whose
// both links are 0 (CoC below min_coc on either side) need no solving;
// StageStats::skipped_px counts them. Their weights cost no division; the
// row pass copies a block of kBlock rows without a link and otherwise sweeps
// every pixel of the block (one segment at a time without AVX-512). The
// column pass copies a whole tile (kTile columns x one block) whose window
// has no link, and otherwise sweeps every column of the tile; it still reads
// the window's depth rows to find the links. Measured savings: `camsim run
// --measure-savings` (docs/performance.md).
//
// Gather DoF (eq. 11, reverse-mapped z-buffer, DofGatherStage): each source
// pixel q spreads its radiance uniformly over a disc of radius
// R_q = min(coc_q / 2, max_radius) in quarter pixels (the "scatter as
// gather" of the z-buffer method):
//   out_p = sum_q [|p - q| <= R_q] x_q / A(R_q) / sum_q [|p - q| <= R_q] / A(R_q),
// A(R) the pixel count of the disc (a table); integer offsets, a binary disc,
// so CoCs below 1.75 px (radius below 1 px after rounding) do not blur. Weights round(2^26 / A); sums in 64 bits;
// one rounded division per channel (details in dof_gather.cc). Reads rows
// y - max_radius .. y + max_radius, clipped to the frame (discs are clipped
// at the borders and renormalised, so no margin columns). A row whose window
// holds no CoC >= 1.75 px is copied (StageStats::skipped_px).
#pragma once

#include "core/pipeline/inverse_depth.h"
#include "core/pipeline/stage.h"

namespace camsim {

enum class DofMethod : uint8_t { kOff, kDiffusion, kGather };

// The column pass solves kBlock (32) output rows with column_window rows on
// each side in one window of at most kMaxWindowRows: W <= (1024 - 32) / 2.
inline constexpr int kMaxColumnWindow = (kMaxWindowRows - 32) / 2;

struct DofConfig {
  DofMethod method = DofMethod::kOff;
  double focal_length_mm = 28.0;   // lens focal length (the host copies lens.focal_length_mm)
  double pixel_pitch_um = 0.0;     // the host fills it in from the sensor; must be > 0
  double focus_distance_m = 3.0;   // z_f, must exceed the focal length
  double max_coc_px = 64.0;        // CoC diameter cap, pixels (0.25 .. 1023)
  double min_coc_px = 0.5;         // smaller CoCs are 0: those pixels are not blurred
  double diffusion_scale = 0.17677669529663687;  // s = 1/sqrt(32), see above
  int column_window = 32;          // diffusion: rows each side solved per column (1 .. kMaxColumnWindow)
  int max_radius_px = 16;          // gather: disc radius cap (1 .. 255); also its row window
  // Structural blur: blur diameter in pixels = sum_k poly[k] r^k, r the
  // normalised radius (0 at the centre, 1 at the corners). All 0: off.
  static constexpr int kPolyTerms = 5;
  double structural_poly[kPolyTerms] = {};
  int structural_poly_count = 0;   // coefficients given (the rest are 0)
  bool structural_only = false;    // diffusion without depth: structural blur alone
};


// The configured thin-lens CoC model, shared by the three stages.
class CocModel {
 public:
  static constexpr int kCocFracBits = 8;  // Q.8 pixels
  static constexpr uint32_t kMaxCocRaw = (1024u << kCocFracBits) - 1;
  static constexpr int kDiffusionCocFracBits = 16;  // Q10.16
  Status Configure(const DofConfig& config, double f_number);
  // CoC diameter, Q.8 pixels, of an inverse-depth sample (0 below min_coc).
  uint32_t Coc(uint32_t inverse_depth) const {
    if (inverse_depth == kInvalidInverseDepth) return 0;
    const uint32_t d = inverse_depth > focus_ ? inverse_depth - focus_ : focus_ - inverse_depth;
    if (d < min_diff_) return 0;
    const uint32_t c = scale_.Apply(d);
    return c < cap_ ? c : cap_;
  }
  // The diffusion's s * coc from the same sample, Q.16 (0 where Coc is 0):
  // 16 fractional bits because s * coc is small (s = 0.18) and b = (s coc)^2
  // would otherwise carry a 1e-3 relative rounding error.
  uint32_t DiffusionCoc(uint32_t inverse_depth) const {
    if (inverse_depth == kInvalidInverseDepth) return 0;
    const uint32_t d = inverse_depth > focus_ ? inverse_depth - focus_ : focus_ - inverse_depth;
    if (d < min_diff_) return 0;
    const uint32_t c = diffusion_scale_.Apply(d);
    return c < diffusion_cap_ ? c : diffusion_cap_;
  }
  // cc2[x] = DiffusionCoc(inverse_depth[x])^2 for x < n (Q.32): the same
  // integers in 64-bit lanes where the CPU has them (dof.cc: four with
  // AVX2, eight with AVX-512).
  void DiffusionCc2Row(const uint32_t* inverse_depth, int n, uint64_t* cc2) const;
  // The same in double pixels (reference; invalid depth -> 0).
  double CocPixels(double z_metres) const;
  uint32_t focus() const { return focus_; }
  uint32_t min_diff() const { return min_diff_; }

 private:
  DofConfig config_;
  double f_number_ = 1.0;
  double k_px_m_ = 0.0;          // K / pitch: CoC in pixels per 1/m of inverse-depth difference
  uint32_t focus_ = 0;           // iz_f, Q12.20
  UScale scale_;                 // |iz - iz_f| Q12.20 -> coc Q.8
  UScale diffusion_scale_;       // |iz - iz_f| -> s coc Q.16
  uint32_t cap_ = 0, diffusion_cap_ = 0;
  uint32_t min_diff_ = 0;        // smallest |iz - iz_f| whose CoC reaches min_coc
};

// The fixed-point line solver, exposed for tests and the bench.
namespace dof {
inline constexpr int kBetaFracBits = 12;             // b: Q20.12
inline constexpr uint32_t kMaxBeta = 0xFFFFFFFFu;    // 2^20 - 2^-12
inline constexpr int kGuardBits = 16;                // u, v, y: Q16.32 in int64
inline constexpr int kWeightFracBits = 30;           // r, e, w: Q2.30
// b from two neighbours' squared diffusion CoCs (Q.32, depth part + structural
// part, each < 2^52): min, to
// Q.12 (rounded, ties up), capped.
constexpr uint32_t BetaOf(uint64_t cc2_a, uint64_t cc2_b) {
  const uint64_t m = cc2_a < cc2_b ? cc2_a : cc2_b;
  const uint64_t b = (m + (1u << 19)) >> 20;  // Q.32 -> Q.12
  return b > kMaxBeta ? kMaxBeta : static_cast<uint32_t>(b);
}
// beta[x] = BetaOf(cc2_a[x], cc2_b[x]) for x < n (a row's links: cc2_b = cc2_a + 1).
void BetaRow(const uint64_t* cc2_a, const uint64_t* cc2_b, int n, uint32_t* beta);
// round(d * w / 2^30) (ties up) for |d| < 2^49, 0 <= w <= 2^30, exact. The
// portable form splits d into a high part (d >> 24, |.| < 2^25) and 24 low
// bits so both 64-bit products stay below 2^55, and rounds the sum once;
// where the compiler has a 128-bit integer (x86-64, aarch64) one wide
// product gives the same exact value faster. armhf uses the split.
constexpr int64_t MulQ30Split(int64_t d, uint32_t w) {
  const int64_t qh = (d >> 24) * static_cast<int64_t>(w);
  const int64_t ql = (d & 0xFFFFFF) * static_cast<int64_t>(w);
  return (qh >> 6) + ((((qh & 63) << 24) + ql + (int64_t{1} << 29)) >> 30);
}
inline int64_t MulQ30(int64_t d, uint32_t w) {
#if defined(__SIZEOF_INT128__)
  __extension__ typedef __int128 Wide;
  return static_cast<int64_t>((static_cast<Wide>(d) * w + (Wide{1} << 29)) >> 30);
#else
  return MulQ30Split(d, w);
#endif
}
// The column pass's per-channel row updates over n columns, in eight
// (AVX-512) or four (AVX2) 64-bit lanes where the CPU has them (dof.cc), one
// by one elsewhere; the same
// integers either way (MulQ30 and OutOf, |u - in 2^16|, |us - y| < 2^49):
//   PullRow: u[x] += MulQ30((in[x] << kGuardBits) - u[x], w[x])  (a sweep step)
//   BackRow: y[x] += MulQ30(us[x] - y[x], e[x]), then
//            out[x] = SatU32(RoundShift(y[x], kGuardBits))     (e == nullptr: no step)
void PullRow(int64_t* u, const uint32_t* in, const uint32_t* w, int n);
void BackRow(int64_t* y, const int64_t* us, const uint32_t* e, uint32_t* out, int n);

// Solves one line of n samples for `channels` (1 .. 3) channels in place: beta[i]
// (i = 1 .. n - 1) couples samples i - 1 and i; beta[0] and beta[n] are
// ignored (insulated ends). work: 2 n uint32 + 3 n int64 (LineWorkBytes).
// Returns the number of samples with a non-zero link: those solved. skip
// false solves the whole line as one segment (the same bytes).
size_t LineWorkBytes(int n);
int SolveLine(uint32_t* const* line, int channels, const uint32_t* beta, int n, uint8_t* work, bool skip = true);

// Up to kLaneLines lines of 3 channels solved together: line j reads
// lines[j].in, writes lines[j].out (SolveLine's result for a copy of in) and
// solved[j] (SolveLine's return), with links lines[j].beta as SolveLine's.
// With AVX-512, line j is lane j of one sweep in 64-bit lanes (dof.cc: the
// same integers); elsewhere SolveLine solves them one by one.
// work: LinesWorkBytes(n), 64-byte aligned.
inline constexpr int kLaneLines = 8;
struct LineIo {
  const uint32_t* in[3];
  uint32_t* out[3];
  const uint32_t* beta;  // n + 1 links
};
size_t LinesWorkBytes(int n);
// skip: a sample without links is its own solution and is not swept (the
// lanes sweep it with weights 1 taken without a step); false steps and
// sweeps it as any other, for the same bytes. solved[j]: line j's samples
// with a non-zero link.
void SolveLines(const LineIo* lines, int count, int n, uint8_t* work, int32_t* solved, bool skip = true);
}  // namespace dof

// Row pass of the diffusion DoF (and structural blur). Rows are solved in
// blocks of kBlock (dof::SolveLines: one lane per row), cached in the strip
// state; each row's solve depends on that row alone, so the block changes
// no bit, only how many rows one sweep carries. Memory per worker: the
// solved block (12 kBlock w bytes: 180 KiB at w = 1920) and, with AVX-512,
// the sweep's weights and state in the scratch (32 kBlock w bytes: 480 KiB).
class DofRowStage final : public Stage {
 public:
  static constexpr int kBlock = dof::kLaneLines;
  Status Configure(const DofConfig& config, const SensorGeometry& geometry, double f_number);
  const char* name() const override { return "dof_rows"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override;
  // Every row of a block reads the block's rows (clipped at the frame's end).
  RowWindow InputRows(int y, int height) const override;
  void CountTables(WorkspaceCounter& counter) const override;
  Status Init(Arena& tables) override;
  size_t ScratchBytes(int width) const override;
  size_t StateBytes(int width) const override;
  void BeginStrip(uint8_t* state) const override;
  void ProcessRow(const RowArgs& args) const override;

  const CocModel& coc() const { return coc_; }
  // Squared diffusion CoC per pixel of row y, Q.32 (depth + structural), after
  // Init. Columns [x0, x1) of row y into cc2[0 .. x1 - x0). Public for tests.
  void RowCc2(const FrameInput& input, int y, int x0, int x1, uint64_t* cc2) const;

 protected:
  friend class DofColumnStage;

  DofConfig config_;
  SensorGeometry geometry_;
  CocModel coc_;
  bool structural_ = false;
  UScale rho_to_index_;          // as vignetting: (dx2 + dy2) -> curve position Q.16
  uint64_t* struct_cc2_ = nullptr;  // kCurvePoints + 1 squared diffusion diameters, Q.16 (< 2^37; added << 16)
  uint32_t* dx2_ = nullptr;
};

// Column pass: windowed solve per block of kBlock output rows.
class DofColumnStage final : public Stage {
 public:
  Status Configure(const DofConfig& config, const SensorGeometry& geometry, const DofRowStage* rows);
  const char* name() const override { return "dof_columns"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override { return rows_->IdentityReason(); }
  RowWindow InputRows(int y, int height) const override;
  size_t ScratchBytes(int width) const override;
  size_t StateBytes(int width) const override;
  void BeginStrip(uint8_t* state) const override;
  void ProcessRow(const RowArgs& args) const override;

  // Output rows solved together: block b = rows [bB, bB + B) is solved once
  // over its window [bB - W, bB + B - 1 + W] and cached in the stage's strip
  // state; every row of the block is read from that solution. Each row keeps
  // at least W rows of window on each side, so the error bound of window W
  // holds; per output row the sweeps cost (B + 3W) / B + 1 steps instead of 2W + 1.
  // B = 32 rather than 16, measured with whole-frame strips
  // (BM_PipelineDof/1920/1080/1/0): 307 -> 266 ms, and a lower error (most
  // rows see more than W rows each side: rms 3.9e-3 -> 1.0e-3 at W = 32,
  // BM_DofDiffusion/32); 0.8 MB more strip state per worker at 1080p.
  static constexpr int kBlock = 32;
  static_assert(kMaxColumnWindow == (kMaxWindowRows - kBlock) / 2, "kMaxColumnWindow follows kBlock");
  static constexpr int kTile = 64;  // columns solved together

 private:
  void FillLinks(const RowArgs& args, uint8_t* state, int lo, int hi) const;
  void SolveTile(const RowArgs& args, int yb, int ye, int x0, int x1, uint32_t* cache, int32_t* solved_rows,
                 const uint32_t* ring, int ring_rows) const;

  DofConfig config_;
  SensorGeometry geometry_;
  const DofRowStage* rows_ = nullptr;
};

// Reverse-mapped z-buffer DoF: disc gather with per-source radius.
class DofGatherStage final : public Stage {
 public:
  static constexpr int kMaxRadius = 255;
  Status Configure(const DofConfig& config, const SensorGeometry& geometry, double f_number);
  const char* name() const override { return "dof_gather"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override;
  RowWindow InputRows(int y, int height) const override;
  void CountTables(WorkspaceCounter& counter) const override;
  Status Init(Arena& tables) override;
  size_t ScratchBytes(int width) const override;
  // Strip state: a byte per frame row, whether the row holds a disc wider
  // than a pixel (kRowUnknown until a window first reads it), so that each
  // row is scanned once per strip for the skip, not once per output row.
  size_t StateBytes(int width) const override;
  void BeginStrip(uint8_t* state) const override;
  void ProcessRow(const RowArgs& args) const override;

 private:
  static constexpr uint8_t kRowUnknown = 2;
  DofConfig config_;
  SensorGeometry geometry_;
  CocModel coc_;
  uint32_t* weight_ = nullptr;     // [R] = round(2^26 / A(R)), R = 0 .. max_radius
  int16_t* half_width_ = nullptr;  // [q * (R_max + 1) + |dy|] = floor(sqrt((q/4)^2 - dy^2)), -1 outside; q = radius in quarter pixels
};

}  // namespace camsim
