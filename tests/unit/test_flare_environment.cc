// Lens flare from an environment map (core/lens/flare_environment.h): a bright
// texel just outside the field of view puts its ghosts at the mirrored
// positions and its glare into the frame; behind the camera it only adds haze;
// inside the frame it is skipped; the camera orientation moves it; the source
// cap keeps the strongest; the stage matches its double reference for any
// strip height and worker; configuration and loader errors name key and file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <limits>

#include "core/lens/flare.h"
#include "core/lens/flare_environment_ref.h"
#include "core/lens/flare_ref.h"
#include "host_tools/io/environment_map.h"
#include "host_tools/io/image_write.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
constexpr int kW = 64, kH = 48;
constexpr double kF = 40.0;  // fx = fy, pixels: a half field of 38.7 x 31.0 degrees
// A 1-degree map: texel (i, j) looks along longitude i + 0.5 - 180 and
// latitude 90 - (j + 0.5) degrees.
constexpr int kMapW = 360, kMapH = 180;

struct Map {
  std::vector<float> rgb = std::vector<float>(static_cast<size_t>(kMapW) * kMapH * 3, 0.0f);
  void Set(int i, int j, double r, double g, double b) {
    float* t = &rgb[(static_cast<size_t>(j) * kMapW + i) * 3];
    t[0] = static_cast<float>(r);
    t[1] = static_cast<float>(g);
    t[2] = static_cast<float>(b);
  }
};

// The solid angle of a texel in row j, steradians, and its excess in
// radiance x on-axis pixels (flare_environment.h).
double TexelOmega(int j) {
  return 2 * kPi / kMapW * (std::sin((90.0 - j) * kDeg) - std::sin((90.0 - j - 1) * kDeg));
}
double TexelExcess(double radiance, int j, double threshold = 8.0) {
  return (radiance - threshold) * TexelOmega(j) * kF * kF;
}

FlareConfig Bare(const Map& m) {
  FlareConfig f;
  f.enabled = true;
  f.glare_fraction = 0;
  f.haze = 0;
  f.ghost_count = 0;
  f.blades = 0;
  FlareEnvironment& e = f.environment;
  e.texels = m.rgb.data();
  e.width = kMapW;
  e.height = kMapH;
  e.fx = e.fy = kF;
  e.cx = (kW - 1) / 2.0;
  e.cy = (kH - 1) / 2.0;
  return f;
}

PipelineConfig FlareOnly(const FlareConfig& f, int w = kW, int h = kH) {
  PipelineConfig c;
  c.geometry = {w, h, Cfa::kBayerRG, 12};
  c.order[0] = StageId::kFlare;
  c.order_count = 1;
  c.flare = f;
  return c;
}

// Runs the flare stage (with its frame pre-pass) in strips; with `alternate`
// strip k goes to worker k % workers. Radiance out, interleaved Q16.16.
std::vector<uint32_t> RunFlare(const test::Built& b, const test::Scene& s, int strip_rows, int workers = 1) {
  const PipelineConfig& c = b.pipeline.config();
  std::vector<FlareSource> storage(static_cast<size_t>(FlareMaxSources(c.geometry)));
  FlareFrame frame;
  FrameInput in = s.View();
  ComputeFlare(c.flare, c.geometry, in, Span<FlareSource>{storage.data(), storage.size()}, &frame);
  in.flare = &frame;
  EXPECT_TRUE(b.pipeline.CheckInput(in).ok());
  std::vector<uint32_t> out(static_cast<size_t>(s.width) * s.height * 3);
  Tap t;
  t.format = TapFormat::kU32;
  t.data = out.data();
  t.stride = s.width * 3;
  int k = 0;
  for (int y = 0; y < s.height; y += strip_rows, ++k)
    b.pipeline.ProcessStrip(in, 0, y, y + strip_rows, k % workers, &t, 1, nullptr, nullptr);
  return out;
}

const FlareEnvironmentSummary& Summary(const test::Built& b) {
  return b.pipeline.flare_stage().environment_summary();
}

int GhostCentre(int pos, double scale, int size) {
  const double c = (size - 1) / 2.0;
  return static_cast<int>(std::floor(c + scale * (pos - c) + 0.5));
}

int DiscArea(int r) {
  int n = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) n += dx * dx + dy * dy <= r * r;
  return n;
}

constexpr double kQ = 65536.0;

// A texel at longitude 40.5, latitude 0.5 (just right of the frame) puts a
// source at the analytic position; its ghost with scale -1 is centred at the
// mirrored position (off the left edge: the part of the disc inside the frame
// is lit) and its scale -0.5 ghost lands inside; nothing else changes.
TEST(FlareEnvironment, GhostsOfAnOffFrameSourceLandAtTheMirroredPositions) {
  Map m;
  m.Set(220, 89, 1000, 1000, 1000);
  FlareConfig f = Bare(m);
  f.ghost_count = 2;
  f.ghost_scale[0] = -1.0;
  f.ghost_radius_px[0] = 6;
  f.ghost_scale[1] = -0.5;
  f.ghost_radius_px[1] = 3;
  for (int g = 0; g < 2; ++g) {
    f.ghost_intensity[g] = 0.01;
    for (int c = 0; c < 3; ++c) f.ghost_tint[3 * g + c] = 1.0;
  }
  auto b = test::Build(FlareOnly(f));
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  // Analytic projection of the texel's centre.
  const double lambda = 40.5 * kDeg, phi = 0.5 * kDeg;
  const double u = (kW - 1) / 2.0 + kF * std::tan(lambda);
  const double v = (kH - 1) / 2.0 - kF * std::tan(phi) / std::cos(lambda);
  const int sx = static_cast<int>(std::floor(u + 0.5)), sy = static_cast<int>(std::floor(v + 0.5));
  ASSERT_EQ(sx, 66);  // outside the 64-pixel-wide frame
  ASSERT_EQ(sy, 23);
  ASSERT_EQ(Summary(*b).sources, 1);
  EXPECT_EQ(Summary(*b).bright_texels, 1);
  EXPECT_EQ(Summary(*b).in_frame, 0);
  EXPECT_EQ(Summary(*b).haze_only, 0);
  const FlareSource& src = b->pipeline.flare_stage().environment_sources()[0];
  EXPECT_EQ(src.x, sx);
  EXPECT_EQ(src.y, sy);
  const double excess = TexelExcess(1000, 89);
  EXPECT_NEAR(src.excess[1] / kQ, excess, 1.0 / kQ);

  // A frame without bright pixels: only the environment's ghosts add light.
  const test::Scene s = test::FlatScene(kW, kH, 1.0, 1.0, 1.0);
  const auto out = RunFlare(*b, s, 7);
  const int g0x = GhostCentre(sx, -1.0, kW), g0y = GhostCentre(sy, -1.0, kH);
  const int g1x = GhostCentre(sx, -0.5, kW), g1y = GhostCentre(sy, -0.5, kH);
  EXPECT_EQ(g0x, kW - 1 - sx);  // the mirror through the centre: -3
  EXPECT_EQ(g0y, kH - 1 - sy);  // 24
  EXPECT_EQ(g1x, 14);
  EXPECT_EQ(g1y, 24);
  const double v0 = 0.01 * excess / DiscArea(6), v1 = 0.01 * excess / DiscArea(3);
  int lit0 = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const bool in0 = (x - g0x) * (x - g0x) + (y - g0y) * (y - g0y) <= 36;
      const bool in1 = (x - g1x) * (x - g1x) + (y - g1y) * (y - g1y) <= 9;
      lit0 += in0;
      const double expected = 1.0 + (in0 ? v0 : 0.0) + (in1 ? v1 : 0.0);
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(out[(static_cast<size_t>(y) * kW + x) * 3 + c] / kQ, expected, 2.0 / kQ) << x << "," << y;
    }
  EXPECT_EQ(lit0, 11 + 9 + 7 + 1);  // columns 0..3 (dx = 3..6) of the radius-6 disc at x = -3
}

// The same texel's glare reaches the frame's right edge (3 pixels from the
// source) but not beyond the glare radius; the light it adds equals the
// double reference's.
TEST(FlareEnvironment, GlareOfAnOffFrameSourceReachesTheEdge) {
  Map m;
  m.Set(220, 89, 1000, 1000, 1000);
  FlareConfig f = Bare(m);
  f.glare_fraction = 0.1;
  auto b = test::Build(FlareOnly(f));
  ASSERT_TRUE(b->status.ok());
  const test::Scene s = test::FlatScene(kW, kH, 1.0, 1.0, 1.0);
  const auto out = RunFlare(*b, s, 48);
  const auto at = [&](int x, int y) { return out[(static_cast<size_t>(y) * kW + x) * 3 + 1] / kQ; };
  EXPECT_GT(at(63, 23), 1.2);            // 3 pixels from the source at (66, 23)
  EXPECT_EQ(at(66 - 17, 23), 1.0);       // beyond the 16-pixel radius
  EXPECT_EQ(at(63, 23 - 17), 1.0);
  ref::RefImage in;
  in.width = kW;
  in.height = kH;
  in.planes.assign(3, std::vector<double>(kW * kH, 1.0));
  const ref::RefImage r = ref::RefFlare(f, b->pipeline.config().geometry, in);
  double got = 0, want = 0;
  for (int i = 0; i < kW * kH; ++i) {
    got += out[static_cast<size_t>(i) * 3 + 1] / kQ - 1.0;
    want += r.planes[1][i] - 1.0;
  }
  EXPECT_GT(want, 0.1 * TexelExcess(1000, 89) * 0.2);  // a good part of the glare lands in the frame
  EXPECT_NEAR(got, want, 1e-3 * want);
  EXPECT_NEAR(at(63, 23), r.planes[1][23 * kW + 63], 1e-4);
}

// Glare is on when its Q0.16 share is not 0, for the frame's pixels and for
// the environment's sources alike; the reference keeps the same sources.
TEST(FlareEnvironment, AGlareFractionBelowItsQ016StepIsOffInStageAndReference) {
  Map m;
  m.Set(220, 89, 1000, 1000, 1000);
  for (double fraction : {5e-6, 7e-6, 1e-5}) {  // 2^-17 = 7.63e-6 rounds to 1/65536
    FlareConfig f = Bare(m);
    f.glare_fraction = fraction;
    auto b = test::Build(FlareOnly(f));
    ASSERT_TRUE(b->status.ok());
    const int want = fraction > 7.63e-6 ? 1 : 0;
    EXPECT_EQ(Summary(*b).sources, want) << fraction;
    EXPECT_EQ(static_cast<int>(ref::RefFlareEnvironment(f, b->pipeline.config().geometry).sources.size()), want)
        << fraction;
  }
}

// A texel behind the camera adds only haze: flare.haze x excess / pixels on
// every pixel, no glare, no ghost.
TEST(FlareEnvironment, BehindTheCameraOnlyHaze) {
  Map m;
  m.Set(0, 89, 1000, 500, 200);  // longitude -179.5
  FlareConfig f = Bare(m);
  f.haze = 0.01;
  f.glare_fraction = 0.05;
  f.ghost_count = 2;
  auto b = test::Build(FlareOnly(f));
  ASSERT_TRUE(b->status.ok());
  EXPECT_EQ(Summary(*b).sources, 0);
  EXPECT_EQ(Summary(*b).haze_only, 1);
  const test::Scene s = test::FlatScene(kW, kH, 1.0, 2.0, 3.0);
  const auto out = RunFlare(*b, s, 5);
  const double radiance[3] = {1000, 500, 200}, base[3] = {1.0, 2.0, 3.0};
  for (int c = 0; c < 3; ++c) {
    const double haze = 0.01 * TexelExcess(radiance[c], 89) / (kW * kH);
    ASSERT_GT(haze, 1e-4);  // > 6 Q16.16 steps
    for (int i = 0; i < kW * kH; ++i)
      ASSERT_NEAR(out[static_cast<size_t>(i) * 3 + c] / kQ, base[c] + haze, 1.0 / kQ) << c << " " << i;
  }
}

// A texel inside the field of view is the renderer's: skipped entirely.
TEST(FlareEnvironment, InsideTheFrameIsSkipped) {
  Map m;
  m.Set(180, 89, 5000, 5000, 5000);  // longitude 0.5, latitude 0.5: near the centre
  FlareConfig f = Bare(m);
  f.haze = 0.01;
  f.glare_fraction = 0.05;
  f.ghost_count = 2;
  auto b = test::Build(FlareOnly(f));
  ASSERT_TRUE(b->status.ok());
  EXPECT_EQ(Summary(*b).in_frame, 1);
  EXPECT_EQ(Summary(*b).sources, 0);
  EXPECT_EQ(Summary(*b).haze_only, 0);
  const test::Scene s = test::FlatScene(kW, kH, 1.0, 2.0, 3.0);
  const auto out = RunFlare(*b, s, 16);
  for (int i = 0; i < kW * kH; ++i)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(out[static_cast<size_t>(i) * 3 + c], s.plane[c][i]);
}

// Yaw 180 turns a texel from behind the camera to just right of the frame;
// pitch brings a texel above the frame into it; roll 90 (clockwise) moves a
// texel right of the frame above it.
TEST(FlareEnvironment, OrientationMovesSources) {
  Map m;
  m.Set(39, 89, 1000, 1000, 1000);  // longitude -140.5: behind
  FlareConfig f = Bare(m);
  f.glare_fraction = 0.05;
  auto ahead = test::Build(FlareOnly(f));
  ASSERT_TRUE(ahead->status.ok());
  EXPECT_EQ(Summary(*ahead).sources, 0);
  EXPECT_EQ(Summary(*ahead).haze_only, 1);
  for (const double yaw : {180.0, -180.0}) {
    f.environment.yaw_deg = yaw;
    auto turned = test::Build(FlareOnly(f));
    ASSERT_TRUE(turned->status.ok());
    ASSERT_EQ(Summary(*turned).sources, 1) << yaw;
    const FlareSource& s = turned->pipeline.flare_stage().environment_sources()[0];
    // Relative longitude 39.5: u = 31.5 + 40 tan(39.5) = 64.47.
    EXPECT_EQ(s.x, static_cast<int>(std::floor(31.5 + kF * std::tan(39.5 * kDeg) + 0.5))) << yaw;
    EXPECT_EQ(s.x, 64);
    EXPECT_EQ(s.y, 23);
  }

  Map up;
  up.Set(180, 49, 1000, 1000, 1000);  // longitude 0.5, latitude 40.5: above the frame
  FlareConfig p = Bare(up);
  p.glare_fraction = 0.05;
  p.ghost_count = 1;
  auto level = test::Build(FlareOnly(p));
  ASSERT_TRUE(level->status.ok());
  ASSERT_EQ(Summary(*level).sources, 1);
  EXPECT_EQ(level->pipeline.flare_stage().environment_sources()[0].y,
            static_cast<int>(std::floor(23.5 - kF * std::tan(40.5 * kDeg) / std::cos(0.5 * kDeg) + 0.5)));
  p.environment.pitch_deg = 40;
  auto tilted = test::Build(FlareOnly(p));
  ASSERT_TRUE(tilted->status.ok());
  EXPECT_EQ(Summary(*tilted).in_frame, 1);
  EXPECT_EQ(Summary(*tilted).sources, 0);

  Map right;
  right.Set(220, 89, 1000, 1000, 1000);  // longitude 40.5, latitude 0.5
  FlareConfig r = Bare(right);
  r.glare_fraction = 0.05;
  r.ghost_count = 1;
  r.environment.roll_deg = 90;
  auto rolled = test::Build(FlareOnly(r));
  ASSERT_TRUE(rolled->status.ok());
  ASSERT_EQ(Summary(*rolled).sources, 1);
  const FlareSource& s = rolled->pipeline.flare_stage().environment_sources()[0];
  // The picture turns anticlockwise: what was right is now up.
  EXPECT_EQ(s.x, static_cast<int>(std::floor(31.5 - kF * std::tan(0.5 * kDeg) / std::cos(40.5 * kDeg) + 0.5)));
  EXPECT_EQ(s.y, static_cast<int>(std::floor(23.5 - kF * std::tan(40.5 * kDeg) + 0.5)));
  EXPECT_EQ(s.y, -11);
}

// The cap keeps the strongest sources (the rest add haze only); equal
// strengths are ordered by position, whatever the scan order.
TEST(FlareEnvironment, CapKeepsTheStrongest) {
  Map m;
  const int rows[5] = {80, 85, 89, 93, 98};
  const double radiance[5] = {100, 500, 300, 200, 400};
  for (int k = 0; k < 5; ++k) m.Set(220, rows[k], radiance[k], radiance[k], radiance[k]);
  FlareConfig f = Bare(m);
  f.glare_fraction = 0.05;
  f.environment.max_sources = 2;
  auto b = test::Build(FlareOnly(f));
  ASSERT_TRUE(b->status.ok());
  const FlareEnvironmentSummary& sum = Summary(*b);
  ASSERT_EQ(sum.sources, 2);
  EXPECT_EQ(sum.bright_texels, 5);
  EXPECT_EQ(sum.haze_only, 3);
  const Span<const FlareSource> src = b->pipeline.flare_stage().environment_sources();
  EXPECT_NEAR(src[0].excess[0] / kQ, TexelExcess(500, 85), 1.0 / kQ);
  EXPECT_NEAR(src[1].excess[0] / kQ, TexelExcess(400, 98), 1.0 / kQ);
  double all = 0;
  for (int k = 0; k < 5; ++k) all += TexelExcess(radiance[k], rows[k]);
  EXPECT_NEAR(sum.haze_excess[0] / kQ, all, 5.0 / kQ);  // every texel outside the frame counts for the haze

  // Two equal texels mirrored left and right of the frame: with room for one,
  // the one with the smaller x is kept.
  Map tie;
  tie.Set(220, 89, 700, 700, 700);  // x = 66
  tie.Set(139, 89, 700, 700, 700);  // longitude -40.5: x = -3
  FlareConfig t = Bare(tie);
  t.glare_fraction = 0.05;
  t.environment.max_sources = 1;
  auto bt = test::Build(FlareOnly(t));
  ASSERT_TRUE(bt->status.ok());
  ASSERT_EQ(Summary(*bt).sources, 1);
  EXPECT_EQ(bt->pipeline.flare_stage().environment_sources()[0].x, -3);
  EXPECT_EQ(bt->pipeline.flare_stage().environment_sources()[0].y, 23);
}

// Sources far off the frame: positions up to the offset limit are safe (a
// scale-0 ghost from 35,000 pixels away lands at the centre), beyond it the
// texel adds haze only; sources whose glare and ghosts cannot reach the frame
// are not kept.
TEST(FlareEnvironment, FarOffFrameSourcesAreSafe) {
  Map m;
  m.Set(240, 89, 1000, 1000, 1000);  // longitude 60.5: u = 31.5 + 2e4 tan(60.5) ~ 35,000
  m.Set(269, 89, 1000, 1000, 1000);  // longitude 89.5: u ~ 2.3e6 > 2^20, haze only
  FlareConfig f = Bare(m);
  f.environment.fx = f.environment.fy = 2e4;
  f.ghost_count = 2;
  f.ghost_scale[0] = 0.0;   // at the centre, wherever the source is
  f.ghost_radius_px[0] = 2;
  f.ghost_intensity[0] = 0.01;
  f.ghost_scale[1] = -4.0;  // far outside
  auto b = test::Build(FlareOnly(f));
  ASSERT_TRUE(b->status.ok());
  ASSERT_EQ(Summary(*b).sources, 1);
  EXPECT_EQ(Summary(*b).haze_only, 1);
  const FlareSource& s = b->pipeline.flare_stage().environment_sources()[0];
  EXPECT_GT(s.x, 30000);
  EXPECT_LE(s.x, kMaxFlareOffset + kW);
  const test::Scene scene = test::FlatScene(kW, kH, 1.0, 1.0, 1.0);
  const auto out = RunFlare(*b, scene, 3);
  EXPECT_GT(out[(24 * kW + 32) * 3], scene.plane[0][24 * kW + 32]);  // the scale-0 ghost at (32, 24)
  EXPECT_EQ(out[(24 * kW + 36) * 3], scene.plane[0][24 * kW + 36]);

  // Without a scale-0 ghost nothing of that source reaches the frame.
  f.ghost_count = 1;
  f.ghost_scale[0] = -1.0;
  auto none = test::Build(FlareOnly(f));
  ASSERT_TRUE(none->status.ok());
  EXPECT_EQ(Summary(*none).sources, 0);
  EXPECT_EQ(Summary(*none).haze_only, 2);
}

// Fixed point against the double reference (sources and the whole frame),
// with a textured frame (its own bright tiles) and a map with sources on
// every side, one behind and one inside; any strip height and worker.
TEST(FlareEnvironment, MatchesTheDoubleReferenceForAnyStripAndWorker) {
  constexpr int kRW = 120, kRH = 90;
  Map m;
  m.Set(230, 88, 3000, 2500, 2000);   // right of the frame
  m.Set(133, 92, 800, 900, 1000);     // left
  m.Set(178, 50, 1200, 1200, 600);    // above
  m.Set(184, 135, 600, 400, 300);     // below
  m.Set(5, 80, 2000, 2000, 2000);     // behind
  m.Set(181, 91, 9000, 9000, 9000);   // inside (skipped)
  FlareConfig f = Bare(m);
  f.glare_fraction = 0.05;
  f.haze = 1e-3;
  f.ghost_count = 3;
  f.blades = 6;
  for (int g = 0; g < 3; ++g)
    for (int c = 0; c < 3; ++c) f.ghost_tint[3 * g + c] = FlareConfig{}.ghost_tint[3 * g + c];
  f.environment.fx = 60;
  f.environment.fy = 62;
  f.environment.cx = (kRW - 1) / 2.0;
  f.environment.cy = (kRH - 1) / 2.0;
  f.environment.yaw_deg = 3;
  f.environment.pitch_deg = -2;
  f.environment.roll_deg = 5;
  auto b = test::Build(FlareOnly(f, kRW, kRH), 2);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const ref::RefEnvironment re = ref::RefFlareEnvironment(f, b->pipeline.config().geometry);
  const FlareEnvironmentSummary& sum = Summary(*b);
  ASSERT_EQ(sum.sources, static_cast<int>(re.sources.size()));
  EXPECT_GE(sum.sources, 3);
  EXPECT_EQ(sum.in_frame, re.in_frame);
  EXPECT_EQ(sum.in_frame, 1);
  EXPECT_EQ(sum.haze_only, re.haze_only);
  double max_excess = 0;
  for (int i = 0; i < sum.sources; ++i) {
    const FlareSource& s = b->pipeline.flare_stage().environment_sources()[static_cast<size_t>(i)];
    EXPECT_EQ(s.x, re.sources[static_cast<size_t>(i)].x);
    EXPECT_EQ(s.y, re.sources[static_cast<size_t>(i)].y);
    for (int c = 0; c < 3; ++c) {
      const double want = re.sources[static_cast<size_t>(i)].excess[c];
      EXPECT_NEAR(s.excess[c] / kQ, want, 1e-9 * want + 1.0 / kQ);  // detmath vs libm, then one rounding
      max_excess = std::max(max_excess, want);
    }
  }
  test::Scene s = test::TexturedScene(kRW, kRH);
  for (int c = 0; c < 3; ++c) s.plane[c][10 * kRW + 100] = Q<16, 16>::FromDouble(3000.0).raw;
  const auto out = RunFlare(*b, s, 16);
  EXPECT_EQ(RunFlare(*b, s, 1), out);
  EXPECT_EQ(RunFlare(*b, s, 7, 2), out);  // strips alternate between two workers
  EXPECT_EQ(RunFlare(*b, s, kRH), out);
  ref::RefImage in;
  in.width = kRW;
  in.height = kRH;
  in.planes.assign(3, std::vector<double>(kRW * kRH));
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < kRW * kRH; ++i) in.planes[c][i] = s.plane[c][i] / kQ;
  const ref::RefImage r = ref::RefFlare(f, b->pipeline.config().geometry, in);
  // As Flare.MatchesTheDoubleReference (the frame's glare share uses the
  // Q0.16 fraction: <= 2^-17 of the pixel's radiance; the environment's glare
  // uses the exact fraction).
  double max_err = 0, max_err_dim = 0;  // all pixels; pixels below the threshold (light added only)
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < kRW * kRH; ++i) {
      const double err = std::abs(out[static_cast<size_t>(i) * 3 + c] / kQ - r.planes[c][i]);
      ASSERT_LE(err, 1e-3 + in.planes[c][i] / 131072.0) << "channel " << c << " pixel " << i;
      max_err = std::max(max_err, err);
      if (in.planes[c][i] <= f.threshold) max_err_dim = std::max(max_err_dim, err);
    }
  EXPECT_LE(max_err_dim, 5e-4);
  RecordProperty("max_abs_error", std::to_string(max_err));
  RecordProperty("max_abs_error_below_threshold", std::to_string(max_err_dim));
}

// Core validation names the key; a map with a NaN texel is refused.
TEST(FlareEnvironment, ConfigureErrorsNameTheKey) {
  Map m;
  const auto field = [](FlareConfig f) {
    PipelineConfig c = FlareOnly(f);
    Pipeline p;
    const Status st = p.Configure(c, 1, false);
    return std::string(st.ok() ? "" : st.field());
  };
  FlareConfig f = Bare(m);
  EXPECT_EQ(field(f), "");
  f.environment.pitch_deg = 91;
  EXPECT_EQ(field(f), "flare.environment_pitch_deg");
  f = Bare(m);
  f.environment.yaw_deg = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(field(f), "flare.environment_yaw_deg");
  f = Bare(m);
  f.environment.roll_deg = 400;
  EXPECT_EQ(field(f), "flare.environment_roll_deg");
  f = Bare(m);
  f.environment.gain = -1;
  EXPECT_EQ(field(f), "flare.environment_gain");
  f = Bare(m);
  f.environment.max_sources = 0;
  EXPECT_EQ(field(f), "flare.environment_max_sources");
  f = Bare(m);
  f.environment.height = 100;  // not 2:1
  EXPECT_EQ(field(f), "flare.environment_map");
  f = Bare(m);
  m.Set(3, 4, 1, std::nan(""), 1);
  EXPECT_EQ(field(f), "flare.environment_map");
  m.Set(3, 4, 1, -0.5, 1);
  EXPECT_EQ(field(f), "flare.environment_map");
}

// ---- host: keys, the loader and when the map is loaded ----

std::string TempPath(const std::string& name) {
  return testing::TempDir() + "camsim_env_" + std::to_string(getpid()) + "_" + name;
}

bool WriteMap(const std::string& path, int w, int h, const std::vector<float>& r, const std::vector<float>& g,
              const std::vector<float>& b, const char* first_name = "R") {
  std::string error;
  std::vector<io::ExrChannel> ch = {{first_name, r.data(), w}};
  if (std::string(first_name) == "R") {
    ch.push_back({"G", g.data(), w});
    ch.push_back({"B", b.data(), w});
  }
  return io::WriteExrFloat(path, w, h, ch, &error);
}

bool Finish(const std::string& toml, host::RunConfig* rc, std::string* error) {
  host::Origins origins;
  if (!host::ParseConfig(toml, "env.toml", rc, &origins, error)) return false;
  return host::FinishConfig(rc, 64, 48, origins, 1, error);
}

TEST(FlareEnvironment, HostKeysAndLoaderErrorsNameKeyAndFile) {
  std::string error;
  host::RunConfig rc;
  EXPECT_FALSE(Finish("[flare]\nenvironment_pitch_deg = 100\n", &rc, &error));
  EXPECT_NE(error.find("env.toml:2"), std::string::npos) << error;
  EXPECT_NE(error.find("flare.environment_pitch_deg"), std::string::npos) << error;
  host::RunConfig rc2;
  EXPECT_FALSE(Finish("[flare]\nenvironment_max_sources = 5000\n", &rc2, &error));
  EXPECT_NE(error.find("flare.environment_max_sources"), std::string::npos) << error;
  host::RunConfig rc3;
  EXPECT_FALSE(Finish("[flare]\nenvironment_gain = \"x\"\n", &rc3, &error));
  EXPECT_NE(error.find("flare.environment_gain"), std::string::npos) << error;

  // Missing file: named, with the key; with flare off it is not even opened.
  const std::string missing = TempPath("missing.exr");
  host::RunConfig off;
  EXPECT_TRUE(Finish("[flare]\nenvironment_map = \"" + missing + "\"\n", &off, &error)) << error;
  EXPECT_EQ(off.environment_data, nullptr);
  EXPECT_EQ(off.core.flare.environment.texels, nullptr);
  host::RunConfig on;
  EXPECT_FALSE(Finish("[flare]\nenabled = true\nenvironment_map = \"" + missing + "\"\n", &on, &error));
  EXPECT_NE(error.find("flare.environment_map"), std::string::npos) << error;
  EXPECT_NE(error.find(missing), std::string::npos) << error;

  // Not 2:1.
  const std::string square = TempPath("square.exr");
  std::vector<float> p(10 * 10, 1.0f);
  ASSERT_TRUE(WriteMap(square, 10, 10, p, p, p));
  io::EnvironmentMap map;
  EXPECT_FALSE(io::LoadEnvironmentMap(square, &map, &error));
  EXPECT_NE(error.find(square), std::string::npos) << error;
  EXPECT_NE(error.find("10 x 10"), std::string::npos) << error;

  // No colour channels.
  const std::string nocolour = TempPath("nocolour.exr");
  std::vector<float> q(8 * 4, 1.0f);
  ASSERT_TRUE(WriteMap(nocolour, 8, 4, q, q, q, "foo"));
  EXPECT_FALSE(io::LoadEnvironmentMap(nocolour, &map, &error));
  EXPECT_NE(error.find(nocolour), std::string::npos) << error;
  EXPECT_NE(error.find("no colour channels"), std::string::npos) << error;

  // NaN, negative and +inf texels are sanitised like the scene's and counted.
  const std::string dirty = TempPath("dirty.exr");
  std::vector<float> r(8 * 4, 1.0f), g(8 * 4, 2.0f), b(8 * 4, 3.0f);
  r[5] = std::nanf("");
  g[6] = -1.0f;
  b[7] = std::numeric_limits<float>::infinity();
  ASSERT_TRUE(WriteMap(dirty, 8, 4, r, g, b));
  ASSERT_TRUE(io::LoadEnvironmentMap(dirty, &map, &error)) << error;
  EXPECT_EQ(map.width, 8);
  EXPECT_EQ(map.height, 4);
  EXPECT_EQ(map.stats.nan, 1u);
  EXPECT_EQ(map.stats.negative, 1u);
  EXPECT_EQ(map.stats.pos_inf, 1u);
  ASSERT_EQ(map.warnings.size(), 1u);  // the line `camsim run` and camsim-gige print
  EXPECT_EQ(map.warnings[0], "'" + dirty + "': 1 NaN, 1 +inf, 1 negative colour samples replaced (first: channel R "
                             "at x=5, y=0)");
  EXPECT_EQ(map.rgb[5 * 3], 0.0f);
  EXPECT_EQ(map.rgb[6 * 3 + 1], 0.0f);
  EXPECT_EQ(map.rgb[7 * 3 + 2], 65504.0f);
  EXPECT_EQ(map.rgb[0 * 3 + 2], 3.0f);
  host::RunConfig good;
  ASSERT_TRUE(Finish("[flare]\nenabled = true\nenvironment_map = \"" + dirty + "\"\n", &good, &error)) << error;
  ASSERT_NE(good.environment_data, nullptr);
  EXPECT_EQ(good.core.flare.environment.width, 8);
  EXPECT_EQ(good.core.flare.environment.texels, good.environment_data->rgb.data());
  // The pinhole comes from the lens: 28 mm on a 36 mm wide, 64-pixel sensor.
  EXPECT_DOUBLE_EQ(good.core.flare.environment.fx, 28.0 / (36.0 / 64));
  EXPECT_DOUBLE_EQ(good.core.flare.environment.cx, 31.5);
  // A finished copy is finished again without reloading.
  const auto data = good.environment_data;
  ASSERT_TRUE(host::FinishConfig(&good, 64, 48, host::Origins{}, 1, &error)) << error;
  EXPECT_EQ(good.environment_data, data);
  for (const std::string& f : {square, nocolour, dirty}) std::remove(f.c_str());
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// `camsim run` with the bundled example map: the report says how many
// sources were used and how many texels went to haze only, and the map
// changes the picture; with flare off it is not used.
TEST(FlareEnvironment, RunReportCountsSourcesAndHazeTexels) {
  const std::string dir = testing::TempDir() + "camsim_env_cli_" + std::to_string(getpid());
  const std::string src = CAMSIM_SOURCE_DIR;
  const auto run = [&](const std::string& name, const std::string& sets) {
    const std::string out = dir + "/" + name;
    const std::string cmd = std::string(CAMSIM_BINARY) + " run --input " + src + "/scenes/aisle_0001.exr --out " + out +
                            " --report " + out + "/report.json --quiet --set 'flare.environment_map=\"" + src +
                            "/scenes/environment/sky_env.exr\"' " + sets + " >/dev/null 2>&1";
    EXPECT_EQ(std::system(("mkdir -p '" + out + "'").c_str()), 0);
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(out + "/report.json");
    std::stringstream s;
    s << in.rdbuf();
    std::ifstream raw(out + "/aisle_0001.raw", std::ios::binary);
    std::stringstream r;
    r << raw.rdbuf();
    return std::pair<std::string, std::string>(s.str(), r.str());
  };
  const auto on = run("on", "--set flare.enabled=true");
  EXPECT_NE(on.first.find("\"flare_environment\""), std::string::npos) << on.first;
  // The sun just above the view is a source; the lamp behind the camera adds haze only.
  EXPECT_NE(on.first.find("\"bright_texels\": 2, \"sources\": 1, \"in_frame_skipped\": 0, \"haze_only_texels\": 1"),
            std::string::npos)
      << on.first;
  EXPECT_NE(on.first.find("\"width\": 128, \"height\": 64"), std::string::npos);
  const auto plain = run("plain", "--set flare.enabled=true --set flare.environment_gain=0");
  EXPECT_NE(plain.first.find("\"sources\": 0"), std::string::npos) << plain.first;
  EXPECT_EQ(on.second.size(), 640u * 480u * 2u);
  EXPECT_NE(on.second, plain.second);  // the sun's glare, ghosts and haze
  const auto off = run("off", "");
  EXPECT_EQ(off.first.find("\"flare_environment\""), std::string::npos) << off.first;
  std::system(("rm -rf '" + dir + "'").c_str());
}

}  // namespace
}  // namespace camsim
