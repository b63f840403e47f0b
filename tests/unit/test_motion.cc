// Motion blur and rolling shutter (core/lens/motion_blur.h): predicted smear
// of a point under camera rotation, exposure scaling, rolling-shutter skew,
// planner, strip-height bit-exactness, configuration errors, and the error
// against the double reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <thread>
#include <vector>

#include "core/lens/motion_blur_ref.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

// A pipeline of the motion stage alone: radiance Q16.16 in and out.
PipelineConfig MotionOnly(int w, int h, double exposure_us) {
  PipelineConfig c;
  c.geometry.width = w;
  c.geometry.height = h;
  c.order[0] = StageId::kMotionBlur;
  c.order_count = 1;
  c.exposure.exposure_time_us = exposure_us;
  c.motion_blur.source = MotionSource::kCamera;
  c.motion_blur.fx_px = 500.0;
  c.motion_blur.fy_px = 500.0;
  return c;
}

// Extra planes for a frame: inverse depth and motion vectors.
struct Extras {
  std::vector<uint32_t> inverse_depth;
  std::vector<int32_t> vectors[2];
};

FrameInput ViewOf(const test::Scene& s, const Extras& e) {
  FrameInput in = s.View();
  if (!e.inverse_depth.empty())
    in.inverse_depth = MakeImageView<const uint32_t>(e.inverse_depth.data(), s.width, s.height);
  for (int c = 0; c < 2; ++c)
    if (!e.vectors[c].empty()) in.motion_vectors[c] = MakeImageView<const int32_t>(e.vectors[c].data(), s.width, s.height);
  return in;
}

// Runs the pipeline's whole frame in strips of strip_rows; returns interleaved RGB.
std::vector<uint32_t> RunMotion(const test::Built& b, const test::Scene& s, const Extras& e, int strip_rows,
                                WorkerStats* stats = nullptr) {
  std::vector<uint32_t> out(static_cast<size_t>(s.width) * s.height * 3, 0xDEADBEEFu);
  Tap t;
  t.format = TapFormat::kU32;
  t.data = out.data();
  t.stride = static_cast<ptrdiff_t>(s.width) * 3;
  const FrameInput in = ViewOf(s, e);
  EXPECT_TRUE(b.pipeline.CheckInput(in).ok());
  b.pipeline.ProcessFrame(in, 0, strip_rows, &t, 1, stats, nullptr);
  return out;
}

test::Scene PointScene(int w, int h, int px, int py, double value) {
  test::Scene s = test::FlatScene(w, h, 0, 0, 0);
  for (int c = 0; c < 3; ++c) s.plane[c][static_cast<size_t>(py) * w + px] = Q<16, 16>::FromDouble(value).raw;
  return s;
}

// Centroid, length (sqrt(12 * variance): the length of a uniform segment),
// mass and extent of channel 0 along row y.
struct RowProfile {
  double mass = 0, centre = 0, length = 0;
  int first = -1, last = -1;
};
RowProfile Profile(const std::vector<uint32_t>& out, int w, int y) {
  RowProfile p;
  double m1 = 0, m2 = 0;
  for (int x = 0; x < w; ++x) {
    const double v = out[(static_cast<size_t>(y) * w + x) * 3];
    if (v == 0) continue;
    if (p.first < 0) p.first = x;
    p.last = x;
    p.mass += v;
    m1 += v * x;
    m2 += v * x * x;
  }
  if (p.mass > 0) {
    p.centre = m1 / p.mass;
    p.length = std::sqrt(12.0 * (m2 / p.mass - p.centre * p.centre));
  }
  return p;
}

// Yaw (rotation about the camera's y axis) moves a point at the principal
// point by du/dt = -fx wy pixels per second: with fx = 500, wy = 2 rad/s and
// T = 10 ms, D = -10 px. The output is the point smeared uniformly over the
// segment [x0 - 5, x0 + 5] of its own row (rho = 0 on the middle row).
TEST(MotionBlur, PointUnderRotationSmearsIntoPredictedSegment) {
  const int w = 101, h = 41, x0 = 50, y0 = 20;
  PipelineConfig c = MotionOnly(w, h, 10000.0);
  c.motion_blur.angular_velocity_rad_s[1] = 2.0;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const double value = 100.0;
  const test::Scene s = PointScene(w, h, x0, y0, value);
  const std::vector<uint32_t> out = RunMotion(*b, s, {}, 8);
  const double predicted = 500.0 * 2.0 * 0.01;  // |D| = fx wy T
  for (int y = 0; y < h; ++y)
    if (y != y0) {
      EXPECT_EQ(Profile(out, w, y).mass, 0.0) << "row " << y;
    }
  const RowProfile p = Profile(out, w, y0);
  // Support: the segment, widened by one pixel of bilinear footprint.
  EXPECT_GE(p.first, x0 - predicted / 2 - 1);
  EXPECT_LE(p.last, x0 + predicted / 2 + 1);
  for (int x = x0 - 4; x <= x0 + 4; ++x) EXPECT_GT(out[(static_cast<size_t>(y0) * w + x) * 3], 0u) << x;
  EXPECT_NEAR(p.centre, x0, 0.05);
  EXPECT_NEAR(p.length, predicted, 0.6);
  // Each of the n samples spreads weight 1 over the pixels (bilinear hat):
  // the smear keeps the point's energy.
  EXPECT_NEAR(p.mass / (Q<16, 16>::FromDouble(value).raw), 1.0, 0.02);
}

TEST(MotionBlur, DoublingExposureDoublesTheSmear) {
  const int w = 161, h = 21, x0 = 80, y0 = 10;
  double length[2];
  for (int k = 0; k < 2; ++k) {
    PipelineConfig c = MotionOnly(w, h, k == 0 ? 8000.0 : 16000.0);
    c.motion_blur.angular_velocity_rad_s[1] = -3.0;  // D = +12 px, then +24 px
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const std::vector<uint32_t> out = RunMotion(*b, PointScene(w, h, x0, y0, 50.0), {}, 5);
    const RowProfile p = Profile(out, w, y0);
    length[k] = p.length;
    EXPECT_NEAR(p.centre, x0, 0.05);
  }
  EXPECT_NEAR(length[0], 12.0, 0.6);
  EXPECT_NEAR(length[1] / length[0], 2.0, 0.05);
}

// Pitch (rotation about x) smears vertically: dv/dt = fy wx (1 + y^2).
TEST(MotionBlur, PitchSmearsAlongTheColumn) {
  const int w = 21, h = 81, x0 = 10, y0 = 40;
  PipelineConfig c = MotionOnly(w, h, 10000.0);
  c.motion_blur.angular_velocity_rad_s[0] = 1.6;  // D = 8 px down
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const std::vector<uint32_t> out = RunMotion(*b, PointScene(w, h, x0, y0, 80.0), {}, 3);
  double mass = 0, m1 = 0, m2 = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double v = out[(static_cast<size_t>(y) * w + x) * 3];
      if (x != x0) {
        EXPECT_EQ(v, 0.0);
      }
      mass += v;
      m1 += v * y;
      m2 += v * y * y;
    }
  const double centre = m1 / mass;
  EXPECT_NEAR(centre, y0, 0.05);
  EXPECT_NEAR(std::sqrt(12.0 * (m2 / mass - centre * centre)), 8.0, 0.6);
}

TEST(MotionBlur, StillCameraIsLeftOut) {
  PipelineConfig c = MotionOnly(16, 8, 10000.0);
  c.order[1] = StageId::kExposure;
  c.order_count = 2;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  EXPECT_FALSE(b->pipeline.plan().entries[0].runs);
  EXPECT_STREQ(b->pipeline.plan().entries[0].reason, "camera is still (zero angular and linear velocity)");
  c.motion_blur.source = MotionSource::kOff;
  auto off = test::Build(c);
  ASSERT_TRUE(off->status.ok());
  EXPECT_STREQ(off->pipeline.plan().entries[0].reason, "motion.source is off");
  // Rolling shutter without motion changes nothing either.
  c.motion_blur.source = MotionSource::kCamera;
  c.motion_blur.line_time_us = 20.0;
  auto rs = test::Build(c);
  ASSERT_TRUE(rs->status.ok());  // a refused config would leave runs at its default, false
  EXPECT_FALSE(rs->pipeline.plan().entries[0].runs);
  EXPECT_STREQ(rs->pipeline.plan().entries[0].reason, "camera is still (zero angular and linear velocity)");
}

// Measures the subpixel position of a bright-to-dark vertical edge in row y:
// the number of "bright" pixels, sum(v) / bright.
double EdgeAt(const std::vector<uint32_t>& out, int w, int y, double bright) {
  double s = 0;
  for (int x = 0; x < w; ++x) s += out[(static_cast<size_t>(y) * w + x) * 3];
  return s / bright;
}

// Rolling shutter under a pan: row y is exposed at t_y = (y - (H-1)/2) * line
// time, when the scene has moved by du/dt * t_y: a vertical edge leans by
// du/dt * line_time pixels per row. A tiny exposure (10 us) keeps the blur
// itself below 0.01 px.
TEST(MotionBlur, RollingShutterSkewsAVerticalEdgeUnderPan) {
  const int w = 81, h = 61, edge = 40;
  PipelineConfig c = MotionOnly(w, h, 10.0);
  c.motion_blur.angular_velocity_rad_s[1] = 1.0;  // du/dt = -500 px/s near the centre
  c.motion_blur.line_time_us = 200.0;             // -0.1 px per row, 6 px over the frame
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  test::Scene s = test::FlatScene(w, h, 0, 0, 0);
  const uint32_t bright = Q<16, 16>::FromDouble(10.0).raw;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < edge; ++x)
      for (int ch = 0; ch < 3; ++ch) s.plane[ch][static_cast<size_t>(y) * w + x] = bright;
  const std::vector<uint32_t> out = RunMotion(*b, s, {}, 7);
  MotionBlurConfig rc = c.motion_blur;
  ref::MotionRefInput ri;
  ri.width = w;
  ri.height = h;
  for (int y = 0; y < h; y += 6) {
    // Predicted: the edge pixel's velocity (with its 1 + x^2 factor) times t_y.
    double dx, dy;
    ref::RefMotionDisplacement(rc, ri, 10.0, edge, y, &dx, &dy);
    const double t_over_T = (y - (h - 1) / 2.0) * 200.0 / 10.0;
    EXPECT_NEAR(EdgeAt(out, w, y, bright), edge + dx * t_over_T, 0.02) << "row " << y;
  }
  // Top to bottom: 60 rows of -0.1 px.
  EXPECT_NEAR(EdgeAt(out, w, h - 1, bright) - EdgeAt(out, w, 0, bright), -6.0, 0.02);
}

// A scene with translation (needs depth), rotation about all axes and a
// rolling shutter: every strip height gives the same bytes; so do threads.
struct Busy {
  PipelineConfig config;
  test::Scene scene;
  Extras extras;
};
Busy BusyCase(int w, int h, MotionSource source) {
  Busy k;
  k.config = MotionOnly(w, h, 8000.0);
  MotionBlurConfig& m = k.config.motion_blur;
  m.source = source;
  m.angular_velocity_rad_s[0] = 0.4;
  m.angular_velocity_rad_s[1] = -0.9;
  m.angular_velocity_rad_s[2] = 0.7;
  m.linear_velocity_m_s[0] = 0.5;
  m.linear_velocity_m_s[1] = -0.2;
  m.linear_velocity_m_s[2] = 1.5;
  m.line_time_us = 15.0;
  m.max_displacement_px = 20;
  m.vector_fps = 50.0;
  k.scene = test::TexturedScene(w, h);
  k.extras.inverse_depth.resize(static_cast<size_t>(w) * h);
  for (int c = 0; c < 2; ++c) k.extras.vectors[c].resize(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      // Depth 0.5 .. 20 m in bands, and a sky (inverse depth 0) at the top.
      const double depth = y < h / 6 ? 0.0 : 0.5 + 19.5 * ((x * 7 + y * 3) % 50) / 49.0;
      k.extras.inverse_depth[i] = depth > 0 ? static_cast<uint32_t>(std::lround(1048576.0 / depth)) : 0u;
      // Vectors: a swirl, up to ~12 px per frame interval.
      k.extras.vectors[0][i] = static_cast<int32_t>(std::lround(65536.0 * 0.15 * (y - h / 2)));
      k.extras.vectors[1][i] = static_cast<int32_t>(std::lround(65536.0 * -0.15 * (x - w / 2)));
    }
  return k;
}

TEST(MotionBlur, BitExactForEveryStripHeightAndThreads) {
  for (MotionSource source : {MotionSource::kCamera, MotionSource::kVectors}) {
    const Busy k = BusyCase(67, 53, source);
    auto b = test::Build(k.config, 3);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const std::vector<uint32_t> whole = RunMotion(*b, k.scene, k.extras, 53);
    for (int strip : {1, 2, 7, 16, 31}) EXPECT_EQ(RunMotion(*b, k.scene, k.extras, strip), whole) << "strip " << strip;
    // Threads: strips of 5 rows on 3 workers.
    std::vector<uint32_t> out(whole.size(), 0xDEADBEEFu);
    Tap t;
    t.format = TapFormat::kU32;
    t.data = out.data();
    t.stride = 67 * 3;
    const FrameInput in = ViewOf(k.scene, k.extras);
    std::vector<std::thread> pool;
    for (int wk = 0; wk < 3; ++wk)
      pool.emplace_back([&, wk] {
        for (int y0 = wk * 5; y0 < 53; y0 += 15) b->pipeline.ProcessStrip(in, 0, y0, y0 + 5, wk, &t, 1, nullptr, nullptr);
      });
    for (std::thread& th : pool) th.join();
    EXPECT_EQ(out, whole);
    // And the blur is real: the output differs from the input.
    size_t changed = 0;
    for (size_t i = 0; i < whole.size(); ++i) changed += whole[i] != k.scene.plane[i % 3][i / 3];
    EXPECT_GT(changed, whole.size() / 2);
  }
}

// Skipping off (PipelineConfig::skip_idle) runs the gather on the pixels
// that do not move: one sample at the pixel itself, the same bytes.
TEST(MotionBlur, SkippingOffChangesNoByte) {
  Busy k = BusyCase(61, 47, MotionSource::kVectors);
  for (int c = 0; c < 2; ++c)  // the left 20 columns still
    for (int y = 0; y < 47; ++y)
      for (int x = 0; x < 20; ++x) k.extras.vectors[c][static_cast<size_t>(y) * 61 + x] = 0;
  WorkerStats on, off;
  auto b = test::Build(k.config);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const std::vector<uint32_t> skipped = RunMotion(*b, k.scene, k.extras, 9, &on);
  k.config.skip_idle = false;
  auto all = test::Build(k.config);
  ASSERT_TRUE(all->status.ok()) << all->status.message();
  EXPECT_EQ(RunMotion(*all, k.scene, k.extras, 9, &off), skipped);
  EXPECT_GE(on.stage[0].skipped_px, 20 * 47) << "the still columns, and the swirl's centre";
  EXPECT_LT(on.stage[0].skipped_px, 61 * 47 / 2);
  EXPECT_EQ(off.stage[0].skipped_px, on.stage[0].skipped_px) << "counted the same";
}

// Error against the double reference on the busy scene, in units of the
// input (Q16.16 radiance): the stage's quantisations are the bilinear
// weights (1/256 px), the sample offsets (2^-16 px) and the final rounding.
// The third case clamps: the vectors' whole length (up to ~12 px) inside the
// exposure against a 2 px bound, so most samples pile up at the bound, in the
// stage and in the reference alike.
TEST(MotionBlur, MatchesTheDoubleReference) {
  struct Case {
    MotionSource source;
    int bound;  // max_displacement_px; 0: the default
  };
  for (const Case& cs : {Case{MotionSource::kCamera, 0}, Case{MotionSource::kVectors, 0}, Case{MotionSource::kVectors, 2}}) {
    const MotionSource source = cs.source;
    const int bound = cs.bound;
    const int w = 96, h = 64;
    Busy k = BusyCase(w, h, source);
    std::vector<uint32_t> unclamped;
    if (bound > 0) {
      k.config.motion_blur.vector_fps = 125.0;  // the whole vector inside the 8 ms exposure: up to ~12 px
      auto free = test::Build(k.config);
      ASSERT_TRUE(free->status.ok());
      unclamped = RunMotion(*free, k.scene, k.extras, 9);
      k.config.motion_blur.max_displacement_px = bound;
    }
    auto b = test::Build(k.config);
    ASSERT_TRUE(b->status.ok());
    const std::vector<uint32_t> out = RunMotion(*b, k.scene, k.extras, 9);
    if (bound > 0) {
      size_t clamped = 0;
      for (size_t i = 0; i < out.size(); ++i) clamped += out[i] != unclamped[i];
      ASSERT_GT(clamped, out.size() / 8) << "the bound hardly binds: the clamp goes untested (" << clamped << " of " << out.size() << ")";
    }
    std::vector<double> planes[3], iz(k.extras.inverse_depth.size()), vec[2];
    for (int c = 0; c < 3; ++c) planes[c].assign(k.scene.plane[c].begin(), k.scene.plane[c].end());
    for (size_t i = 0; i < iz.size(); ++i) iz[i] = k.extras.inverse_depth[i] / 1048576.0;
    for (int c = 0; c < 2; ++c)
      for (int32_t v : k.extras.vectors[c]) vec[c].push_back(v / 65536.0);
    ref::MotionRefInput ri;
    ri.width = w;
    ri.height = h;
    for (int c = 0; c < 3; ++c) ri.plane[c] = &planes[c];
    ri.inverse_depth = &iz;
    ri.vectors[0] = &vec[0];
    ri.vectors[1] = &vec[1];
    const auto want = ref::RefMotionBlur(k.config.motion_blur, ri, 8000.0);
    // Relative to the input's full range per channel (the bright spot saturates
    // to 400.0): weights quantised to 1/1024 px give at most range / 2048 per sample.
    double max_rel = 0, sum_abs = 0;
    for (int c = 0; c < 3; ++c) {
      const double range = *std::max_element(planes[c].begin(), planes[c].end());
      for (size_t i = 0; i < want[c].size(); ++i) {
        const double e = std::abs(out[i * 3 + c] - want[c][i]);
        max_rel = std::max(max_rel, e / range);
        sum_abs += e;
      }
    }
    const double mean_abs = sum_abs / (3.0 * w * h);
    std::printf("motion %s%s: max error %.3g of range, mean %.3g LSB (Q16.16)\n",
                source == MotionSource::kCamera ? "camera" : "vectors", bound > 0 ? ", clamped at 2 px" : "", max_rel,
                mean_abs);
    EXPECT_LT(max_rel, 1.0 / 2048);
    EXPECT_LT(mean_abs, 24.0);  // measured 15-16 LSB: 2.4e-4 of radiance 1.0
    // Clamped: measured 13.2 LSB (deterministic: the stage is bit-exact); a
    // bound a quarter pixel too far gives 15.4.
    if (bound > 0) {
      EXPECT_LT(mean_abs, 14.5);
    }
  }
}

TEST(MotionBlur, CheckInputNeedsDepthForTranslationAndVectorsForVectors) {
  const Busy k = BusyCase(32, 24, MotionSource::kCamera);
  auto b = test::Build(k.config);
  ASSERT_TRUE(b->status.ok());
  const Status s = b->pipeline.CheckInput(k.scene.View());
  EXPECT_FALSE(s.ok());
  EXPECT_STREQ(s.field(), "motion.linear_velocity_m_s");
  EXPECT_TRUE(b->pipeline.CheckInput(ViewOf(k.scene, k.extras)).ok());
  const Busy v = BusyCase(32, 24, MotionSource::kVectors);
  auto bv = test::Build(v.config);
  ASSERT_TRUE(bv->status.ok());
  EXPECT_STREQ(bv->pipeline.CheckInput(v.scene.View()).field(), "motion.source");
  // Rotation only: no depth needed.
  PipelineConfig rot = MotionOnly(32, 24, 1000.0);
  rot.motion_blur.angular_velocity_rad_s[2] = 1.0;
  auto br = test::Build(rot);
  ASSERT_TRUE(br->status.ok());
  EXPECT_TRUE(br->pipeline.CheckInput(k.scene.View()).ok());
}

TEST(MotionBlur, ConfigErrorsNameTheKey) {
  struct Case {
    void (*edit)(PipelineConfig&);
    const char* field;
  };
  const Case cases[] = {
      {[](PipelineConfig& c) { c.motion_blur.max_displacement_px = 512; }, "motion.max_displacement_px"},
      {[](PipelineConfig& c) { c.motion_blur.max_displacement_px = 0; }, "motion.max_displacement_px"},
      {[](PipelineConfig& c) { c.motion_blur.max_samples = 257; }, "motion.max_samples"},
      {[](PipelineConfig& c) { c.motion_blur.samples_per_px = 0.01; }, "motion.samples_per_px"},
      {[](PipelineConfig& c) { c.motion_blur.samples_per_px = 17; }, "motion.samples_per_px"},
      {[](PipelineConfig& c) { c.motion_blur.line_time_us = -1; }, "motion.line_time_us"},
      {[](PipelineConfig& c) { c.motion_blur.line_time_us = std::nan(""); }, "motion.line_time_us"},
      {[](PipelineConfig& c) { c.motion_blur.angular_velocity_rad_s[0] = INFINITY; }, "motion.angular_velocity_rad_s"},
      {[](PipelineConfig& c) { c.motion_blur.angular_velocity_rad_s[1] = 1e9; }, "motion.angular_velocity_rad_s"},
      {[](PipelineConfig& c) { c.motion_blur.linear_velocity_m_s[2] = 1e12; }, "motion.linear_velocity_m_s"},
      {[](PipelineConfig& c) { c.motion_blur.fx_px = 0; }, "motion.fx_px"},
      {[](PipelineConfig& c) { c.motion_blur.fy_px = 0.5; }, "motion.fy_px"},
      {[](PipelineConfig& c) {
         c.geometry.height = 100;
         c.motion_blur.fy_px = 2;  // 49.5 rows from the centre / 2 px: |y| > 16
       }, "motion.fy_px"},
      {[](PipelineConfig& c) { c.motion_blur.source = static_cast<MotionSource>(9); }, "motion.source"},
      {[](PipelineConfig& c) {
         c.motion_blur.source = MotionSource::kVectors;
         c.motion_blur.vector_fps = 0;
       }, "motion.vector_fps"},
      {[](PipelineConfig& c) {
         c.motion_blur.source = MotionSource::kVectors;
         c.motion_blur.vector_fps = 1e5;  // exposure 1000 us = 100 frame intervals
       }, "motion.vector_fps"},
  };
  for (const Case& k : cases) {
    PipelineConfig c = MotionOnly(32, 24, 1000.0);
    c.motion_blur.angular_velocity_rad_s[2] = 0.5;
    k.edit(c);
    Pipeline p;
    const Status s = p.Configure(c, 1, false);
    EXPECT_FALSE(s.ok()) << k.field;
    EXPECT_STREQ(s.field(), k.field);
  }
}

// Motion beyond the bound stops there: with max_displacement_px = 4 a 20 px
// smear is cut to the 9 pixels [x0 - 4, x0 + 4] (plus bilinear spill: none,
// as the clamped offsets are whole pixels).
TEST(MotionBlur, DisplacementBeyondTheBoundIsClamped) {
  const int w = 61, h = 9, x0 = 30, y0 = 4;
  PipelineConfig c = MotionOnly(w, h, 10000.0);
  c.motion_blur.angular_velocity_rad_s[1] = 4.0;  // D = -20 px
  c.motion_blur.max_displacement_px = 4;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const RowProfile p = Profile(RunMotion(*b, PointScene(w, h, x0, y0, 10.0), {}, 4), w, y0);
  EXPECT_GE(p.first, x0 - 4);
  EXPECT_LE(p.last, x0 + 4);
  EXPECT_NEAR(p.centre, x0, 0.05);
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// A pan reads only the rows its samples can reach: the window (and so the
// line rings) shrinks from 2 * max_displacement_px + 2 rows to a few.
TEST(MotionBlur, PanReadsFewRows) {
  PipelineConfig c = MotionOnly(640, 480, 10000.0);
  c.motion_blur.angular_velocity_rad_s[1] = 2.0;  // 10 px of horizontal blur
  c.motion_blur.max_displacement_px = 200;
  MotionBlurStage s;
  ASSERT_TRUE(s.Configure(c.motion_blur, c.geometry, 10000.0).ok());
  // The rotational dv along the edge rows is -T fy wy x y: at the corners
  // 0.01 * 500 * 2 * 0.64 * 0.48 = 3.07 px, times |tau| <= 1/2.
  EXPECT_EQ(s.VerticalReach(), 3);
  EXPECT_EQ(s.InputRows(100, 480).first, 97);
  EXPECT_EQ(s.InputRows(100, 480).last, 104);
  EXPECT_EQ(s.InputRows(0, 480).first, 0);
  EXPECT_EQ(s.InputRows(479, 480).last, 479);
  // Translation can move anything anywhere (depth is per pixel): the full bound.
  c.motion_blur.linear_velocity_m_s[0] = 0.1;
  ASSERT_TRUE(s.Configure(c.motion_blur, c.geometry, 10000.0).ok());
  EXPECT_EQ(s.VerticalReach(), 200);
}

// A long vertical smear (150 px, beyond the old 64-row context) through the
// InputRows window: predicted length, and the same bytes for every strip height.
TEST(MotionBlur, LongSmearThroughAWideWindow) {
  const int w = 9, h = 401, x0 = 4, y0 = 200;
  PipelineConfig c = MotionOnly(w, h, 10000.0);
  c.motion_blur.angular_velocity_rad_s[0] = 30.0;  // D = fy wx T = 150 px down
  c.motion_blur.max_displacement_px = 100;
  c.motion_blur.max_samples = 256;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const test::Scene s = PointScene(w, h, x0, y0, 500.0);
  const std::vector<uint32_t> out = RunMotion(*b, s, {}, h);
  for (int strip : {1, 13, 64}) EXPECT_EQ(RunMotion(*b, s, {}, strip), out) << strip;
  double mass = 0, m1 = 0, m2 = 0;
  int first = -1, last = -1;
  for (int y = 0; y < h; ++y) {
    const double v = out[(static_cast<size_t>(y) * w + x0) * 3];
    if (v == 0) continue;
    if (first < 0) first = y;
    last = y;
    mass += v;
    m1 += v * y;
    m2 += v * y * y;
  }
  const double centre = m1 / mass;
  // (1 + y^2) grows to 1.16 at the ends of the segment (y = +-0.2 at 75..100
  // px from the centre row), so the smear is a little longer than 150 px.
  EXPECT_NEAR(centre, y0, 0.5);
  EXPECT_GE(first, y0 - 80);
  EXPECT_LE(last, y0 + 80);
  EXPECT_NEAR(std::sqrt(12.0 * (m2 / mass - centre * centre)), 150.0, 6.0);
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// The precision knob: against the continuous time integral (the reference
// with 16 samples per pixel of motion), the RMS error falls as
// samples_per_px grows.
TEST(MotionBlur, ErrorFallsAsSamplesPerPixelGrows) {
  const int w = 96, h = 64;
  Busy k = BusyCase(w, h, MotionSource::kCamera);
  k.config.motion_blur.max_samples = 256;
  std::vector<double> planes[3], iz(k.extras.inverse_depth.size());
  for (int c = 0; c < 3; ++c) planes[c].assign(k.scene.plane[c].begin(), k.scene.plane[c].end());
  for (size_t i = 0; i < iz.size(); ++i) iz[i] = k.extras.inverse_depth[i] / 1048576.0;
  ref::MotionRefInput ri;
  ri.width = w;
  ri.height = h;
  for (int c = 0; c < 3; ++c) ri.plane[c] = &planes[c];
  ri.inverse_depth = &iz;
  const auto ideal = ref::RefMotionBlur(k.config.motion_blur, ri, 8000.0, true);
  double previous = 1e300;
  for (double spp : {0.25, 0.5, 1.0, 2.0, 4.0}) {
    k.config.motion_blur.samples_per_px = spp;
    auto b = test::Build(k.config);
    ASSERT_TRUE(b->status.ok());
    const std::vector<uint32_t> out = RunMotion(*b, k.scene, k.extras, 16);
    double sq = 0;
    for (int c = 0; c < 3; ++c)
      for (size_t i = 0; i < ideal[c].size(); ++i) sq += std::pow(out[i * 3 + c] - ideal[c][i], 2);
    const double rms = std::sqrt(sq / (3.0 * w * h)) / 65536.0;
    std::printf("samples_per_px %.2f: rms error %.3g (radiance units)\n", spp, rms);
    EXPECT_LT(rms, previous * 0.8) << spp;
    previous = rms;
  }
}

}  // namespace
}  // namespace camsim

#include "host_tools/io/exr_scene.h"
#include "host_tools/scene_input.h"

namespace camsim {
namespace {

// The two motion sources agree on the bundled scene. aisle_0002 is frame 2
// of a dolly from y = -3.0 to -2.6 m over frames 1..3 (scenes/make_scene.py),
// so the camera moved 0.2 m along world +y since frame 1; the camera is
// pitched 85 degrees about x, so in its own frame (x right, y down, z
// forward) that is v = (0, -0.2 sin 5deg, 0.2 cos 5deg) per frame. The
// motion field of that translation with the scene's depth must match
// Blender's Vector pass as the host converts it (velocity, rows downwards).
// The Vector pass is a finite difference over a frame and the field a
// derivative: they differ by about the fraction of the depth travelled
// (v_z / depth), so only pixels beyond 5 m (< 4 %) are compared.
TEST(MotionBlur, CameraMotionFieldMatchesTheBlenderVectorPass) {
  io::SceneFrame frame;
  std::string error;
  ASSERT_TRUE(io::LoadSceneExr(CAMSIM_SOURCE_DIR "/scenes/aisle_0002.exr", "", &frame, &error)) << error;
  host::CoreInput in;
  host::PrepareInput(frame, frame.width, frame.height, host::SceneFit::kCrop, &in);
  const int w = in.width, h = in.height;
  MotionBlurConfig c;
  c.source = MotionSource::kCamera;
  c.fx_px = c.fy_px = 28.0 / 36.0 * w;  // scenes/README.md: 28 mm lens, 36 mm sensor width
  const double kPi = 3.14159265358979323846, tilt = 5.0 * kPi / 180.0;
  c.linear_velocity_m_s[1] = -0.2 * std::sin(tilt);
  c.linear_velocity_m_s[2] = 0.2 * std::cos(tilt);
  std::vector<double> iz(in.inverse_depth.size());
  for (size_t i = 0; i < iz.size(); ++i) iz[i] = in.inverse_depth[i] / 1048576.0;
  ref::MotionRefInput ri;
  ri.width = w;
  ri.height = h;
  ri.inverse_depth = &iz;
  std::vector<double> rel;
  int compared = 0, sign_ok = 0;
  for (int y = 0; y < h; y += 3)
    for (int x = 0; x < w; x += 3) {
      const size_t i = static_cast<size_t>(y) * w + x;
      if (!(iz[i] > 0 && iz[i] < 1.0 / 5.0)) continue;  // beyond 5 m, not sky
      double dx, dy;
      ref::RefMotionDisplacement(c, ri, 1e6, x, y, &dx, &dy);  // T = 1 s at "velocity per frame": per frame
      const double mx = in.motion[0][i] / 65536.0, my = in.motion[1][i] / 65536.0;
      const double predicted = std::hypot(dx, dy);
      if (predicted < 0.5) continue;
      ++compared;
      sign_ok += (dx * mx + dy * my) > 0;
      rel.push_back(std::hypot(dx - mx, dy - my) / predicted);
    }
  ASSERT_GT(compared, 1000);
  std::sort(rel.begin(), rel.end());
  const double median = rel[rel.size() / 2], p90 = rel[rel.size() * 9 / 10];
  std::printf("vector pass vs camera motion field: %d pixels, median error %.3g, 90th percentile %.3g\n", compared,
              median, p90);
  EXPECT_EQ(sign_ok, compared);
  EXPECT_LT(median, 0.05);
  EXPECT_LT(p90, 0.10);
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// The largest values every bound allows: saturated samples stay saturated
// (the mean of 2^32 - 1 is 2^32 - 1), extreme vectors are clamped, and
// nothing overflows (the debug preset runs this under UBSan).
TEST(MotionBlur, ExtremesStayInRange) {
  const int w = 48, h = 40;
  test::Scene s = test::FlatScene(w, h, 0, 0, 0);
  for (int c = 0; c < 3; ++c) std::fill(s.plane[c].begin(), s.plane[c].end(), 0xFFFFFFFFu);
  Extras e;
  e.inverse_depth.assign(static_cast<size_t>(w) * h, kMaxInverseDepth);  // 0.24 mm everywhere
  e.vectors[0].assign(static_cast<size_t>(w) * h, INT32_MIN);
  e.vectors[1].assign(static_cast<size_t>(w) * h, INT32_MAX);
  for (MotionSource source : {MotionSource::kCamera, MotionSource::kVectors}) {
    PipelineConfig c = MotionOnly(w, h, 1e6);  // 1 s exposure
    MotionBlurConfig& m = c.motion_blur;
    m.source = source;
    m.fx_px = m.fy_px = 3.0;                   // |x| <= 7.8, |y| <= 6.5
    m.angular_velocity_rad_s[0] = 300.0;       // just inside the 65536 px table bound
    m.angular_velocity_rad_s[1] = -300.0;
    m.angular_velocity_rad_s[2] = 300.0;
    m.linear_velocity_m_s[0] = 200.0;          // 16384 px at 1 m: near the bound
    m.linear_velocity_m_s[2] = -100.0;
    m.line_time_us = 1e6 * 32768.0 / ((h - 1) / 2.0);  // |rho| up to 32768
    m.max_displacement_px = MotionBlurStage::kMaxDisplacementPx;
    m.max_samples = MotionBlurStage::kMaxSamples;
    m.samples_per_px = 16.0;
    m.vector_fps = 16.0;  // T / Tf = 16
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.field() << " " << b->status.message();
    const std::vector<uint32_t> out = RunMotion(*b, s, e, 5);
    for (uint32_t v : out) ASSERT_EQ(v, 0xFFFFFFFFu);
  }
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// The host's conversion of depth and Blender vectors into the core's planes.
TEST(MotionBlur, HostConvertsDepthAndVectors) {
  io::SceneFrame f;
  f.width = 7;
  f.height = 1;
  for (io::FloatPlane* p : {&f.r, &f.g, &f.b, &f.depth, &f.motion_x, &f.motion_y}) {
    p->width = 7;
    p->height = 1;
    p->data.assign(7, 0.0f);
  }
  f.has_depth = f.has_motion = true;
  const float nan = std::nanf(""), inf = INFINITY;
  f.depth.data = {0.0f, -1.0f, nan, inf, 1e10f, 2.0f, 0.001f};
  f.motion_x.data = {1.0f, -2.5f, 0, 0, 0, 0, 0};
  f.motion_y.data = {2.0f, 0.25f, 0, 0, 0, 0, 0};
  host::CoreInput in;
  host::PrepareInput(f, 7, 1, host::SceneFit::kCrop, &in);
  // The rules of core/pipeline/inverse_depth.h: 0 m: nearest; negative:
  // invalid; NaN, inf: infinitely far (0); 1e10 m: 1e-10 * 2^20 rounds to 0;
  // 2 m: 2^19; 1 mm (as a float, 0.001f): round(2^20 / 0.001f).
  const uint32_t mm = static_cast<uint32_t>(std::lround(1048576.0 / static_cast<double>(0.001f)));
  const std::vector<uint32_t> iz = {kMaxInverseDepth, kInvalidInverseDepth, 0, 0, 0, 1u << 19, mm};
  EXPECT_EQ(in.inverse_depth, iz);
  // Velocity rows downwards: (-X, +Y), Q16.16.
  EXPECT_EQ(in.motion[0][0], -65536);
  EXPECT_EQ(in.motion[1][0], 131072);
  EXPECT_EQ(in.motion[0][1], 163840);
  EXPECT_EQ(in.motion[1][1], 16384);
}

}  // namespace
}  // namespace camsim
