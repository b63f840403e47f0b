// Lens distortion and lateral chromatic aberration (paper eq. 1-2) as a remap:
// each output (distorted) pixel samples the ideal pinhole image (the renderer's
// input, same camera matrix) at the undistorted source position given by the
// inverse of the calibration model (core/lens/lens_model.h, OpenCV and ROS
// conventions). A user's own cv::undistort with the same calibration gives
// back the straight input.
//
// Remap table: the source position is solved in double at the nodes of a
// coarse grid (every grid_step output pixels, the precision knob) and stored
// as the displacement source - node, Q15.16 signed (int32). Per pixel it is
// interpolated bilinearly in fixed point: first between two node rows into
// scratch (rounded to Q.16), then along the row (rounded to Q.16).
//
// Chromatic aberration: channel c samples at centre + s_c (source - centre),
// centre = (cx, cy), s_c = chromatic_scale[c] as Q8.24; one table serves all
// three channels. A scale above 1 magnifies that colour's image.
//
// Resampling: the source position is rounded to 1/phases of a pixel; a
// separable filter of N taps (bilinear 2, bicubic 4 = Keys a = -0.5,
// Lanczos-3 6, Lanczos-4 8 as OpenCV's INTER_LANCZOS4) with weights per phase in Q1.14 (int16), each phase's weights
// summing to exactly 2^14 (rounding remainder on the largest tap), so a flat
// field stays exactly flat. Horizontal sums of 64-bit products rounded to
// integers (ties up), then the vertical sum rounded again; bicubic and
// Lanczos results are clamped to the range of the 2x2 samples around the
// source (ringing clamp: no halo at a hard edge, but a peak between samples
// is cut; ringing_clamp = false leaves the filter as it is), and every result
// to [0, 2^32 - 1].
// Taps beyond the frame are reflected (reflect-101, as the driver does rows).
//
// Fill: a source outside [-0.5, W - 0.5] x [-0.5, H - 0.5] (off the rendered
// image), or with no solution (beyond the fisheye's half-sphere, or in a grid
// cell touching such a node), gives 0: black, as cv::remap with
// BORDER_CONSTANT. A radial model that folds over (stops increasing) inside
// the frame is refused at Configure, naming the coefficients.
//
// Streaming: the input rows an output row reads are known per grid band
// (grid_step rows) from the nodes' source rows, widened monotonically
// (InputRows); the driver keeps that many rows in its ring.
//
// CFA site only: when a Bayer CFA is the next running stage, the planner
// calls SetSiteOnly (before Plan) and leaves the CFA out: each pixel then
// computes only the colour its CFA site keeps, and the stage writes the
// mosaic itself (1 channel; a third of the work and of the line memory).
//
// Speed: when Init proves the table's ranges fit 32 bits (no chromatic
// scaling, |displacement| <= 8192 px, neighbouring nodes closer than 256
// px), ProcessRow takes 32-bit fast paths (bilinear in lanes, see the
// .cc) that give exactly the general path's bits; tests compare the two.
// On x86-64 with AVX2 they take eight pixels at a time in lanes (sixteen
// with AVX-512), picking samples from contiguous loads with vpermd
// (vpermt2d), the N-tap row sums two taps at a time by vpmaddwd; elsewhere,
// and in the debug preset, the bilinear one stages them and the others go
// pixel by pixel.
//
// Formats: in/out 3 channels, Radiance Q16.16 or Photons Q24.8 (unchanged).
#pragma once

#include "core/lens/lens_model.h"
#include "core/pipeline/stage.h"

namespace camsim {

enum class ResampleFilter : uint8_t { kBilinear, kBicubic, kLanczos3, kLanczos4 };

// An arbitrary displacement mesh (paper section 4.1: asymmetric distortion,
// e.g. measured): node (i, j) sits at output pixel (i * step, j * step) and
// moves that pixel's source by (dx, dy) pixels, added to the lens model's
// source (alone when the model is off). Between nodes: bilinear; beyond the
// last node: the edge node's value. Caller-owned; read at Configure and Init
// only (a reconfiguration compares a digest of the values Configure read).
struct DisplacementMesh {
  const float* dxdy = nullptr;  // cols * rows pairs (dx, dy), row-major
  int cols = 0, rows = 0;
  double step = 0.0;  // pixels between nodes
};

// The focal lengths (pixels) the stage takes: below 1 pixel a pixel spans
// more than 45 degrees. The calibration reader checks a file against them.
inline constexpr double kMinFocalPx = 1.0, kMaxFocalPx = 1e6;

struct DistortionConfig {
  LensModel lens;
  DisplacementMesh mesh;
  double chromatic_scale[3] = {1.0, 1.0, 1.0};  // R, G, B radial scale of the source
  ResampleFilter filter = ResampleFilter::kLanczos3;
  int phases = 64;     // sub-pixel phases: 16, 32, 64, 128 or 256
  int grid_step = 8;   // remap grid spacing in pixels: 4, 8, 16, 32 or 64 (precision knob)
  bool ringing_clamp = true;  // bicubic, Lanczos: clamp to the 2x2 samples around the source
};

class DistortionStage final : public Stage {
 public:
  static constexpr int kWeightFracBits = 14;
  static constexpr int kScaleFracBits = 24;
  static constexpr int kMaxBands = 16384 / 4 + 2;
  static constexpr int kLaneTaps = 8;  // int32 weights per phase in wt_, the AVX2 lanes' table (>= taps)

  // previous (optional): this stage of a configured pipeline, initialised or
  // not. With the same configuration and geometry its band ranges are taken
  // instead of solving the grid's nodes again.
  Status Configure(const DistortionConfig& config, const SensorGeometry& geometry,
                   const DistortionStage* previous = nullptr);
  void SetSiteOnly(bool site_only) { site_only_ = site_only; }
  bool site_only() const { return site_only_; }

  const char* name() const override { return "distortion"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override;
  RowWindow InputRows(int y, int height) const override;
  void CountTables(WorkspaceCounter& counter) const override;
  size_t ScratchBytes(int width) const override;
  Status Init(Arena& tables) override;
  Status InitFrom(Arena& tables, const Stage& previous, int* copied) override;  // all tables, or none
  void ProcessRow(const RowArgs& args) const override;

  // Table size in bytes and the widest window of input rows (for reports).
  size_t TableBytes() const;
  int MaxWindowRows() const;
  // The fixed-point source position of output pixel (x, y), channel c, in
  // Q.16 pixels (after Init; for tests). False when the pixel gets the fill.
  bool SourcePosition(int x, int y, int c, int64_t* sx, int64_t* sy) const;
  int taps() const { return taps_; }
  // Whether ProcessRow takes the 32-bit fast path (see "Fast path" in the
  // .cc); tests can force the general path to compare the two.
  bool fast_path() const { return fast_path_ && !force_general_; }
  // Whether the last Configure took its band ranges from `previous`.
  bool bands_borrowed() const { return bands_borrowed_; }
  void ForceGeneralPathForTest(bool force) { force_general_ = force; }

 private:
  // Whether `other` was configured from the same configuration and geometry
  // (then its band ranges are this stage's), and SameTables: initialised
  // too (then its tables are).
  bool SameGrid(const DistortionStage& other) const;
  bool SameTables(const DistortionStage& other) const { return SameGrid(other) && other.table_ != nullptr; }
  static uint64_t MeshDigest(const DisplacementMesh& mesh);
  // Init; copies every table from `same` when it is not null (SameTables).
  Status Build(Arena& tables, const DistortionStage* same);
  // The mesh's displacement at output position (u, v) (pixels).
  void MeshDisplacement(double u, double v, double* dx, double* dy) const;
  // The source position (pixels) of grid node (i, j); false if none.
  bool NodeSource(int i, int j, double* sx, double* sy) const;
  void InterpolateRow(int y, int32_t* dx, int32_t* dy) const;
  struct RowView;  // what every ProcessRow variant starts from (the .cc)
  RowView StartRow(const RowArgs& args) const;
  template <int N>
  void ProcessRowN(const RowArgs& args) const;
  template <int N, bool kSiteOnly>
  void ProcessRowFast(const RowArgs& args) const;
  template <bool kSiteOnly>
  void ProcessRowBilinear(const RowArgs& args) const;
  template <int N, bool kSiteOnly>
  void ProcessRowLanes(const RowArgs& args) const;  // AVX2 only (the .cc)

  DistortionConfig config_;
  SensorGeometry geometry_;
  LensBranch branch_;
  bool site_only_ = false;
  bool fast_path_ = false;      // set by Init when the table's ranges fit 32 bits
  bool force_general_ = false;  // tests only
  bool avx2_ = false;           // bilinear fast path: the AVX2 kernel (set by Init)
  bool avx512_ = false;         // N-tap fast path: sets of sixteen lanes (AVX-512) first (set by Init)
  int taps_ = 6;
  int phase_bits_ = 6;
  int step_bits_ = 4;
  int grid_w_ = 0, grid_h_ = 0;
  bool scaled_[3] = {};
  int64_t scale_[3] = {};            // Q8.24
  int64_t centre_x_ = 0, centre_y_ = 0;  // Q.16
  // Window of input rows per band of grid_step output rows.
  int16_t band_first_[kMaxBands] = {};
  int16_t band_last_[kMaxBands] = {};
  int max_window_ = 1;
  uint64_t mesh_digest_ = 0;   // MeshDigest of the configured mesh
  bool bands_borrowed_ = false;
  bool configured_ = false;  // the last Configure succeeded (SameGrid lends only then)
  int32_t* table_ = nullptr;   // grid_h_ x grid_w_ x (dx, dy), Q15.16
  int16_t* weights_ = nullptr; // phases x taps, Q1.14
  int32_t* wt_ = nullptr;      // the same as int32, phases x kLaneTaps (AVX2 lanes)
  int32_t* wtap_ = nullptr;    // the same tap-major, taps x TapStride() (AVX-512 lanes)
  int TapStride() const { return phase_bits_ < 5 ? 32 : 1 << phase_bits_; }  // whole vpermt2d tables
};

// Filter kernel value at offset t (pixels) from the source position (double).
double ResampleKernel(ResampleFilter filter, double t);
int ResampleTaps(ResampleFilter filter);

}  // namespace camsim
