// Motion blur (paper eq. 14-16, corrected) and rolling shutter: one gather
// along each pixel's motion path during its row's exposure.
//
// Model. D(p) is the image displacement of pixel p over the exposure time T
// (pixels), from either source:
//  - camera: the camera's angular velocity w (rad/s) and linear velocity v
//    (m/s), both in the camera frame (x right, y down, z forward: OpenCV),
//    with intrinsics fx, fy, cx, cy (pixels) and inverse depth iz (1/m). For
//    a static scene point at normalised position (x, y) = ((u-cx)/fx, (v-cy)/fy)
//    the image velocity is (the motion field of a rigid camera motion):
//      du/dt = fx [ (-vx + x vz) iz + x y wx - (1 + x^2) wy + y wz ]
//      dv/dt = fy [ (-vy + y vz) iz + (1 + y^2) wx - x y wy - x wz ]
//    and D = T * (du/dt, dv/dt). Translation needs depth; iz = 0 (sky, no
//    depth) gives no translational motion.
//  - vectors: renderer motion vectors M (pixels per frame interval Tf =
//    1 / vector_fps, from the previous frame to this one, image rows
//    downwards): D = M * T / Tf.
// The rendered image is the scene at the middle of the frame's readout: row y
// is exposed over [t_y - T/2, t_y + T/2] with t_y = (y - (H-1)/2) * line_time
// (line_time = 0: global shutter). A point at p at the rendered instant is at
// p + D t / T at time t, so, by gathering at the output pixel (D taken at the
// output pixel, the usual gather approximation):
//   out(p) = 1/n sum_{i<n} S(p - D * (rho_y - 1/2 + (i + 1/2) / n)),  rho_y = t_y / T
// Midpoint samples in time replace eq. 14's i/(n-1), which fails for n = 1.
// n = min(max_samples, 1 + ceil(samples_per_px * max(|Dx|, |Dy|))): with the
// default 1 sample per pixel of motion the spacing is below one pixel;
// samples_per_px is the precision knob (the midpoint rule's error against the
// continuous time integral falls as it grows; camsim tradeoff measures it).
// S is sampled bilinearly. Rolling shutter alone (tiny T) is a pure per-row
// shift; motion blur alone (line_time 0) is centred on p.
//
// Bounds. Every sample's offset from p is clamped per component to
// +-max_displacement_px (a knob, up to 511: it bounds the rows of context,
// 2 * max + 2 <= kMaxWindowRows); motion beyond the bound is cut off there (a
// longer smear piles up at the bound). Sample positions are then clamped into
// the frame (edge pixels repeat), so no margin columns are read and the row
// window is clamped into the frame too. For camera rotation without
// translation the vertical reach is known at configure time (the rotational
// field is linear in x along a row): the vertical bound, and so the window and
// the line rings, shrink to that reach + 1 row (a 10 px pan at 640x480:
// 8 rows instead of 66).
//
// Formats: in/out kRadiance Q16.16 or kPhotons Q24.8, 3 channels (not mosaic);
//   the stage is linear in the samples, so units pass through.
//   D: int32 Q15.16 pixels, clamped to +-2^30 (16384 px) when formed.
//   Camera tables (configure-time doubles, rounded once): per column and per
//   row int64 Q.16 pixels; normalised y per row Q.24 (|y| <= 16, validated);
//   products with FrameInput.inverse_depth (Q12.20 1/m, core/pipeline/inverse_depth.h;
//   an invalid depth counts as infinitely far) rounded (ties up) by >> 20.
//   Vectors: int32 Q16.16, clamped to +-2^26, times T/Tf as Q.32 (<= 2^36).
//   rho_y: int64 Q.16 (|rho| <= 2^15, validated).
//   Sample offsets: D (1/2 - rho) and D (2i+1) / (2n) with 1/(2n) as Q.32;
//   positions Q.16; bilinear weights Q0.10 per axis (rounded from Q.16, ties
//   up), products summing to 2^20; sum over samples in uint64 (< 2^32 2^20 256);
//   out = round(sum / (n 2^20)), ties up, exact integer division; a mean of
//   32-bit samples, so it cannot exceed 2^32 - 1 (no saturation needed).
//   samples_per_px: Q.4 (rounded to 1/16); n from L (Q.16) * spp (Q.4), ceil.
#pragma once

#include "core/pipeline/inverse_depth.h"
#include "core/pipeline/stage.h"

namespace camsim {

enum class MotionSource : uint8_t { kOff, kCamera, kVectors };

struct MotionBlurConfig {
  MotionSource source = MotionSource::kOff;
  double angular_velocity_rad_s[3] = {};  // camera: wx, wy, wz (camera frame)
  double linear_velocity_m_s[3] = {};     // camera: vx, vy, vz (camera frame)
  double fx_px = 0.0, fy_px = 0.0;        // camera: focal lengths, pixels (> 0)
  double cx_px = -1.0, cy_px = -1.0;      // camera: principal point, pixels; < 0 = centre, (W-1)/2, (H-1)/2
  double vector_fps = 24.0;               // vectors: render frame rate; the vectors span 1 / fps (Blender's default 24)
  double line_time_us = 0.0;              // rolling shutter: row-to-row delay; 0 = global shutter
  int max_displacement_px = 32;           // bound on each sample's offset, 1 .. 511 pixels
  int max_samples = 64;                   // bound on n, 1 .. 256
  double samples_per_px = 1.0;            // samples per pixel of motion length, 1/16 .. 16 (1/16 steps)
};

class MotionBlurStage final : public Stage {
 public:
  static constexpr int kMaxDisplacementPx = 511;  // window 2 * max + 2 <= kMaxWindowRows (1024)
  static constexpr int kMaxSamples = 256;        // keeps the uint64 sum below 2^56
  static constexpr int kVectorFracBits = 16;        // FrameInput.motion_vectors, Q16.16 px

  Status Configure(const MotionBlurConfig& config, const SensorGeometry& geometry, double exposure_time_us);
  const char* name() const override { return "motion_blur"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  const char* IdentityReason() const override;
  RowWindow InputRows(int y, int height) const override;
  // Rows above and below its own that a sample may reach (<= max_displacement_px).
  int VerticalReach() const { return vreach_; }
  void CountTables(WorkspaceCounter& counter) const override;
  size_t ScratchBytes(int width) const override;
  Status Init(Arena& tables) override;
  void ProcessRow(const RowArgs& args) const override;

  // True when the stage reads FrameInput.inverse_depth / motion_vectors.
  bool NeedsInverseDepth() const;
  bool NeedsVectors() const { return config_.source == MotionSource::kVectors; }
  const MotionBlurConfig& config() const { return config_; }

 private:
  // Displacements over the exposure of row y, Q.16 pixels, into du/dv.
  void RowDisplacements(const RowArgs& a, int32_t* du, int32_t* dv) const;

  MotionBlurConfig config_;
  SensorGeometry geometry_;
  double exposure_us_ = 0.0;
  bool translating_ = false;
  int vreach_ = 0;                // vertical bound on sample offsets, pixels
  int64_t vector_scale_q32_ = 0;  // T / Tf, Q.32
  int64_t spp_q4_ = 16;           // samples_per_px, Q.4
  int64_t ku_ = 0;                // T fx wz, Q.16 px (times y)
  // Tables (Init): per column
  int64_t* cu_a_ = nullptr;  // T fx wx x, Q.16 (times y)
  int64_t* cu_b_ = nullptr;  // -T fx wy (1 + x^2)
  int64_t* cu_c_ = nullptr;  // T fx (-vx + x vz) (times iz)
  int64_t* cv_a_ = nullptr;  // -T fy wy x (times y)
  int64_t* cv_b_ = nullptr;  // -T fy wz x
  // per row
  int64_t* ry_ = nullptr;    // y, Q.24
  int64_t* rv_b_ = nullptr;  // T fy wx (1 + y^2)
  int64_t* rv_c_ = nullptr;  // T fy (-vy + y vz) (times iz)
  int64_t* rho_ = nullptr;   // t_y / T, Q.16
  uint32_t* inv2n_ = nullptr;  // round(2^32 / (2n)) for n = 1 .. max_samples ([0] unused)
};

}  // namespace camsim
