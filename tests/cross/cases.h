// Pipeline configurations shared by the cross-architecture golden test
// (core_golden.cc) and the bare-metal build (baremetal_main.cc). Core headers
// only: no host library, no allocation.
#pragma once

#include "core/pipeline/pipeline.h"
#include "tests/support/fixtures.h"

namespace camsim::cross {

// configs/camera.toml (the demo camera) written out in code, because the TOML
// reader is a host tool: BayerRG 12 bit, exposure 10 ms at f/2.8, cos4
// vignetting of a 28 mm lens on a 36 mm wide sensor, the default EMVA 1288
// sensor, white balance (1.3, 1, 1.1818), Malvar demosaic, sRGB gamma. The
// colour matrix is the identity, so the planner leaves it out.
inline PipelineConfig DemoConfig(int width, int height) {
  PipelineConfig c;
  c.geometry.width = width;
  c.geometry.height = height;
  c.geometry.cfa = Cfa::kBayerRG;
  c.geometry.adc_bits = 12;
  c.seed = 1;
  c.exposure.exposure_time_us = 10000.0;
  c.exposure.f_number = 2.8;
  c.vignetting.mode = VignettingMode::kCos4;
  // host_tools/config.cc: focal_length_px = focal_length_mm / (36 mm / width).
  c.vignetting.focal_length_px = 28.0 / (36.0 / width);
  c.white_balance.gain[0] = 1.3;
  c.white_balance.gain[1] = 1.0;
  c.white_balance.gain[2] = 1.1818;
  c.demosaic.method = DemosaicMethod::kMalvar;
  c.gamma.curve = GammaCurve::kSrgb;
  return c;
}

// A mono sensor: 10-bit, 6 dB analog gain, a vignetting table instead of
// cos4, a mono white-balance gain and a power-law gamma. Demosaic and the
// colour matrix are left out (nothing to interpolate for a mono sensor).
inline PipelineConfig MonoConfig(int width, int height) {
  PipelineConfig c;
  c.geometry.width = width;
  c.geometry.height = height;
  c.geometry.cfa = Cfa::kMono;
  c.geometry.adc_bits = 10;
  c.seed = 7;
  c.exposure.exposure_time_us = 1000.0;  // the flat field at ~50 % of the range
  c.exposure.f_number = 2.0;
  c.vignetting.mode = VignettingMode::kTable;
  const double table[5] = {1.0, 0.97, 0.9, 0.78, 0.6};
  for (int i = 0; i < 5; ++i) c.vignetting.table[i] = table[i];
  c.vignetting.table_count = 5;
  c.sensor.gain_db = 6.0;
  c.white_balance.gain[1] = 1.25;
  c.gamma.curve = GammaCurve::kPower;
  c.gamma.gamma = 2.2;
  return c;
}

// The paper's BayerBG layout with bilinear demosaic (eq. 23-24), a 16-bit
// ADC with 12 dB analog gain, a warm sensor (dark current doubling), a seed using all 64 bits, no
// vignetting (left out) and a real colour matrix.
inline PipelineConfig BilinearBgConfig(int width, int height) {
  PipelineConfig c;
  c.geometry.width = width;
  c.geometry.height = height;
  c.geometry.cfa = Cfa::kBayerBG;
  c.geometry.adc_bits = 16;
  c.seed = 0x0123456789ABCDEFull;
  c.exposure.exposure_time_us = 20000.0;
  c.exposure.f_number = 4.0;
  c.sensor.gain_db = 12.0;
  c.sensor.temperature_c = 45.0;
  c.sensor.black_level_dn = 256.0;
  c.white_balance.gain[0] = 1.9;
  c.white_balance.gain[1] = 1.0;
  c.white_balance.gain[2] = 1.45;
  c.demosaic.method = DemosaicMethod::kBilinear;
  const double m[9] = {1.62, -0.41, -0.21, -0.28, 1.49, -0.21, -0.07, -0.52, 1.59};
  for (int i = 0; i < 9; ++i) c.color_matrix.m[i] = m[i];
  c.gamma.curve = GammaCurve::kSrgb;
  return c;
}

// The demo camera shaken and moving: camera-source motion blur with rotation
// about every axis, translation (so the depth plane, DepthMetres, is read)
// and a rolling shutter of 12 us per row.
inline PipelineConfig MotionConfig(int width, int height) {
  PipelineConfig c = DemoConfig(width, height);
  c.motion_blur.source = MotionSource::kCamera;
  c.motion_blur.angular_velocity_rad_s[0] = 0.3;
  c.motion_blur.angular_velocity_rad_s[1] = -0.8;
  c.motion_blur.angular_velocity_rad_s[2] = 0.5;
  c.motion_blur.linear_velocity_m_s[0] = 0.4;
  c.motion_blur.linear_velocity_m_s[1] = -0.1;
  c.motion_blur.linear_velocity_m_s[2] = 1.2;
  c.motion_blur.fx_px = c.vignetting.focal_length_px;
  c.motion_blur.fy_px = c.vignetting.focal_length_px;
  c.motion_blur.line_time_us = 12.0;
  c.motion_blur.max_displacement_px = 24;
  return c;
}

// Depth of field on the textured scene (DepthMetres below): the stages in
// the radiance domain, then exposure, so the cases hash the DoF output scaled
// to photons. 28 mm at f/1.4 focused at 1.2 m on 18.75 um pixels: CoCs of
// 0 .. 30 px. Diffusion with a 12-row column window; gather capped at 6 px;
// structural blur (diffusion of a radial polynomial) without depth.
inline PipelineConfig DofConfig(int width, int height, DofMethod method, bool structural) {
  PipelineConfig c;
  c.geometry.width = width;
  c.geometry.height = height;
  c.exposure.f_number = 1.4;
  c.dof.method = method;
  c.dof.focal_length_mm = 28.0;
  c.dof.pixel_pitch_um = 18.75;
  c.dof.focus_distance_m = 1.2;
  c.dof.column_window = 12;
  c.dof.max_radius_px = 6;
  if (structural) {
    c.dof.structural_only = true;
    c.dof.structural_poly[0] = 0.5;
    c.dof.structural_poly[2] = 9.0;
  }
  c.order[0] = StageId::kDofGather;
  c.order[1] = StageId::kDofRows;
  c.order[2] = StageId::kDofColumns;
  c.order[3] = StageId::kExposure;
  c.order_count = 4;
  return c;
}
inline PipelineConfig DofDiffusionConfig(int w, int h) { return DofConfig(w, h, DofMethod::kDiffusion, false); }
inline PipelineConfig DofGatherConfig(int w, int h) { return DofConfig(w, h, DofMethod::kGather, false); }
inline PipelineConfig StructuralBlurConfig(int w, int h) { return DofConfig(w, h, DofMethod::kOff, true); }

// Depth in metres of the cases' scenes at (x, y): a slanted plane from 0.4 m
// to 6 m, a band of 1e10 (sky) at the top, a focus-distance square, and
// single pixels at 0 and -1 m (IEEE basic operations only).
inline double DepthMetres(int width, int height, int x, int y) {
  if (y * 8 < height) return 1e10;
  if (x == width / 3 && y == height / 2) return 0.0;
  if (x == width / 2 && y == height / 3) return -1.0;
  if (x * 5 > width * 3 && x * 5 < width * 4 && y * 2 > height) return 1.2;
  return 0.4 + 5.6 * (static_cast<double>(x) + y) / (width + height);
}

// The demo camera behind a lens: Brown-Conrady barrel distortion with
// tangential terms (typical machine-vision magnitudes), lateral chromatic
// aberration, Lanczos-3 resampling. Distortion is the first stage that runs
// (on radiance, reading the input rows directly) and computes only each CFA
// site's colour (the pipeline's site-only path).
inline PipelineConfig LensConfig(int width, int height) {
  PipelineConfig c = DemoConfig(width, height);
  // The typical lens, a little longer and nearer the centre.
  LensModel& m = c.distortion.lens;
  m = test::TypicalLens(width, height);
  m.fx = m.fy = 0.8 * width;
  m.cx = (width - 1) / 2.0 + 1.5;
  m.cy = (height - 1) / 2.0 - 0.75;
  c.distortion.chromatic_scale[0] = 1.003;
  c.distortion.chromatic_scale[2] = 0.998;
  return c;
}

// The lens alone in full colour, without the ringing clamp (the filter as it
// is, saturated to [0, 2^32 - 1]): the distortion stage's other kernel path.
inline PipelineConfig LensUnclampedConfig(int width, int height) {
  PipelineConfig c = LensConfig(width, height);
  c.distortion.ringing_clamp = false;
  c.order[0] = StageId::kDistortion;
  c.order_count = 1;
  return c;
}

// The lens with Lanczos-4 resampling (8 taps, OpenCV's INTER_LANCZOS4),
// CFA site only as in LensConfig: the widest filter's kernel paths.
inline PipelineConfig LensLanczos4Config(int width, int height) {
  PipelineConfig c = LensConfig(width, height);
  c.distortion.filter = ResampleFilter::kLanczos4;
  return c;
}

// The radiance of the tests' TexturedScene (tests/support/test_support.cc
// uses this too) at (x, y) for colour c, Q16.16: smooth gradients, a checkerboard of 8-pixel cells and a
// bright (saturating) spot. IEEE basic operations only, so it is the same on
// every platform.
inline uint32_t TexturedRadiance(int width, int height, int x, int y, int c) {
  const double gx = static_cast<double>(x) / (width > 1 ? width - 1 : 1);
  const double gy = static_cast<double>(y) / (height > 1 ? height - 1 : 1);
  const bool check = ((x / 8) + (y / 8)) % 2 == 0;
  double v[3] = {0.05 + 0.9 * gx, 0.1 + 0.6 * gy, 0.3 * (check ? 1.0 : 0.2)};
  const double dx = x - width * 0.7, dy = y - height * 0.3;
  if (dx * dx + dy * dy < 9.0) v[0] = v[1] = v[2] = 400.0;
  return Q<16, 16>::FromDouble(v[c]).raw;
}

// The issue-5 effects: flare (the textured scene's bright spot is above the
// threshold), BayerGR, blooming (the spot saturates), CCD smear, row and
// column FPN, hot, dead and stuck pixels.
inline PipelineConfig ArtefactsConfig(int width, int height) {
  PipelineConfig c;
  c.geometry.width = width;
  c.geometry.height = height;
  c.geometry.cfa = Cfa::kBayerGR;
  c.geometry.adc_bits = 12;
  c.seed = 11;
  c.exposure.exposure_time_us = 20000.0;
  c.exposure.f_number = 2.0;
  c.flare.enabled = true;
  c.flare.threshold = 50.0;
  c.flare.ghost_count = 3;
  c.blooming.enabled = true;
  c.blooming.rows = 8;
  c.sensor.smear_row_transfer_us = 2.0;
  c.sensor.smear_leak = 0.01;
  c.sensor.row_fpn_e = 2.0;
  c.sensor.column_fpn_e = 1.5;
  c.sensor.hot_pixel_fraction = 0.002;
  c.sensor.dead_pixel_fraction = 0.001;
  c.sensor.stuck_pixel_fraction = 0.001;
  c.demosaic.method = DemosaicMethod::kMalvar;
  return c;
}

// Dark current non-uniformity (DCNU 30 %: the gain max(0, 1 + 0.3 z4)
// clamps at 0 for z4 < -3.3) on a warm BayerBG sensor with a long exposure,
// so that the dark charge (800 e-/s x 4 x 50 ms = 160 e-) shows next to the
// signal; PRNU and DSNU at their defaults, drawn per frame, and hot pixels
// (which add to the DCNU charge).
inline PipelineConfig DcnuConfig(int width, int height) {
  PipelineConfig c = DemoConfig(width, height);
  c.geometry.cfa = Cfa::kBayerBG;
  c.seed = 19;
  c.exposure.exposure_time_us = 50000.0;
  c.exposure.f_number = 8.0;
  c.sensor.dark_current_e_per_s = 800.0;
  c.sensor.temperature_c = c.sensor.dark_current_ref_c + 2.0 * c.sensor.dark_current_doubling_c;
  c.sensor.dcnu_percent = 30.0;
  c.sensor.hot_pixel_fraction = 0.002;
  return c;
}

// Listed defect pixels (each kind, at the corners and the centre, over a
// seeded map) and CCD smear under cos4 vignetting (the smear pre-pass applies
// the vignetting gains). The list lives in static storage refilled by each
// call: a case's config is used before the next size's call.
inline PipelineConfig ListedDefectsConfig(int width, int height) {
  PipelineConfig c = ArtefactsConfig(width, height);
  c.geometry.cfa = Cfa::kBayerRG;
  c.flare.enabled = false;
  c.blooming.enabled = false;
  c.seed = 13;
  c.vignetting.mode = VignettingMode::kCos4;
  c.vignetting.focal_length_px = 0.5 * width;  // strong: the corners get ~1/4 of the centre's light
  static DefectPixel list[4];
  list[0] = {0, 0, DefectKind::kDead, -1.0};
  list[1] = {width / 2, height / 2, DefectKind::kHot, 5000.0};
  list[2] = {width / 2 + 1, height / 2, DefectKind::kStuck, -1.0};
  list[3] = {width - 1, height - 1, DefectKind::kStuck, 1000.0};
  c.sensor.defects = list;
  c.sensor.defect_count = 4;
  return c;
}

// Flare with an environment map (core/lens/flare_environment.h) on the demo
// camera: a 32 x 16 synthetic lat-long map in static storage (refilled by
// each call) with a sky, a sun right of the view, a lamp above it, one behind
// the camera and one inside the view (skipped); the camera turned, tilted and
// rolled a little, fx = fy = 0.8 x width.
inline PipelineConfig EnvironmentFlareConfig(int width, int height) {
  PipelineConfig c = DemoConfig(width, height);
  c.seed = 17;
  c.flare.enabled = true;
  c.flare.threshold = 50.0;
  c.flare.ghost_count = 3;
  constexpr int kMapW = 32, kMapH = 16;
  static float map[kMapW * kMapH * 3];
  for (int j = 0; j < kMapH; ++j)
    for (int i = 0; i < kMapW; ++i)
      for (int k = 0; k < 3; ++k) map[(j * kMapW + i) * 3 + k] = j < kMapH / 2 ? 1.0f + 0.25f * static_cast<float>(k) : 0.3f;
  const auto set = [](int i, int j, float r, float g, float b) {
    float* t = &map[(j * kMapW + i) * 3];
    t[0] = r;
    t[1] = g;
    t[2] = b;
  };
  set(20, 6, 20000.0f, 19000.0f, 17000.0f);  // longitude 50.6, latitude 16.9: right of the view
  set(16, 4, 900.0f, 800.0f, 600.0f);        // longitude 5.6, latitude 39.4: above it
  set(1, 7, 3000.0f, 3000.0f, 3000.0f);      // behind: haze only
  set(16, 7, 5000.0f, 5000.0f, 5000.0f);     // inside the view: skipped
  FlareEnvironment& e = c.flare.environment;
  e.texels = map;
  e.width = kMapW;
  e.height = kMapH;
  e.yaw_deg = 10.0;
  e.pitch_deg = 5.0;
  e.roll_deg = 3.0;
  e.gain = 1.5;
  e.max_sources = 8;
  e.fx = e.fy = 0.8 * width;
  e.cx = (width - 1) / 2.0;
  e.cy = (height - 1) / 2.0;
  return c;
}

}  // namespace camsim::cross
