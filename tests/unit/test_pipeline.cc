// The streaming driver and planner: strip-height and thread-count invariance,
// what the planner leaves out, workspace accounting, no heap while processing.
#include <gtest/gtest.h>

#include <vector>

#include "core/pipeline/pipeline.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/scene_input.h"
#include "tests/support/allocations.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

using test::Build;
using test::DemoConfig;
using test::Find;
using test::RunFrame;

// Every tap format on every Q0.16 value and beyond (saturation), for 1 and 3
// channels and widths that leave a vector tail: kU8 is round(v * 255 / 65535)
// with ties up, here computed as floor((510 v + 65535) / 131070).
TEST(Pipeline, TapRowsConvertEverySample) {
  const int w = 65536 + 37;
  std::vector<uint32_t> planes[3];
  for (int c = 0; c < 3; ++c) {
    planes[c].resize(w);
    for (int x = 0; x < w; ++x) planes[c][x] = x < 65536 ? static_cast<uint32_t>((x * (c + 1) * 7919) % 65536)
                                                        : 0xFFFFFFFFu - static_cast<uint32_t>(x * c);
  }
  const uint32_t* rows[3] = {planes[0].data(), planes[1].data(), planes[2].data()};
  const auto u8 = [](uint32_t v) {
    const uint64_t q = v > 65535u ? 65535u : v;
    return static_cast<uint8_t>((510 * q + 65535) / 131070);
  };
  for (const int channels : {1, 3})
    for (const int width : {w, 17, 15, 1}) {
      std::vector<uint8_t> b8(static_cast<size_t>(2) * width * channels, 0xAB);
      std::vector<uint16_t> b16(static_cast<size_t>(2) * width * channels, 0xABCD);
      std::vector<uint32_t> b32(static_cast<size_t>(2) * width * channels, 0xDEADBEEFu);
      Tap t8{0, TapFormat::kU8, b8.data(), static_cast<ptrdiff_t>(width) * channels};
      Tap t16{0, TapFormat::kU16, b16.data(), static_cast<ptrdiff_t>(width) * channels};
      Tap t32{0, TapFormat::kU32, b32.data(), static_cast<ptrdiff_t>(width) * channels};
      for (const Tap& t : {t8, t16, t32}) WriteTapRow(t, rows, channels, 1, width);  // row 1: the second half
      for (int x = 0; x < width; ++x)
        for (int c = 0; c < channels; ++c) {
          const size_t i = static_cast<size_t>(width + x) * channels + c;
          const uint32_t v = planes[c][x];
          ASSERT_EQ(b8[i], u8(v)) << "v " << v << " x " << x << " c " << c << " of " << channels;
          ASSERT_EQ(b16[i], v > 65535u ? 65535u : v);
          ASSERT_EQ(b32[i], v);
        }
      for (size_t i = 0; i < static_cast<size_t>(width) * channels; ++i)
        ASSERT_TRUE(b8[i] == 0xAB && b16[i] == 0xABCD && b32[i] == 0xDEADBEEFu) << "row 0 untouched";
    }
}

TEST(Pipeline, StripHeightDoesNotChangeOutput) {
  // Odd sizes so that strips end mid-Bayer-cell and rows reflect at both edges.
  for (DemosaicMethod method : {DemosaicMethod::kBilinear, DemosaicMethod::kMalvar}) {
    PipelineConfig c = DemoConfig(67, 53);
    c.demosaic.method = method;
    auto b = Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const test::Scene scene = test::TexturedScene(67, 53);
    const std::vector<uint32_t> whole = RunFrame(*b, scene, 3, 53);
    for (int rows : {1, 2, 7, 64}) {
      EXPECT_EQ(RunFrame(*b, scene, 3, rows), whole) << "strip rows " << rows;
    }
    for (uint32_t v : whole) ASSERT_NE(v, 0xDEADBEEFu) << "an output pixel was never written";
  }
}

TEST(Pipeline, ThreadCountDoesNotChangeOutput) {
  PipelineConfig c = DemoConfig(96, 80);
  const test::Scene scene = test::TexturedScene(96, 80);
  auto one = Build(c, 1);
  ASSERT_TRUE(one->status.ok());
  const std::vector<uint32_t> reference = RunFrame(*one, scene, 0, 80);
  ASSERT_EQ(test::UnwrittenCount(reference), 0u);
  for (int threads : {2, 3, 4}) {
    auto b = Build(c, threads);
    ASSERT_TRUE(b->status.ok());
    EXPECT_EQ(test::RunFrameThreads(*b, scene, 0, 5, threads), reference) << threads << " threads";
  }
}

TEST(Pipeline, NoiseIsKeyedByFrameAndSeed) {
  PipelineConfig c = DemoConfig(32, 32);
  const test::Scene scene = test::FlatScene(32, 32, 0.3, 0.3, 0.3);
  auto b = Build(c);
  ASSERT_TRUE(b->status.ok());
  const auto f0 = RunFrame(*b, scene, 0, 32);
  EXPECT_EQ(RunFrame(*b, scene, 0, 32), f0);
  EXPECT_NE(RunFrame(*b, scene, 1, 32), f0);
  c.seed = 2;
  auto b2 = Build(c);
  ASSERT_TRUE(b2->status.ok());  // else its unwritten output differs from f0 anyway
  EXPECT_NE(RunFrame(*b2, scene, 0, 32), f0);
}

TEST(Pipeline, PlannerLeavesOutIdentityStagesAndSaysWhy) {
  PipelineConfig c;  // all defaults: identity vignetting, WB, CCM, gamma
  c.geometry.width = 16;
  c.geometry.height = 8;
  auto b = Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const Plan& p = b->pipeline.plan();
  EXPECT_EQ(p.count, kStageCount);
  EXPECT_FALSE(Find(p, StageId::kVignetting)->runs);
  EXPECT_STREQ(Find(p, StageId::kVignetting)->reason, "vignetting.mode is off");
  EXPECT_FALSE(Find(p, StageId::kWhiteBalance)->runs);
  EXPECT_FALSE(Find(p, StageId::kColorMatrix)->runs);
  EXPECT_FALSE(Find(p, StageId::kGamma)->runs);
  EXPECT_TRUE(Find(p, StageId::kSensor)->runs);
  EXPECT_TRUE(Find(p, StageId::kDemosaic)->runs);
  EXPECT_EQ(p.running, 5);
  EXPECT_EQ(p.output.domain, Domain::kLinear);
  EXPECT_EQ(p.output.channels, 3);
}

TEST(Pipeline, StageSubsetsChainOrFailClearly) {
  PipelineConfig c = DemoConfig(16, 16);
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kDemosaic;  // demosaic needs a mosaic, not RGB photons
  c.order_count = 2;
  auto b = Build(c);
  ASSERT_FALSE(b->status.ok());
  EXPECT_STREQ(b->status.field(), "demosaic");

  c.order[1] = StageId::kVignetting;
  auto ok = Build(c);
  ASSERT_TRUE(ok->status.ok());
  EXPECT_EQ(ok->pipeline.plan().output.domain, Domain::kPhotons);

  c.order[1] = StageId::kExposure;  // listed twice
  EXPECT_FALSE(Build(c)->status.ok());
}

TEST(Pipeline, MonoSensorLeavesOutDemosaicAndColourMatrix) {
  PipelineConfig c = DemoConfig(16, 16);
  c.geometry.cfa = Cfa::kMono;
  c.color_matrix.m[1] = 0.1;  // not the identity: left out for being mono, not for being identity
  c.color_matrix.m[0] = 0.9;
  auto b = Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const Plan& p = b->pipeline.plan();
  EXPECT_FALSE(Find(p, StageId::kDemosaic)->runs);
  EXPECT_STREQ(Find(p, StageId::kDemosaic)->reason, "sensor.cfa is Mono: there is no mosaic to interpolate");
  EXPECT_FALSE(Find(p, StageId::kColorMatrix)->runs);
  EXPECT_TRUE(Find(p, StageId::kGamma)->runs);
  EXPECT_EQ(p.output.channels, 1);
  EXPECT_FALSE(p.output.mosaic);
  const test::Scene s = test::FlatScene(16, 16, 0.5, 0.5, 0.5);
  const auto out = RunFrame(*b, s, 0, 16);
  EXPECT_EQ(out.size(), 16u * 16u);
}

TEST(Pipeline, WorkspaceTooSmallIsAConfigurationError) {
  PipelineConfig c = DemoConfig(64, 32);
  Pipeline p;
  ASSERT_TRUE(p.Configure(c, 2, false).ok());
  std::vector<uint8_t> ws(p.WorkspaceBytes() - 1);
  const Status s = p.Init(Span<uint8_t>{ws.data(), ws.size()});
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted);
  // Any alignment of the caller's buffer works when it is WorkspaceBytes() long.
  std::vector<uint8_t> big(p.WorkspaceBytes() + 7);
  for (size_t skew = 0; skew < 4; ++skew)
    EXPECT_TRUE(p.Init(Span<uint8_t>{big.data() + skew, p.WorkspaceBytes()}).ok());
}

TEST(Pipeline, WorkspaceGrowsWithWidthNotHeight) {
  PipelineConfig a = DemoConfig(640, 480), b = DemoConfig(640, 4800), c = DemoConfig(1280, 480);
  Pipeline pa, pb, pc;
  ASSERT_TRUE(pa.Configure(a, 1, false).ok());
  ASSERT_TRUE(pb.Configure(b, 1, false).ok());
  ASSERT_TRUE(pc.Configure(c, 1, false).ok());
  EXPECT_EQ(pa.WorkerBytes(), pb.WorkerBytes());  // line rings, no frame buffers
  // Rows twice as wide: the rings (and so the worker memory) about double.
  EXPECT_GT(pc.WorkerBytes(), pa.WorkerBytes() * 3 / 2);
  EXPECT_LE(pc.WorkerBytes(), pa.WorkerBytes() * 2);
}

TEST(Pipeline, NoHeapAllocationWhileProcessing) {
  PipelineConfig c = DemoConfig(128, 64);
  auto b = Build(c);
  ASSERT_TRUE(b->status.ok());
  const test::Scene scene = test::TexturedScene(128, 64);
  std::vector<uint32_t> out(128 * 64 * 3);
  Tap t;
  t.format = TapFormat::kU32;
  t.data = out.data();
  t.stride = 128 * 3;
  WorkerStats stats;
  const FrameInput in = scene.View();
  const long before = test::AllocationCount();
  for (uint32_t frame = 0; frame < 3; ++frame) b->pipeline.ProcessFrame(in, frame, 7, &t, 1, &stats, nullptr);
  EXPECT_EQ(test::AllocationCount() - before, 0);
  EXPECT_GT(stats.stage[0].count[0], 0);  // the work did happen
}

// The same for every stage a frame can run, on two workers (strips of 7 rows
// taken in turn), pre-passes included: configs/tradeoff.toml (distortion with
// chromatic scale, diffusion DoF, motion blur from camera motion) plus flare,
// blooming, smear, row and column noise, hot pixels, a colour matrix and the
// fixed-pattern table; then the gather DoF with motion vectors. Only the
// configuration (host code) allocates, before the count starts.
TEST(Pipeline, NoHeapAllocationWhileProcessingEveryStage) {
  const std::vector<std::string> every = {
      "flare.enabled=true",         "flare.threshold=0.5",          "blooming.enabled=true",
      "sensor.smear_row_transfer_us=2", "sensor.row_fpn_e=1",       "sensor.column_fpn_e=1",
      "sensor.hot_pixel_fraction=0.01", "sensor.fixed_pattern_table=true",
      "color_matrix.m=[1.2, -0.1, -0.1, -0.1, 1.2, -0.1, -0.1, -0.1, 1.2]"};
  const std::vector<std::string> gather = [&every] {
    std::vector<std::string> g = every;
    g.insert(g.end(), {"dof.method=gather", "motion.source=vectors"});
    return g;
  }();
  io::SceneFrame scene;
  std::string error;
  ASSERT_TRUE(io::LoadSceneExr(CAMSIM_SOURCE_DIR "/scenes/aisle_0001.exr", "", &scene, &error)) << error;
  for (const auto* sets : {&every, &gather}) {
    host::RunConfig rc;
    host::Origins origins;
    ASSERT_TRUE(host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/tradeoff.toml", &rc, &origins, &error)) << error;
    for (const std::string& a : *sets) ASSERT_TRUE(host::ApplyOverride(a, &rc, &origins, &error)) << error;
    ASSERT_TRUE(host::ApplyOverride("sensor.width=96", &rc, &origins, &error)) << error;
    ASSERT_TRUE(host::ApplyOverride("sensor.height=64", &rc, &origins, &error)) << error;
    ASSERT_TRUE(host::ApplyOverride("sensor.scene_fit=scale", &rc, &origins, &error)) << error;
    std::unique_ptr<Pipeline> p;
    ASSERT_TRUE(host::FinishConfig(&rc, scene.width, scene.height, origins, 2, &error, nullptr, &p)) << error;
    // Every stage of the order runs but the other DoF method.
    std::string left_out;
    for (int i = 0; i < p->plan().count; ++i)
      if (!p->plan().entries[i].runs)
        left_out += std::string(StageName(p->plan().entries[i].id)) + " (" + p->plan().entries[i].reason + ") ";
    // All but the other DoF method (one stage or two) and the cfa, whose
    // mosaic the distortion writes itself.
    EXPECT_EQ(p->plan().running, kStageCount - (sets == &every ? 2 : 3)) << left_out;
    std::vector<uint8_t> workspace(p->WorkspaceBytes());
    ASSERT_TRUE(p->Init(Span<uint8_t>{workspace.data(), workspace.size()}).ok());
    host::CoreInput input;
    host::PrepareInput(scene, p->width(), p->height(), rc.fit, &input);
    std::vector<FlareSource> sources(static_cast<size_t>(p->PrepassFlareSources()));
    std::vector<uint32_t> smear(static_cast<size_t>(p->PrepassSmearEntries()));
    FlareFrame flare;
    std::vector<uint8_t> out(static_cast<size_t>(p->width()) * p->height() * 3);
    Tap t;
    t.format = TapFormat::kU8;
    t.data = out.data();
    t.stride = p->width() * 3;
    WorkerStats stats[2];
    const long before = test::AllocationCount();
    for (uint32_t frame = 0; frame < 2; ++frame) {
      const FrameInput in = p->RunPrepasses(input.View(), Span<FlareSource>{sources.data(), sources.size()}, &flare,
                                            Span<uint32_t>{smear.data(), smear.size()});
      ASSERT_TRUE(p->CheckInput(in).ok());
      for (int y0 = 0, k = 0; y0 < p->height(); y0 += 7, ++k)
        p->ProcessStrip(in, frame, y0, y0 + 7, k % 2, &t, 1, &stats[k % 2], nullptr);
    }
    EXPECT_EQ(test::AllocationCount() - before, 0) << (sets == &every ? "diffusion" : "gather");
    EXPECT_GT(stats[0].stage[0].count[1] + stats[1].stage[0].count[1], 0);  // the work did happen
  }
}

TEST(Pipeline, CheckInputRejectsWrongSizes) {
  PipelineConfig c = DemoConfig(32, 16);
  auto b = Build(c);
  const test::Scene wrong = test::FlatScene(31, 16, 1, 1, 1);
  EXPECT_FALSE(b->pipeline.CheckInput(wrong.View()).ok());
  const test::Scene right = test::FlatScene(32, 16, 1, 1, 1);
  EXPECT_TRUE(b->pipeline.CheckInput(right.View()).ok());
}

TEST(Pipeline, TinyFramesWork) {
  for (auto [w, h] : {std::pair{1, 1}, {1, 7}, {7, 1}, {2, 2}, {3, 5}}) {
    PipelineConfig c = DemoConfig(64, 64);
    c.geometry.width = w;
    c.geometry.height = h;
    auto b = Build(c);
    ASSERT_TRUE(b->status.ok()) << w << "x" << h << ": " << b->status.message();
    const test::Scene scene = test::TexturedScene(w, h);
    const auto whole = RunFrame(*b, scene, 0, h);
    EXPECT_EQ(RunFrame(*b, scene, 0, 1), whole);
    for (uint32_t v : whole) EXPECT_LE(v, 65535u);
  }
}

}  // namespace
}  // namespace camsim
