// Lens distortion and chromatic aberration: the model's inverse, the remap
// table's error, the fixed-point resampling against the double reference,
// flat fields, streaming invariance, the CFA site-only path and bad configs.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "core/lens/distortion.h"
#include "core/lens/distortion_ref.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

// A typical calibration of a 640x480 machine-vision camera (OpenCV sample
// magnitudes): barrel distortion with a little tangential.
LensModel TypicalBrown(int width, int height) {
  LensModel m;
  m.model = DistortionModel::kBrown;
  m.fx = m.fy = 500.0 * width / 640.0;
  m.cx = (width - 1) / 2.0 + 3.25;
  m.cy = (height - 1) / 2.0 - 2.5;
  m.k[0] = -0.28;
  m.k[1] = 0.07;
  m.p1 = 0.0012;
  m.p2 = -0.0007;
  m.k[2] = 0.01;
  return m;
}

LensModel RationalLens(int width, int height) {
  LensModel m = TypicalBrown(width, height);
  m.k[0] = 0.5;
  m.k[1] = -0.1;
  m.k[2] = 0.01;
  m.k[3] = 0.8;
  m.k[4] = 0.05;
  m.k[5] = 0.0;
  return m;
}

LensModel FisheyeLens(int width, int height) {
  LensModel m;
  m.model = DistortionModel::kFisheye;
  m.fx = m.fy = 280.0 * width / 640.0;
  m.cx = (width - 1) / 2.0;
  m.cy = (height - 1) / 2.0;
  m.k[0] = 0.05;
  m.k[1] = -0.01;
  m.k[2] = 0.003;
  m.k[3] = -0.0005;
  return m;
}

PipelineConfig DistortionOnly(int width, int height, const DistortionConfig& d) {
  PipelineConfig c;
  c.geometry.width = width;
  c.geometry.height = height;
  c.order[0] = StageId::kDistortion;
  c.order_count = 1;
  c.distortion = d;
  return c;
}

// Radiance that varies smoothly (periods 23 and 31 px), 0.25 .. 1.75.
test::Scene SmoothScene(int width, int height) {
  test::Scene s;
  s.width = width;
  s.height = height;
  for (int c = 0; c < 3; ++c) s.plane[c].resize(static_cast<size_t>(width) * height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double v = 1.0 + 0.4 * std::sin(x * 0.273 + c) + 0.35 * std::cos(y * 0.2027 - c);
        s.plane[c][static_cast<size_t>(y) * width + x] = Q<16, 16>::FromDouble(v).raw;
      }
  return s;
}

TEST(LensModel, InverseReproducesTheDistortedPoint) {
  for (const LensModel& m : {TypicalBrown(640, 480), RationalLens(640, 480), FisheyeLens(640, 480)}) {
    const LensBranch b = LensAnalyse(m, 2.0);
    double worst = 0.0;
    for (int v = 0; v < 480; v += 7)
      for (int u = 0; u < 640; u += 7) {
        const double xd = (u - m.cx) / m.fx, yd = (v - m.cy) / m.fy;
        double x = 0.0, y = 0.0, rx = 0.0, ry = 0.0;
        ASSERT_TRUE(LensUndistort(m, b, xd, yd, &x, &y)) << u << "," << v;
        LensDistort(m, x, y, &rx, &ry);
        worst = std::fmax(worst, std::hypot((rx - xd) * m.fx, (ry - yd) * m.fy));
      }
    // The 2-D polish's tolerance (1e-12 normalised) leaves about 5e-10 px.
    EXPECT_LT(worst, 1e-8) << "pixels, model " << static_cast<int>(m.model);
  }
}

// A standalone stage with its tables (the pipeline's own instance is private).
struct StandaloneStage {
  DistortionStage stage;
  std::vector<uint8_t> memory;
  explicit StandaloneStage(const DistortionConfig& d, int w, int h) {
    SensorGeometry g;
    g.width = w;
    g.height = h;
    EXPECT_TRUE(stage.Configure(d, g).ok());
    WorkspaceCounter counter;
    stage.CountTables(counter);
    memory.resize(counter.bytes());
    Arena arena(Span<uint8_t>{memory.data(), memory.size()});
    EXPECT_TRUE(stage.Init(arena).ok());
  }
};

TEST(Distortion, TableErrorAgainstExactInverse) {
  const int w = 640, h = 480;
  double previous = 0.0;
  for (int step : {4, 8, 16, 32, 64}) {
    DistortionConfig d;
    d.lens = TypicalBrown(w, h);
    d.grid_step = step;
    d.chromatic_scale[0] = 1.002;
    auto b = test::Build(DistortionOnly(w, h, d));
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    ReferenceDistortion ref(d, b->pipeline.config().geometry);
    StandaloneStage standalone(d, w, h);
    const DistortionStage& stage = standalone.stage;
    double worst = 0.0, sum = 0.0;
    int n = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; c += 2) {
          int64_t fx = 0, fy = 0;
          double rx = 0.0, ry = 0.0;
          ASSERT_TRUE(stage.SourcePosition(x, y, c, &fx, &fy));
          ASSERT_TRUE(ref.Source(x, y, c, &rx, &ry));
          const double e = std::hypot(fx / 65536.0 - rx, fy / 65536.0 - ry);
          worst = std::fmax(worst, e);
          sum += e;
          ++n;
        }
    std::printf("grid step %2d: table %6zu bytes, position error max %.5f px, mean %.6f px\n", step,
                stage.TableBytes(), worst, sum / n);
    // Bilinear interpolation of a smooth field: the error grows as step^2
    // (measured 0.0111 px at step 4 for this strong barrel lens at 640x480).
    const double bound = 8e-4 * step * step;
    EXPECT_LT(worst, bound) << "step " << step;
    EXPECT_GE(worst + 1e-5, previous * 0.5);
    previous = worst;
  }
}

TEST(Distortion, FlatFieldStaysExactlyFlat) {
  const int w = 160, h = 120;
  for (ResampleFilter f : {ResampleFilter::kBilinear, ResampleFilter::kBicubic, ResampleFilter::kLanczos3, ResampleFilter::kLanczos4}) {
    for (const LensModel& m : {TypicalBrown(w, h), FisheyeLens(w, h)}) {
      DistortionConfig d;
      d.lens = m;
      d.filter = f;
      d.grid_step = 4;  // table error < 0.05 px at this small size
      d.chromatic_scale[2] = 0.997;
      auto b = test::Build(DistortionOnly(w, h, d));
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      const test::Scene scene = test::FlatScene(w, h, 0.8, 1.3, 2.1);
      const std::vector<uint32_t> out = test::RunFrame(*b, scene, 0, 13);
      ReferenceDistortion ref(d, b->pipeline.config().geometry);
      int flat = 0, filled = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int c = 0; c < 3; ++c) {
            const uint32_t v = out[(static_cast<size_t>(y) * w + x) * 3 + c];
            if (v == scene.plane[c][0]) {
              ++flat;
              continue;
            }
            ASSERT_EQ(v, 0u) << "not flat at " << x << "," << y << " c" << c;
            // A fill only where the exact source is off the image, or within
            // the table's position error (< 0.2 px at the default step) of its edge.
            double sx = 0.0, sy = 0.0;
            if (ref.Source(x, y, c, &sx, &sy)) {
              EXPECT_TRUE(sx < -0.3 || sy < -0.3 || sx > w - 0.7 || sy > h - 0.7) << x << "," << y;
            }
            ++filled;
          }
      EXPECT_GT(flat, filled);
    }
  }
}

// Fixed point against the double reference on a smooth scene. Resampling
// alone: the reference filter at the stage's own source position, so the
// error is the phase rounding (1/128 px at 64 phases) times the local slope
// plus the Q1.14 weights. Total: against the exact source position, adding
// the table's interpolation error.
TEST(Distortion, ResamplingErrorAgainstReference) {
  const int w = 320, h = 240;
  const test::Scene scene = SmoothScene(w, h);
  for (ResampleFilter f : {ResampleFilter::kBilinear, ResampleFilter::kBicubic, ResampleFilter::kLanczos3, ResampleFilter::kLanczos4})
  for (bool clamp : {true, false}) {
    DistortionConfig d;
    d.lens = TypicalBrown(w, h);
    d.filter = f;
    d.ringing_clamp = clamp;
    d.grid_step = 4;
    d.chromatic_scale[0] = 1.003;
    auto b = test::Build(DistortionOnly(w, h, d));
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const std::vector<uint32_t> out = test::RunFrame(*b, scene, 0, 17);
    ReferenceDistortion ref(d, b->pipeline.config().geometry);
    StandaloneStage s(d, w, h);
    double worst = 0.0, sum = 0.0, worst_total = 0.0, sum_total = 0.0;
    int n = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          const ImageView<const uint32_t> plane = MakeImageView<const uint32_t>(scene.plane[c].data(), w, h);
          const double v = out[(static_cast<size_t>(y) * w + x) * 3 + c];
          const double exact = ref.Sample(plane, x, y, c);
          int64_t px = 0, py = 0;
          ASSERT_TRUE(s.stage.SourcePosition(x, y, c, &px, &py));
          if (v == 0.0 || exact == 0.0) continue;  // fills (tested in FlatFieldStaysExactlyFlat)
          const double r = ref.Filter(plane, px / 65536.0, py / 65536.0);
          worst = std::fmax(worst, std::fabs(v - r));
          sum += std::fabs(v - r);
          worst_total = std::fmax(worst_total, std::fabs(v - exact));
          sum_total += std::fabs(v - exact);
          ++n;
        }
    std::printf("filter %d: resampling error max %.1f mean %.2f; with the step-4 table max %.1f mean %.2f "
                "(Q16.16 LSB, signal 0.25..1.75 = 16384..114688)\n",
                static_cast<int>(f), worst, sum / n, worst_total, sum_total / n);
    // Slope of the scene is at most 0.4*0.273 + 0.35*0.2027 = 0.18 per pixel
    // (11800 LSB/px): 1/128 px phase rounding gives <= 92 LSB, plus the
    // weights' rounding (6 x 2^-15 of the signal: < 25 LSB).
    EXPECT_LT(worst, 120.0) << "filter " << static_cast<int>(f);
    EXPECT_LT(sum / n, 30.0);
    // The step-4 table adds <= 0.025 px here (half the frame of the 640x480 case).
    EXPECT_LT(worst_total, 120.0 + 0.025 * 11800);
    EXPECT_GT(n, w * h * 3 / 2);
  }
}

PipelineConfig DemoWithLens(int w, int h) {
  PipelineConfig c = test::DemoConfig(w, h);
  c.distortion.lens = TypicalBrown(w, h);
  c.distortion.chromatic_scale[0] = 1.004;
  c.distortion.chromatic_scale[2] = 0.996;
  return c;
}

TEST(Distortion, StripHeightAndThreadsDoNotChangeOutput) {
  for (ResampleFilter f : {ResampleFilter::kBilinear, ResampleFilter::kLanczos3}) {
    PipelineConfig c = DemoWithLens(97, 75);
    c.distortion.filter = f;
    c.distortion.grid_step = 8;
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const test::Scene scene = test::TexturedScene(97, 75);
    const std::vector<uint32_t> whole = test::RunFrame(*b, scene, 2, 75);
    ASSERT_EQ(test::UnwrittenCount(whole), 0u);  // equal outputs of a run that wrote nothing prove nothing
    for (int rows : {1, 2, 7, 16, 64}) EXPECT_EQ(test::RunFrame(*b, scene, 2, rows), whole) << rows;
    auto b3 = test::Build(c, 3);
    ASSERT_TRUE(b3->status.ok());
    EXPECT_EQ(test::RunFrameThreads(*b3, scene, 2, 5, 3), whole);
  }
}

// Before a Bayer CFA the stage computes only each site's colour: the mosaic
// must be the same as the full-colour output's site samples.
TEST(Distortion, CfaSiteOnlyEqualsFullColour) {
  const int w = 90, h = 70;
  const test::Scene scene = test::TexturedScene(w, h);
  for (Cfa cfa : {Cfa::kBayerRG, Cfa::kBayerGB}) {
    PipelineConfig c;
    c.geometry.width = w;
    c.geometry.height = h;
    c.geometry.cfa = cfa;
    c.distortion.lens = TypicalBrown(w, h);
    c.distortion.chromatic_scale[0] = 1.01;
    c.vignetting.mode = VignettingMode::kCos4;
    c.vignetting.focal_length_px = 80.0;
    c.order[0] = StageId::kDistortion;
    c.order[1] = StageId::kExposure;
    c.order[2] = StageId::kVignetting;
    c.order[3] = StageId::kCfa;
    c.order_count = 4;
    auto mosaic = test::Build(c);
    ASSERT_TRUE(mosaic->status.ok()) << mosaic->status.message();
    c.order_count = 3;  // no CFA: full colour
    auto full = test::Build(c);
    ASSERT_TRUE(full->status.ok());
    const std::vector<uint32_t> m = test::RunFrame(*mosaic, scene, 0, 9);
    const std::vector<uint32_t> f = test::RunFrame(*full, scene, 0, 9);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        ASSERT_EQ(m[static_cast<size_t>(y) * w + x], f[(static_cast<size_t>(y) * w + x) * 3 + CfaColour(cfa, x, y)])
            << x << "," << y;
  }
}

TEST(Distortion, IdentityParametersLeaveTheStageOut) {
  PipelineConfig c = test::DemoConfig(64, 48);
  c.distortion.lens.model = DistortionModel::kBrown;
  c.distortion.lens.fx = c.distortion.lens.fy = 50.0;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const Plan& p = b->pipeline.plan();
  int e = 0;
  while (e < p.count && p.entries[e].id != StageId::kDistortion) ++e;
  ASSERT_LT(e, p.count);
  EXPECT_FALSE(p.entries[e].runs);
  EXPECT_NE(std::string(p.entries[e].reason).find("0"), std::string::npos) << p.entries[e].reason;
  // Same bytes as without the stage listed at all.
  PipelineConfig without = test::DemoConfig(64, 48);
  auto b2 = test::Build(without);
  const test::Scene scene = test::TexturedScene(64, 48);
  EXPECT_EQ(test::RunFrame(*b, scene, 0, 64), test::RunFrame(*b2, scene, 0, 64));
}

std::string ConfigureError(const DistortionConfig& d, int w = 640, int h = 480) {
  DistortionStage s;
  SensorGeometry g;
  g.width = w;
  g.height = h;
  const Status st = s.Configure(d, g);
  return st.ok() ? "" : std::string(st.field()) + ": " + st.message();
}

TEST(Distortion, ExtremeCoefficientsGiveClearErrorsOrDocumentedFill) {
  DistortionConfig d;
  d.lens = TypicalBrown(640, 480);
  d.lens.k[0] = -1.0;  // folds at r = 0.577 (178 px from the centre): inside the frame
  d.lens.k[1] = d.lens.k[2] = 0.0;
  EXPECT_NE(ConfigureError(d).find("distortion.k1"), std::string::npos) << ConfigureError(d);
  EXPECT_NE(ConfigureError(d).find("folds"), std::string::npos);

  d.lens.k[0] = 1.0;  // strong pincushion: monotone, valid
  EXPECT_EQ(ConfigureError(d), "");

  d.lens = TypicalBrown(640, 480);
  d.lens.fx = 0.5;
  EXPECT_NE(ConfigureError(d).find("distortion.fx"), std::string::npos);
  d.lens.fx = NAN;
  EXPECT_NE(ConfigureError(d).find("distortion.fx"), std::string::npos);
  d.lens = TypicalBrown(640, 480);
  d.lens.k[1] = INFINITY;
  EXPECT_NE(ConfigureError(d).find("distortion.k2"), std::string::npos);
  d.lens = TypicalBrown(640, 480);
  d.grid_step = 12;
  EXPECT_NE(ConfigureError(d).find("distortion.grid_step"), std::string::npos);
  d.grid_step = 16;
  d.phases = 100;
  EXPECT_NE(ConfigureError(d).find("distortion.phases"), std::string::npos);
  d.phases = 64;
  d.chromatic_scale[1] = 3.0;
  EXPECT_NE(ConfigureError(d).find("distortion.chromatic_scale"), std::string::npos);

  // Tiny focal length (1 px): almost every source is far off the image, and
  // the fisheye's points beyond 90 degrees have none: those pixels are
  // filled with 0, nothing crashes. Huge focal length: nearly the identity.
  const int w = 64, h = 48;
  const test::Scene scene = test::FlatScene(w, h, 1.0, 1.0, 1.0);
  for (double focal : {1.0, 1e6}) {
    for (DistortionModel model : {DistortionModel::kBrown, DistortionModel::kFisheye}) {
      DistortionConfig e;
      e.lens = model == DistortionModel::kBrown ? TypicalBrown(w, h) : FisheyeLens(w, h);
      e.lens.fx = e.lens.fy = focal;
      auto b = test::Build(DistortionOnly(w, h, e));
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      const std::vector<uint32_t> out = test::RunFrame(*b, scene, 0, 5);
      size_t ones = 0;
      for (uint32_t v : out) {
        ASSERT_TRUE(v == 0 || v == 65536u) << v;
        ones += v != 0;
      }
      if (focal > 1.0) {
        EXPECT_EQ(ones, out.size());  // nothing moves by more than ~1e-3 px
      }
      if (focal == 1.0 && model == DistortionModel::kFisheye) {
        EXPECT_LT(ones, out.size() / 4);
      }
    }
  }
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// What distortion adds to the workspace at 1920x1080 for the typical lens:
// its table and a row of scratch, and no line ring when it runs first (it
// reads the caller's rows); after exposure it needs a ring as deep as its
// widest row window, 3 channels.
TEST(Distortion, WorkspaceAt1080p) {
  const int w = 1920, h = 1080;
  PipelineConfig plain = test::DemoConfig(w, h);
  PipelineConfig lens = plain;
  lens.distortion.lens = TypicalBrown(w, h);
  Pipeline a, b;
  ASSERT_TRUE(a.Configure(plain, 1, false).ok());
  ASSERT_TRUE(b.Configure(lens, 1, false).ok());
  DistortionStage s;
  SensorGeometry g = lens.geometry;
  ASSERT_TRUE(s.Configure(lens.distortion, g).ok());
  WorkspaceCounter tables;
  s.CountTables(tables);
  std::printf("1080p typical lens: table %zu bytes (grid step %d), widest row window %d rows; workspace %zu -> %zu "
              "bytes (distortion first)\n",
              s.TableBytes(), lens.distortion.grid_step, s.MaxWindowRows(), a.WorkspaceBytes(), b.WorkspaceBytes());
  EXPECT_EQ(b.TableBytes() - a.TableBytes(), tables.raw_bytes());
  // Per worker: no ring for its input; one row (3 channels, with margins)
  // between it and exposure, and its scratch row of interpolated nodes.
  std::printf("  per worker %zu -> %zu bytes\n", a.WorkerBytes(), b.WorkerBytes());
  // (Measured: 27200 bytes, about one 3-channel row; a ring of the window would be 90 rows.)
  const size_t window_ring = static_cast<size_t>(s.MaxWindowRows()) * 3 * w * sizeof(uint32_t);
  EXPECT_LT(b.WorkerBytes() - a.WorkerBytes(), window_ring / 50);

  // After exposure: a ring of the window's span, 3 channels of uint32.
  PipelineConfig late = lens;  // the default order with distortion moved after exposure
  int k = 0;
  for (int i = 0; i < lens.order_count; ++i) {
    if (lens.order[i] == StageId::kDistortion) continue;
    late.order[k++] = lens.order[i];
    if (lens.order[i] == StageId::kExposure) late.order[k++] = StageId::kDistortion;
  }
  Pipeline c;
  ASSERT_TRUE(c.Configure(late, 1, false).ok());
  const size_t ring = window_ring;
  std::printf("  distortion after exposure: workspace %zu bytes (ring of %d rows x 3 x %d x 4 B = %zu)\n",
              c.WorkspaceBytes(), s.MaxWindowRows(), w, ring);
  EXPECT_GE(c.WorkerBytes(), a.WorkerBytes() + ring - 3 * static_cast<size_t>(w) * 4 * 2);
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// A displacement mesh alone: a uniform shift moves the image by exactly that
// (to the table's Q.16 and the 1/64 px phase), a varying mesh matches the
// reference; with a lens model, the mesh adds to the model's source.
TEST(Distortion, DisplacementMesh) {
  const int w = 96, h = 72;
  const test::Scene scene = SmoothScene(w, h);
  std::vector<float> uniform(4 * 3 * 2);
  for (size_t i = 0; i < uniform.size(); i += 2) {
    uniform[i] = 3.0f;    // dx: sources 3 px to the right
    uniform[i + 1] = -2.0f;  // dy: 2 px up
  }
  DistortionConfig d;
  d.mesh = {uniform.data(), 4, 3, 40.0};
  d.filter = ResampleFilter::kBicubic;
  auto b = test::Build(DistortionOnly(w, h, d));
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const std::vector<uint32_t> out = test::RunFrame(*b, scene, 0, 7);
  for (int y = 2; y < h; ++y)
    for (int x = 0; x + 3 < w; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(out[(static_cast<size_t>(y) * w + x) * 3 + c], scene.plane[c][static_cast<size_t>(y - 2) * w + x + 3])
            << x << "," << y;

  // A varying mesh (a shear and a bulge), with a lens model: fixed point
  // against the reference's exact source.
  std::vector<float> mesh;
  const int cols = 5, rows = 4;
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) {
      mesh.push_back(static_cast<float>(0.5 * j - 0.3 * i));
      mesh.push_back(static_cast<float>(1.5 * std::sin(i * 0.9) * std::cos(j * 0.7)));
    }
  DistortionConfig e;
  e.lens = TypicalBrown(w, h);
  e.mesh = {mesh.data(), cols, rows, 24.0};
  e.grid_step = 4;
  StandaloneStage s(e, w, h);
  DistortionConfig model_only = e;
  model_only.mesh = DisplacementMesh();
  ReferenceDistortion ref(model_only, SensorGeometry{w, h, Cfa::kBayerRG, 12});
  ReferenceDistortion ref_mesh(e, SensorGeometry{w, h, Cfa::kBayerRG, 12});
  double worst = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int64_t fx = 0, fy = 0;
      double rx = 0.0, ry = 0.0, lx = 0.0, ly = 0.0;
      ASSERT_TRUE(s.stage.SourcePosition(x, y, 1, &fx, &fy));
      ASSERT_TRUE(ref.Source(x, y, 1, &lx, &ly));  // the model alone
      // Mesh by hand: bilinear between nodes at multiples of 24 px.
      const double gx = std::min(x / 24.0, cols - 1.0), gy = std::min(y / 24.0, rows - 1.0);
      const int i = std::min(static_cast<int>(gx), cols - 2), j = std::min(static_cast<int>(gy), rows - 2);
      const auto at = [&](int ii, int jj, int k) { return mesh[(static_cast<size_t>(jj) * cols + ii) * 2 + k]; };
      for (int k = 0; k < 2; ++k) {
        const double top = at(i, j, k) + (at(i + 1, j, k) - at(i, j, k)) * (gx - i);
        const double bot = at(i, j + 1, k) + (at(i + 1, j + 1, k) - at(i, j + 1, k)) * (gx - i);
        (k == 0 ? rx : ry) = (k == 0 ? lx : ly) + top + (bot - top) * (gy - j);
      }
      worst = std::max(worst, std::hypot(fx / 65536.0 - rx, fy / 65536.0 - ry));
      double mx = 0.0, my = 0.0;
      ASSERT_TRUE(ref_mesh.Source(x, y, 1, &mx, &my));
      ASSERT_NEAR(mx, rx, 1e-9);  // the reference's mesh is the same bilinear mesh
      ASSERT_NEAR(my, ry, 1e-9);
    }
  // The step-4 table of this strong lens at 96x72 (its error scales as 1/size:
  // 0.011 px at 640x480, TableErrorAgainstExactInverse).
  EXPECT_LT(worst, 0.1);

  // Bad meshes name the key.
  std::vector<float> nan_mesh(8, 0.0f);
  nan_mesh[3] = NAN;
  DistortionConfig f;
  f.mesh = {nan_mesh.data(), 2, 2, 10.0};
  EXPECT_NE(ConfigureError(f).find("distortion.mesh"), std::string::npos);
  f.mesh = {uniform.data(), 1, 3, 10.0};
  EXPECT_NE(ConfigureError(f).find("distortion.mesh"), std::string::npos);
}

}  // namespace
}  // namespace camsim

#include "core/pipeline/pipeline_ref.h"

namespace camsim {
namespace {

// The whole-pipeline reference (camsim tradeoff) runs the distortion
// reference, as a mosaic of the sites' colours when a Bayer CFA follows.
TEST(Distortion, PipelineReferenceRunsTheStage) {
  const int w = 80, h = 60;
  const test::Scene scene = SmoothScene(w, h);
  PipelineConfig c;
  c.geometry.width = w;
  c.geometry.height = h;
  c.distortion.lens = TypicalBrown(w, h);
  c.distortion.grid_step = 4;
  c.order[0] = StageId::kDistortion;
  c.order[1] = StageId::kExposure;
  c.order[2] = StageId::kCfa;
  c.order_count = 3;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const FrameInput in = scene.View();
  const ref::RefImage r = ref::RunStageReference(b->pipeline, 0, ref::SceneRadiance(in, w, h), in);
  ASSERT_EQ(r.planes.size(), 1u);
  // The stage's own output (its tap), the mosaic.
  std::vector<uint32_t> out(static_cast<size_t>(w) * h);
  Tap tap;
  tap.stage = 0;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = w;
  b->pipeline.ProcessFrame(in, 0, 16, &tap, 1, nullptr, nullptr);
  // The reference of the site's colour, from the full-colour reference.
  c.order_count = 1;
  auto rgb = test::Build(c);
  ASSERT_TRUE(rgb->status.ok());
  const ref::RefImage all = ref::RunStageReference(rgb->pipeline, 0, ref::SceneRadiance(in, w, h), in);
  ASSERT_EQ(all.planes.size(), 3u);
  double worst = 0.0;
  int compared = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      const double v = out[i] / 65536.0;
      const double e = r.planes[0][i];
      ASSERT_EQ(e, all.planes[static_cast<size_t>(CfaColour(Cfa::kBayerRG, x, y))][i]) << x << "," << y;
      if (v != 0.0 && e != 0.0) {
        worst = std::max(worst, std::fabs(v - e));
        ++compared;
      }
    }
  EXPECT_GT(compared, w * h / 2);
  EXPECT_LT(worst, 0.03);  // radiance units; slope <= 0.18 / px times the table and phase error at this size
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// Extreme samples: a saturated flat field stays saturated, and a
// checkerboard of 0 and 2^32 - 1 stays within [0, 2^32 - 1] with no wrap
// (the 64-bit sums have headroom; the ringing clamp holds the range).
TEST(Distortion, ExtremeSamplesNeitherWrapNorRing) {
  const int w = 64, h = 48;
  test::Scene s;
  s.width = w;
  s.height = h;
  for (int c = 0; c < 3; ++c) s.plane[c].assign(static_cast<size_t>(w) * h, 0xFFFFFFFFu);
  for (ResampleFilter f : {ResampleFilter::kBilinear, ResampleFilter::kBicubic, ResampleFilter::kLanczos3, ResampleFilter::kLanczos4})
  for (bool clamp : {true, false}) {  // without the clamp, saturation holds the range
    DistortionConfig d;
    d.lens = TypicalBrown(w, h);
    d.ringing_clamp = clamp;
    d.filter = f;
    d.grid_step = 4;
    auto b = test::Build(DistortionOnly(w, h, d));
    ASSERT_TRUE(b->status.ok());
    for (uint32_t v : test::RunFrame(*b, s, 0, 8)) ASSERT_TRUE(v == 0xFFFFFFFFu || v == 0u) << v;
    test::Scene checker = s;
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) checker.plane[c][static_cast<size_t>(y) * w + x] = ((x + y) & 1) ? 0xFFFFFFFFu : 0u;
    const std::vector<uint32_t> out = test::RunFrame(*b, checker, 0, 8);
    uint64_t sum = 0;
    for (uint32_t v : out) sum += v;
    // Half of full scale on average (fills aside): the sampled values are
    // convex mixtures and clamps of 0 and 2^32 - 1, never wrapped.
    EXPECT_GT(sum / out.size(), 0x40000000u);
  }
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// Runs the stage directly on planes (w x h, 3 channels): each output row gets
// the window of rows InputRows names, as the driver does. Returns R, G, B planes.
std::vector<uint32_t> RunStageDirect(const DistortionStage& s, const std::vector<uint32_t>& planes, int w, int h,
                                     bool general) {
  const_cast<DistortionStage&>(s).ForceGeneralPathForTest(general);
  std::vector<RowIn> rows(static_cast<size_t>(h));
  for (int y = 0; y < h; ++y)
    for (int c = 0; c < 3; ++c) rows[y].ch[c] = planes.data() + (static_cast<size_t>(c) * h + y) * w;
  std::vector<uint8_t> scratch(s.ScratchBytes(w));
  std::vector<uint32_t> out(static_cast<size_t>(w) * h * 3, 0xDEADBEEFu);
  for (int y = 0; y < h; ++y) {
    const RowWindow win = s.InputRows(y, h);
    RowArgs a;
    a.y = y;
    a.width = w;
    a.rows = rows.data() + win.first;
    a.first_row = win.first;
    a.row_count = win.last - win.first + 1;
    for (int c = 0; c < 3; ++c) a.out[c] = out.data() + (static_cast<size_t>(c) * h + y) * w;
    a.scratch = scratch.data();
    s.ProcessRow(a);
  }
  const_cast<DistortionStage&>(s).ForceGeneralPathForTest(false);
  return out;
}

// The 32-bit fast paths (ProcessRowFast, ProcessRowBilinear and its AVX2
// clone when the CPU has it) must give the general 64-bit path's bytes:
// random samples with runs of the extremes 0 and 2^32 - 1, every filter,
// full colour and CFA site only, grid steps 4..64, a width that is no
// multiple of the 64-pixel chunk, a barrel lens whose corners sample off the
// image (fill), displacement meshes and two fisheyes (one too strong for the
// fast paths' ranges).
TEST(Distortion, FastPathEqualsGeneralPath) {
  const int w = 203, h = 61;
  std::vector<uint32_t> planes(static_cast<size_t>(w) * h * 3);
  uint64_t state = 0x9E3779B97F4A7C15ull;
  for (size_t i = 0; i < planes.size(); ++i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    const uint32_t r = static_cast<uint32_t>(state >> 32);
    const int kind = static_cast<int>((i / 7) % 5);  // runs of each kind
    planes[i] = kind == 0 ? 0u : kind == 1 ? 0xFFFFFFFFu : kind == 2 ? (r & 1 ? 0xFFFFFFFFu : 0u) : r;
  }
  std::vector<float> mesh(2 * 5 * 4), steep(mesh.size());
  for (size_t i = 0; i < mesh.size(); ++i) mesh[i] = static_cast<float>(static_cast<int>(i % 7) - 3) * 1.37f;
  for (size_t i = 0; i < mesh.size(); ++i) steep[i] = 2.0f * mesh[i];
  int fast_cases = 0;
  for (int lens = 0; lens < 5; ++lens)
    for (ResampleFilter f : {ResampleFilter::kBilinear, ResampleFilter::kBicubic, ResampleFilter::kLanczos3, ResampleFilter::kLanczos4})
      for (int step : {4, 8, 64})
        for (bool site_only : {false, true}) {
          DistortionConfig d;
          d.lens = lens == 0 ? TypicalBrown(w, h) : lens == 1 ? FisheyeLens(w, h) : LensModel();
          if (lens == 1) d.lens.fx = d.lens.fy = 0.3 * w;  // a strong fisheye: black corners
          if (lens == 4) d.lens = FisheyeLens(w, h);         // a milder one: the fast paths
          if (lens == 2) d.mesh = DisplacementMesh{mesh.data(), 5, 4, 50.0};
          // Twice as steep: sixteen site-only lanes' first tap rows spread
          // over up to nine rows (AVX-512 takes up to six, the rest go by eight or alone).
          if (lens == 3) d.mesh = DisplacementMesh{steep.data(), 5, 4, 50.0};
          d.filter = f;
          d.grid_step = step;
          // With and without the ringing clamp (only saturation), each
          // filter both ways across the lenses.
          d.ringing_clamp = (lens + step / 4 + site_only) % 2 == 0;
          // Every phase count (the AVX-512 lanes' weight table has one
          // to eight 32-phase blocks) with every lens and filter.
          d.phases = 16 << ((lens + step) % 5);
          SensorGeometry g;
          g.width = w;
          g.height = h;
          g.cfa = Cfa::kBayerGR;
          DistortionStage s;
          ASSERT_TRUE(s.Configure(d, g).ok());
          s.SetSiteOnly(site_only);
          WorkspaceCounter counter;
          s.CountTables(counter);
          std::vector<uint8_t> tables(counter.bytes());
          Arena arena(Span<uint8_t>{tables.data(), tables.size()});
          ASSERT_TRUE(s.Init(arena).ok());
          // The strong fisheye's nodes near the half-sphere lie thousands of
          // pixels away: beyond the fast path's ranges, the general path runs.
          EXPECT_EQ(s.fast_path(), lens != 1) << lens << " " << step;
          fast_cases += s.fast_path();
          const std::vector<uint32_t> fast = RunStageDirect(s, planes, w, h, false);
          const std::vector<uint32_t> general = RunStageDirect(s, planes, w, h, true);
          size_t zeros = 0, differ = 0, first = 0;
          for (size_t i = 0; i < fast.size(); ++i) {
            zeros += fast[i] == 0;
            if (fast[i] != general[i] && differ++ == 0) first = i;
          }
          ASSERT_EQ(differ, 0u) << "lens " << lens << " filter " << static_cast<int>(f) << " step " << step
                                << " site only " << site_only << ": first at plane " << first / (size_t{w} * h)
                                << " pixel " << first % (size_t{w} * h) << ": " << fast[first] << " vs "
                                << general[first];
          EXPECT_LT(zeros, fast.size());  // not all fill
          // Site only, the stage writes the mosaic into the first plane, every
          // sample of it, and nothing else.
          const size_t plane = static_cast<size_t>(w) * h;
          const auto mosaic_end = fast.begin() + static_cast<ptrdiff_t>(plane);
          const size_t unwritten_first = static_cast<size_t>(std::count(fast.begin(), mosaic_end, 0xDEADBEEFu));
          const size_t unwritten_rest = static_cast<size_t>(std::count(mosaic_end, fast.end(), 0xDEADBEEFu));
          EXPECT_EQ(unwritten_first, 0u);
          EXPECT_EQ(unwritten_rest, site_only ? 2 * plane : 0u);
        }
  EXPECT_EQ(fast_cases, 96);
}

}  // namespace
}  // namespace camsim
