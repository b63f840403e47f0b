// Lens flare: the ghost of a point source lands at the mirrored position,
// glare conserves energy, the stage matches its double reference, a frame
// without bright pixels passes unchanged, and the stage is left out when off.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "core/lens/flare.h"
#include "core/lens/flare_ref.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

PipelineConfig FlareOnly(int w, int h, const FlareConfig& f) {
  PipelineConfig c;
  c.geometry = {w, h, Cfa::kBayerRG, 12};
  c.order[0] = StageId::kFlare;
  c.order_count = 1;
  c.flare = f;
  return c;
}

// Runs the flare stage with its pre-pass; radiance out (interleaved, Q16.16).
std::vector<uint32_t> RunFlare(const test::Built& b, const test::Scene& s, int strip_rows, int* sources = nullptr,
                               WorkerStats* stats = nullptr) {
  const PipelineConfig& c = b.pipeline.config();
  std::vector<FlareSource> storage(static_cast<size_t>(FlareMaxSources(c.geometry)));
  FlareFrame frame;
  FrameInput in = s.View();
  ComputeFlare(c.flare, c.geometry, in, Span<FlareSource>{storage.data(), storage.size()}, &frame);
  in.flare = &frame;
  if (sources) *sources = frame.count;
  EXPECT_TRUE(b.pipeline.CheckInput(in).ok());
  std::vector<uint32_t> out(static_cast<size_t>(s.width) * s.height * 3);
  Tap t;
  t.format = TapFormat::kU32;
  t.data = out.data();
  t.stride = s.width * 3;
  b.pipeline.ProcessFrame(in, 0, strip_rows, &t, 1, stats, nullptr);
  return out;
}

FlareConfig Bare() {
  FlareConfig f;
  f.enabled = true;
  f.glare_fraction = 0;
  f.haze = 0;
  f.ghost_count = 0;
  return f;
}

TEST(Flare, GhostLandsAtTheMirroredPosition) {
  constexpr int kW = 64, kH = 48;
  FlareConfig f = Bare();
  f.ghost_count = 1;
  f.ghost_scale[0] = -1.0;
  f.ghost_radius_px[0] = 3;
  f.ghost_intensity[0] = 0.01;
  f.ghost_tint[0] = f.ghost_tint[1] = f.ghost_tint[2] = 1.0;
  f.blades = 0;
  auto b = test::Build(FlareOnly(kW, kH, f));
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  test::Scene s = test::FlatScene(kW, kH, 0.1, 0.1, 0.1);
  for (int c = 0; c < 3; ++c) s.plane[c][8 * kW + 10] = Q<16, 16>::FromDouble(1000.0).raw;
  const auto out = RunFlare(*b, s, 5);
  double sum = 0, sx = 0, sy = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double d = (double(out[(y * kW + x) * 3 + 1]) - s.plane[1][y * kW + x]) / 65536.0;
      if (d == 0) continue;
      EXPECT_LE((x - 53) * (x - 53) + (y - 39) * (y - 39), 9) << x << "," << y;  // inside the ghost disc
      sum += d;
      sx += d * x;
      sy += d * y;
    }
  // (10, 8) mirrored through the centre of 64 x 48: (63 - 10, 47 - 8) = (53, 39).
  EXPECT_NEAR(sx / sum, 53.0, 1e-6);
  EXPECT_NEAR(sy / sum, 39.0, 1e-6);
  EXPECT_NEAR(sum, 0.01 * (1000.0 - 8.0), 1e-3);  // intensity times the excess over the threshold
}

TEST(Flare, GlareConservesEnergy) {
  constexpr int kW = 96, kH = 80;
  FlareConfig f = Bare();
  f.glare_fraction = 0.3;
  f.glare_radius = 20;
  f.blades = 5;  // odd: 10 spikes
  auto b = test::Build(FlareOnly(kW, kH, f));
  ASSERT_TRUE(b->status.ok());
  test::Scene s = test::FlatScene(kW, kH, 0.5, 0.5, 0.5);
  for (int y = 38; y < 42; ++y)
    for (int x = 46; x < 50; ++x)
      for (int c = 0; c < 3; ++c) s.plane[c][y * kW + x] = Q<16, 16>::FromDouble(500.0 + 10 * c).raw;
  const auto out = RunFlare(*b, s, 9);
  for (int c = 0; c < 3; ++c) {
    int64_t in_sum = 0, out_sum = 0;
    for (int i = 0; i < kW * kH; ++i) {
      in_sum += s.plane[c][i];
      out_sum += out[i * 3 + c];
    }
    // Each of the (2R+1)^2 kernel terms rounds by at most half a Q16.16 unit.
    EXPECT_LE(std::abs(out_sum - in_sum), 41 * 41 / 2 + 1) << c;
  }
  // The light moved: the source lost 30 % of its excess, the neighbourhood gained.
  EXPECT_LT(out[(40 * kW + 47) * 3], s.plane[0][40 * kW + 47]);
  EXPECT_GT(out[(40 * kW + 60) * 3], s.plane[0][40 * kW + 60]);
}

TEST(Flare, MatchesTheDoubleReference) {
  constexpr int kW = 120, kH = 90;
  FlareConfig f;
  f.enabled = true;
  f.ghost_count = 3;
  auto b = test::Build(FlareOnly(kW, kH, f));
  ASSERT_TRUE(b->status.ok());
  test::Scene s = test::TexturedScene(kW, kH);  // has a bright spot
  for (int c = 0; c < 3; ++c) {
    s.plane[c][10 * kW + 100] = Q<16, 16>::FromDouble(3000.0).raw;
    s.plane[c][70 * kW + 15] = Q<16, 16>::FromDouble(800.0 + 100 * c).raw;
  }
  int sources = 0;
  const auto out = RunFlare(*b, s, 16, &sources);
  EXPECT_GE(sources, 2);
  EXPECT_EQ(RunFlare(*b, s, 1), out);  // any strip height
  ref::RefImage in;
  in.width = kW;
  in.height = kH;
  in.planes.assign(3, std::vector<double>(kW * kH));
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < kW * kH; ++i) in.planes[c][i] = s.plane[c][i] / 65536.0;
  const ref::RefImage r = ref::RefFlare(f, b->pipeline.config().geometry, in);
  // Q16.16 output, ~40 rounded spreads per pixel (< 1e-3 together), and the
  // glare fraction quantised to Q0.16 (its error, <= 2^-17, times the excess).
  double max_err = 0, mean_err = 0;
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < kW * kH; ++i) {
      const double err = std::abs(out[i * 3 + c] / 65536.0 - r.planes[c][i]);
      EXPECT_LE(err, 1e-3 + in.planes[c][i] / 131072.0) << "channel " << c << " pixel " << i;
      max_err = std::max(max_err, err);
      mean_err += err / (3.0 * kW * kH);
    }
  // The rounding errors are unbiased: their mean is far below the per-pixel
  // bound, so an error that touches every pixel (the haze's level, say: about
  // 1.6e-3 per pixel here) shows even where it stays under that bound.
  std::printf("flare vs reference: max %.3g, mean %.3g\n", max_err, mean_err);
  EXPECT_LE(mean_err, 1e-4);
  RecordProperty("max_abs_error", std::to_string(max_err));
}

// The pre-pass finds a tile with one sample above the threshold wherever
// it is: its tile peaks go 64 tiles (1024 columns) at a time, the last tile
// of a row and the last tile row may be partial. One bright sample per
// tile gives a source at that sample, in tile order.
TEST(Flare, ThePrePassFindsEveryBrightTile) {
  constexpr int kW = 1100, kH = 40;  // 69 tile columns (the last 12 wide), 3 tile rows (the last 8 high)
  FlareConfig f = Bare();
  f.threshold = 2.0;
  const PipelineConfig c = FlareOnly(kW, kH, f);
  test::Scene s = test::FlatScene(kW, kH, 1.0, 1.0, 1.0);  // below the threshold
  const int bright[][3] = {{0, 0, 0}, {1023, 5, 1}, {1024, 20, 2}, {1099, 39, 0}, {700, 33, 1}};
  const uint32_t v = Q<16, 16>::FromDouble(5.0).raw, threshold = Q<16, 16>::FromDouble(2.0).raw;
  for (const auto& b : bright) s.plane[b[2]][static_cast<size_t>(b[1]) * kW + b[0]] = v;
  std::vector<FlareSource> storage(static_cast<size_t>(FlareMaxSources(c.geometry)));
  FlareFrame frame;
  ComputeFlare(c.flare, c.geometry, s.View(), Span<FlareSource>{storage.data(), storage.size()}, &frame);
  // In tile order: tile row 0 (x 0, 1023), tile row 1 (x 1024), tile row 2 (x 700, 1099).
  const int order[] = {0, 1, 2, 4, 3};
  ASSERT_EQ(frame.count, 5);
  for (int i = 0; i < 5; ++i) {
    const auto& b = bright[order[i]];
    SCOPED_TRACE(i);
    EXPECT_EQ(frame.sources[i].x, b[0]);
    EXPECT_EQ(frame.sources[i].y, b[1]);
    for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(frame.sources[i].excess[ch], ch == b[2] ? v - threshold : 0u);
  }
}

// The pixels of tiles without a bright pixel are counted as skipped (`camsim
// run` reports them): whole tiles, a partial last tile column and row.
TEST(Flare, CountsThePixelsOfTilesWithoutABrightPixel) {
  constexpr int kW = 1100, kH = 40;  // the last tile column 12 wide, the last tile row 8 high
  FlareConfig f;
  f.enabled = true;
  f.threshold = 2.0;
  auto b = test::Build(FlareOnly(kW, kH, f));
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  test::Scene s = test::FlatScene(kW, kH, 1.0, 1.0, 1.0);
  // Bright pixels in five tiles; two in one tile count it once.
  const int bright[][2] = {{0, 0}, {5, 9}, {1023, 5}, {1024, 20}, {1099, 39}, {700, 33}};
  for (const auto& p : bright) s.plane[1][static_cast<size_t>(p[1]) * kW + p[0]] = Q<16, 16>::FromDouble(5.0).raw;
  const int64_t tiles = 16 * 16 + 16 * 16 + 16 * 16 + 12 * 8 + 16 * 8;
  for (const int strip : {7, 40}) {
    WorkerStats stats;
    int sources = 0;
    RunFlare(*b, s, strip, &sources, &stats);
    EXPECT_EQ(sources, 5);
    EXPECT_EQ(stats.stage[0].skipped_px, int64_t{kW} * kH - tiles) << "strip " << strip;
  }
  WorkerStats none;
  RunFlare(*b, test::FlatScene(kW, kH, 1.0, 1.0, 1.0), 8, nullptr, &none);
  EXPECT_EQ(none.stage[0].skipped_px, int64_t{kW} * kH) << "no bright pixel: every pixel";
}

// ProcessRow visits only the sources whose glare or ghosts can reach the
// row (by tile row); visiting every source gives the same bytes. Scenes
// bright in many tiles, ghosts at every kind of scale (mirrored, zero,
// beyond the frame, barely moving), radii at their limits, odd sizes.
TEST(Flare, SourcesFoundByTileRowGiveTheBytesOfVisitingEverySource) {
  struct Case {
    int w, h, glare_radius, ghosts;
    double scale[kMaxGhosts], radius[kMaxGhosts];
  };
  const Case cases[] = {
      {64, 48, 16, 2, {-1.0, -0.5}, {24.0, 10.0}},
      {67, 53, 1, 4, {0.0, 4.0, -4.0, 0.01}, {1.0, 64.0, 64.0, 3.0}},
      {33, 131, 32, 3, {-1.5, 0.5, 2.0}, {40.0, 6.0, 1.0}},
      {131, 17, 7, 4, {1.0, -0.01, -3.0, 0.3}, {5.0, 64.0, 20.0, 2.0}},
  };
  for (const Case& k : cases) {
    FlareConfig f;
    f.enabled = true;
    f.threshold = 2.0;
    f.glare_radius = k.glare_radius;
    f.ghost_count = k.ghosts;
    for (int g = 0; g < k.ghosts; ++g) {
      f.ghost_scale[g] = k.scale[g];
      f.ghost_radius_px[g] = k.radius[g];
      f.ghost_intensity[g] = 0.05;
    }
    auto b = test::Build(FlareOnly(k.w, k.h, f));
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    test::Scene s = test::FlatScene(k.w, k.h, 0.5, 0.5, 0.5);
    for (int y = 0; y < k.h; ++y)  // a bright pixel in most tiles, some saturating
      for (int x = 0; x < k.w; ++x)
        if ((x * 7 + y * 13) % 23 == 0)
          for (int c = 0; c < 3; ++c)
            s.plane[c][static_cast<size_t>(y) * k.w + x] = (x + y) % 5 == 0 ? 0xFFFFFFFFu : (50u + x + c) << 16;
    auto& stage = const_cast<FlareStage&>(b->pipeline.flare_stage());
    int sources = 0;
    stage.ForceEverySourceForTest(true);
    const std::vector<uint32_t> every = RunFlare(*b, s, 7, &sources);
    stage.ForceEverySourceForTest(false);
    EXPECT_GT(sources, k.w * k.h / 256 / 2) << k.w << "x" << k.h;
    EXPECT_EQ(RunFlare(*b, s, 7), every) << k.w << "x" << k.h;
  }
}

TEST(Flare, NoBrightPixelPassesTheFrameUnchanged) {
  FlareConfig f;
  f.enabled = true;
  auto b = test::Build(FlareOnly(40, 30, f));
  ASSERT_TRUE(b->status.ok());
  const test::Scene s = test::FlatScene(40, 30, 7.9, 2.0, 0.5);  // all below the threshold 8
  int sources = -1;
  const auto out = RunFlare(*b, s, 8, &sources);
  EXPECT_EQ(sources, 0);
  for (int i = 0; i < 40 * 30; ++i)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(out[i * 3 + c], s.plane[c][i]);
}

TEST(Flare, LeftOutWhenOffAndNeedsItsPrePass) {
  auto off = test::Build(FlareOnly(16, 16, FlareConfig{}));
  EXPECT_FALSE(off->status.ok());  // the only listed stage was left out
  PipelineConfig c = FlareOnly(16, 16, FlareConfig{});
  c.order[1] = StageId::kExposure;
  c.order_count = 2;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  EXPECT_FALSE(b->pipeline.plan().entries[0].runs);
  FlareConfig on;
  on.enabled = true;
  auto needs = test::Build(FlareOnly(16, 16, on));
  ASSERT_TRUE(needs->status.ok());
  const test::Scene s = test::FlatScene(16, 16, 1, 1, 1);
  EXPECT_EQ(std::string(needs->pipeline.CheckInput(s.View()).field()), "flare.enabled");
}

// The pre-pass reads the frame input, so a stage that changes the image
// before flare would leave the two looking at different images.
TEST(Flare, RunsFirstOrNotAtAll) {
  FlareConfig on;
  on.enabled = true;
  PipelineConfig c;
  c.geometry = {16, 16, Cfa::kBayerRG, 12};
  c.flare = on;
  c.distortion.lens.model = DistortionModel::kBrown;
  c.distortion.lens.fx = c.distortion.lens.fy = 16;
  c.distortion.lens.cx = c.distortion.lens.cy = 7.5;
  c.distortion.lens.k[0] = 0.1;
  // Distortion keeps radiance, so only the order check refuses flare after it.
  PipelineConfig late = c;
  late.order[0] = StageId::kDistortion;
  late.order[1] = StageId::kFlare;
  late.order_count = 2;
  auto refused = test::Build(late);
  ASSERT_FALSE(refused->status.ok());
  EXPECT_EQ(std::string(refused->status.field()), "pipeline.stages") << refused->status.message();
  // The default order runs it first, with the lens stage on too.
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  EXPECT_EQ(b->pipeline.plan().entries[0].id, StageId::kFlare);
  EXPECT_TRUE(b->pipeline.plan().entries[0].runs);
}

}  // namespace
}  // namespace camsim
