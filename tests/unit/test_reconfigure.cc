// Reconfiguration: a pipeline configured with `previous` (Pipeline::Configure,
// Stage::InitFrom) copies the tables whose inputs did not change, and gives
// the bytes of a pipeline built from scratch for every change.
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "core/lens/distortion.h"
#include "core/pipeline/pipeline.h"
#include "host_tools/config.h"
#include "host_tools/render.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

constexpr int kW = 96, kH = 80;

// Every stage with tables InitFrom can copy is on: the lens with chromatic
// aberration and a mesh, flare with ghosts, the sensor's stored fixed pattern
// and column offsets, an sRGB curve.
struct Base {
  std::vector<float> mesh = std::vector<float>(2 * 4 * 3, 0.25f);
  PipelineConfig config = test::DemoConfig(kW, kH);
  Base() {
    config.distortion.lens = test::TypicalLens(kW, kH);
    config.distortion.chromatic_scale[0] = 1.003;
    config.distortion.mesh = DisplacementMesh{mesh.data(), 4, 3, 32.0};
    config.flare.enabled = true;
    config.flare.threshold = 50.0;  // the textured scene's bright spot
    config.sensor.fixed_pattern_table = true;
    config.sensor.column_fpn_e = 2.0;
    config.gamma.curve = GammaCurve::kSrgb;
  }
};

// Configures and initialises `config`, with `previous` (may be null); the
// workspace starts filled with `fill`, so a table left unwritten shows.
std::unique_ptr<test::Built> BuildFrom(const PipelineConfig& config, const Pipeline* previous, uint8_t fill) {
  auto b = std::make_unique<test::Built>();
  b->status = b->pipeline.Configure(config, 1, false, previous);
  if (!b->status.ok()) return b;
  b->workspace.assign(b->pipeline.WorkspaceBytes(), fill);
  b->status = b->pipeline.Init(Span<uint8_t>{b->workspace.data(), b->workspace.size()}, previous);
  return b;
}

// Copied tables per stage name for a change of the base configuration; a
// stage not named copies none.
struct Change {
  const char* what;
  std::function<void(Base&)> apply;
  std::vector<std::pair<std::string, int>> copied;
  std::function<void(Base&)> setup = nullptr;  // applied to both configurations first
};

// Distortion: its 4 tables. Flare: the glare kernel. Sensor: the Gaussian and
// Poisson constants, the fixed pattern, the column offsets (and the DCNU
// gains, when on). Gamma: its curve.
const std::vector<Change>& Changes() {
  static const std::vector<Change> changes = {
      {"ExposureTime", [](Base& b) { b.config.exposure.exposure_time_us *= 1.5; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"Gain", [](Base& b) { b.config.sensor.gain_db += 6.0; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"k1", [](Base& b) { b.config.distortion.lens.k[0] += 0.01; },
       {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"cx", [](Base& b) { b.config.distortion.lens.cx += 0.5; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"chromatic scale", [](Base& b) { b.config.distortion.chromatic_scale[2] = 0.998; },
       {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"the mesh's values, in place", [](Base& b) { b.mesh[5] = -0.5f; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"grid step", [](Base& b) { b.config.distortion.grid_step = 16; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"seed", [](Base& b) { b.config.seed += 1; }, {{"distortion", 4}, {"flare", 1}, {"sensor", 2}, {"gamma", 1}}},
      {"PRNU", [](Base& b) { b.config.sensor.prnu_percent = 1.0; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 3}, {"gamma", 1}}},
      {"column FPN", [](Base& b) { b.config.sensor.column_fpn_e = 3.0; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 3}, {"gamma", 1}}},
      {"glare radius", [](Base& b) { b.config.flare.glare_radius = 12; },
       {{"distortion", 4}, {"sensor", 4}, {"gamma", 1}}},
      {"blades", [](Base& b) { b.config.flare.blades = 5; }, {{"distortion", 4}, {"sensor", 4}, {"gamma", 1}}},
      {"flare threshold", [](Base& b) { b.config.flare.threshold = 80.0; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"gamma curve", [](Base& b) { b.config.gamma.curve = GammaCurve::kPower; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 4}}},
      {"frame width", [](Base& b) { b.config.geometry.width = kW - 2; }, {{"flare", 1}, {"sensor", 2}, {"gamma", 1}}},
      {"frame height", [](Base& b) { b.config.geometry.height = kH + 2; }, {{"flare", 1}, {"sensor", 3}, {"gamma", 1}}},
      {"ADC bits", [](Base& b) { b.config.geometry.adc_bits = 10; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      // Every input of the lens's tables; filter and phases also size them.
      {"filter", [](Base& b) { b.config.distortion.filter = ResampleFilter::kBicubic; },
       {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"phases", [](Base& b) { b.config.distortion.phases = 128; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"fy", [](Base& b) { b.config.distortion.lens.fy *= 1.01; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"k2", [](Base& b) { b.config.distortion.lens.k[1] += 0.01; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"p2", [](Base& b) { b.config.distortion.lens.p2 += 1e-3; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"green's chromatic scale", [](Base& b) { b.config.distortion.chromatic_scale[1] = 1.001; },
       {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"mesh step", [](Base& b) { b.config.distortion.mesh.step = 24.0; }, {{"flare", 1}, {"sensor", 4}, {"gamma", 1}}},
      {"gamma exponent", [](Base& b) { b.config.gamma.gamma = 2.4; }, {{"distortion", 4}, {"flare", 1}, {"sensor", 4}},
       [](Base& b) { b.config.gamma.curve = GammaCurve::kPower; }},
      {"DSNU", [](Base& b) { b.config.sensor.dsnu_e = 2.5; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 3}, {"gamma", 1}}},
      // With DCNU the sensor also stores its dark-current gains: a new
      // exposure time (auto exposure) copies them (they do not hold the
      // exposure's dark charge), a new DCNU does not.
      {"ExposureTime with DCNU", [](Base& b) { b.config.exposure.exposure_time_us *= 1.5; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 5}, {"gamma", 1}},
       [](Base& b) { b.config.sensor.dcnu_percent = 20.0, b.config.sensor.dark_current_e_per_s = 2e4; }},
      {"DCNU", [](Base& b) { b.config.sensor.dcnu_percent = 25.0; },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 4}, {"gamma", 1}},
       [](Base& b) { b.config.sensor.dcnu_percent = 20.0, b.config.sensor.dark_current_e_per_s = 2e4; }},
      // Without the CFA, a sensor per colour: its fixed pattern has three planes.
      {"sensor channels",
       [](Base& b) {
         int n = 0;
         for (int i = 0; i < b.config.order_count; ++i)
           if (b.config.order[i] != StageId::kCfa && b.config.order[i] != StageId::kDemosaic)
             b.config.order[n++] = b.config.order[i];
         b.config.order_count = n;
       },
       {{"distortion", 4}, {"flare", 1}, {"sensor", 3}, {"gamma", 1}}},
  };
  return changes;
}

int Expected(const Change& c, const char* stage) {
  for (const auto& [name, n] : c.copied)
    if (name == stage) return n;
  return 0;
}

// The running distortion stage of `p`, or nullptr.
const DistortionStage* RunningDistortion(const Pipeline& p) {
  for (int i = 0; i < p.plan().running; ++i)
    if (std::string(p.running_stage(i).name()) == "distortion")
      return static_cast<const DistortionStage*>(&p.running_stage(i));
  return nullptr;
}

TEST(Reconfigure, CopiedTablesGiveTheBytesOfAPipelineBuiltFromScratch) {
  for (const Change& change : Changes()) {
    SCOPED_TRACE(change.what);
    Base base;
    if (change.setup) change.setup(base);
    auto before = BuildFrom(base.config, nullptr, 0);
    ASSERT_TRUE(before->status.ok()) << before->status.message();
    change.apply(base);
    const int w = base.config.geometry.width, h = base.config.geometry.height;
    const test::Scene scene = test::TexturedScene(w, h);
    auto fresh = BuildFrom(base.config, nullptr, 0);
    auto reused = BuildFrom(base.config, &before->pipeline, 0xA5);
    ASSERT_TRUE(fresh->status.ok()) << fresh->status.message();
    ASSERT_TRUE(reused->status.ok()) << reused->status.message();
    EXPECT_EQ(reused->pipeline.WorkspaceBytes(), fresh->pipeline.WorkspaceBytes());
    const Plan& plan = reused->pipeline.plan();
    ASSERT_EQ(plan.running, fresh->pipeline.plan().running);
    for (int i = 0; i < plan.running; ++i) {
      const char* name = reused->pipeline.running_stage(i).name();
      EXPECT_EQ(reused->pipeline.CopiedTables(i), Expected(change, name)) << name;
      EXPECT_EQ(fresh->pipeline.CopiedTables(i), 0) << name;
    }
    // Configure borrows the lens's band ranges exactly when Init copies its tables.
    ASSERT_NE(RunningDistortion(reused->pipeline), nullptr);
    EXPECT_EQ(RunningDistortion(reused->pipeline)->bands_borrowed(), Expected(change, "distortion") == 4);
    for (uint32_t frame : {0u, 7u}) {
      const std::vector<uint32_t> want = test::RunFrame(*fresh, scene, frame, 13);
      ASSERT_EQ(test::UnwrittenCount(want), 0u);
      EXPECT_EQ(test::RunFrame(*reused, scene, frame, 13), want) << "frame " << frame;
    }
  }
}

// Only an initialised pipeline lends its tables, and only for stages it ran.
// A pipeline only configured lends the lens's band ranges to Configure; one
// whose Configure failed lends nothing.
TEST(Reconfigure, OnlyStagesThatRanInAnInitialisedPipelineLendTheirTables) {
  Base base;
  Pipeline configured_only;
  ASSERT_TRUE(configured_only.Configure(base.config, 1, false).ok());
  auto b = BuildFrom(base.config, &configured_only, 0);
  ASSERT_TRUE(b->status.ok());
  for (int i = 0; i < b->pipeline.plan().running; ++i) EXPECT_EQ(b->pipeline.CopiedTables(i), 0);
  ASSERT_NE(RunningDistortion(b->pipeline), nullptr);
  EXPECT_TRUE(RunningDistortion(b->pipeline)->bands_borrowed());
  PipelineConfig broken = base.config;
  broken.gamma.gamma = -1.0;  // refused after the lens is configured
  broken.gamma.curve = GammaCurve::kPower;
  ASSERT_FALSE(configured_only.Configure(broken, 1, false).ok());
  auto after_failure = BuildFrom(base.config, &configured_only, 0);
  ASSERT_TRUE(after_failure->status.ok());
  EXPECT_FALSE(RunningDistortion(after_failure->pipeline)->bands_borrowed());

  PipelineConfig linear = base.config;
  linear.gamma.curve = GammaCurve::kLinear;  // left out: its stage has no table
  auto without_gamma = BuildFrom(linear, nullptr, 0);
  ASSERT_TRUE(without_gamma->status.ok());
  auto with_gamma = BuildFrom(base.config, &without_gamma->pipeline, 0);
  ASSERT_TRUE(with_gamma->status.ok());
  const Plan& plan = with_gamma->pipeline.plan();
  ASSERT_EQ(std::string(with_gamma->pipeline.running_stage(plan.running - 1).name()), "gamma");
  EXPECT_EQ(with_gamma->pipeline.CopiedTables(plan.running - 1), 0);
  EXPECT_EQ(with_gamma->pipeline.CopiedTables(0), 1) << "flare ran in both";

  // Reconfiguring a pipeline from itself is a plain reconfiguration.
  auto self = BuildFrom(base.config, nullptr, 0);
  ASSERT_TRUE(self->status.ok());
  ASSERT_TRUE(self->pipeline.Configure(base.config, 1, false, &self->pipeline).ok());
  ASSERT_TRUE(self->pipeline.Init(Span<uint8_t>{self->workspace.data(), self->workspace.size()}, &self->pipeline).ok());
  for (int i = 0; i < self->pipeline.plan().running; ++i) EXPECT_EQ(self->pipeline.CopiedTables(i), 0);
  const test::Scene scene = test::TexturedScene(kW, kH);
  EXPECT_EQ(test::RunFrame(*self, scene, 1, 16), test::RunFrame(*b, scene, 1, 16));
}

// A kW x kH scene of grey levels 0 .. 2.
io::SceneFrame GreyScene() {
  io::SceneFrame scene;
  scene.width = kW;
  scene.height = kH;
  for (io::FloatPlane* p : {&scene.r, &scene.g, &scene.b}) {
    p->width = kW;
    p->height = kH;
    for (int i = 0; i < kW * kH; ++i) p->data.push_back(static_cast<float>((i * 37) % 101) / 50.0f);
  }
  return scene;
}

// The host's renderer, as the emulated camera uses it on an ExposureTime
// write: plan and install a new pipeline over the one in use. The scene stays,
// the lens's tables are copied, and the frame is the one a renderer built for
// the new setting from scratch gives.
std::vector<uint8_t> RenderRgb(host::FrameRenderer& r) {
  std::vector<uint8_t> rgb(static_cast<size_t>(r.pipeline().width()) * r.pipeline().height() * 3);
  Tap tap;
  tap.format = TapFormat::kU8;
  tap.data = rgb.data();
  tap.stride = static_cast<ptrdiff_t>(r.pipeline().width()) * 3;
  r.Render(2, &tap, 1, nullptr);
  return rgb;
}

TEST(Reconfigure, TheRendererKeepsItsSceneAndCopiesTheLensTables) {
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  ASSERT_TRUE(host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, &origins, &error)) << error;
  ASSERT_TRUE(host::ParseConfig("[distortion]\nmodel = \"brown\"\nk1 = -0.28\nk2 = 0.07\np1 = 0.0012\n", "lens",
                                &rc, &origins, &error))
      << error;
  const io::SceneFrame scene = GreyScene();
  host::FrameRenderer r(1, 0);
  ASSERT_TRUE(r.Configure(rc, origins, kW, kH, nullptr, &error)) << error;
  ASSERT_TRUE(r.SetScene(scene, &error)) << error;
  const std::vector<uint8_t> first = RenderRgb(r);

  host::RunConfig longer = rc;
  longer.core.exposure.exposure_time_us *= 1.5;
  host::PlannedPipeline planned;
  ASSERT_TRUE(r.PlanPipeline(longer, origins, kW, kH, &planned, &error)) << error;
  ASSERT_TRUE(r.Install(std::move(planned), origins, &error)) << error;
  EXPECT_TRUE(r.has_scene());
  const Plan& plan = r.pipeline().plan();
  ASSERT_EQ(std::string(r.pipeline().running_stage(0).name()), "distortion");
  EXPECT_EQ(r.pipeline().CopiedTables(0), 4);
  EXPECT_EQ(std::string(r.pipeline().running_stage(plan.running - 1).name()), "gamma");
  EXPECT_EQ(r.pipeline().CopiedTables(plan.running - 1), 1);
  const std::vector<uint8_t> second = RenderRgb(r);
  EXPECT_NE(second, first) << "the exposure changed the frame";

  host::FrameRenderer fresh(1, 0);
  ASSERT_TRUE(fresh.Configure(longer, origins, kW, kH, nullptr, &error)) << error;
  ASSERT_TRUE(fresh.SetScene(scene, &error)) << error;
  EXPECT_EQ(RenderRgb(fresh), second);
}

// FinishConfig hands out the pipeline it configured to check the
// configuration (FrameRenderer::PlanPipeline installs it instead of
// configuring another): it solved the lens's band ranges itself (the auto
// exposure's corner checks borrow them), has the workers asked for, and
// gives the frame of a pipeline configured afresh from the finished
// configuration.
TEST(Reconfigure, TheValidationsPipelineIsTheOnePlanned) {
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  ASSERT_TRUE(host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, &origins, &error)) << error;
  ASSERT_TRUE(host::ParseConfig("[distortion]\nmodel = \"brown\"\nk1 = -0.28\nk2 = 0.07\n"
                                "[auto_exposure]\nmode = \"continuous\"\n",
                                "lens", &rc, &origins, &error))
      << error;
  std::unique_ptr<Pipeline> configured;
  ASSERT_TRUE(host::FinishConfig(&rc, kW, kH, origins, 2, &error, nullptr, &configured)) << error;
  ASSERT_NE(configured, nullptr);
  ASSERT_NE(RunningDistortion(*configured), nullptr);
  // Validated again with it as `previous` (a reconfiguration): the next one borrows.
  host::RunConfig again = rc;
  std::unique_ptr<Pipeline> next;
  ASSERT_TRUE(host::FinishConfig(&again, kW, kH, origins, 2, &error, configured.get(), &next)) << error;
  ASSERT_NE(next, nullptr);
  ASSERT_NE(RunningDistortion(*next), nullptr);
  EXPECT_TRUE(RunningDistortion(*next)->bands_borrowed());
  // A failed validation hands out nothing.
  host::RunConfig bad = rc;
  bad.output_bits = 12;
  EXPECT_FALSE(host::FinishConfig(&bad, kW, kH, origins, 2, &error, nullptr, &next));
  EXPECT_EQ(next, nullptr);
  auto fresh = test::Build(rc.core, 2);
  ASSERT_TRUE(fresh->status.ok()) << fresh->status.message();
  ASSERT_EQ(configured->WorkspaceBytes(), fresh->pipeline.WorkspaceBytes());
  std::vector<uint8_t> workspace(configured->WorkspaceBytes(), 0xA5);
  ASSERT_TRUE(configured->Init(Span<uint8_t>{workspace.data(), workspace.size()}).ok());
  const test::Scene scene = test::TexturedScene(kW, kH);
  std::vector<uint32_t> out(static_cast<size_t>(kW) * kH * configured->plan().output.channels, test::kUnwritten);
  Tap tap;
  tap.stage = -1;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = static_cast<ptrdiff_t>(kW) * configured->plan().output.channels;
  const FrameInput in = scene.View();
  configured->ProcessStrip(in, 3, 0, kH / 2, 0, &tap, 1, nullptr, nullptr);
  configured->ProcessStrip(in, 3, kH / 2, kH, 1, &tap, 1, nullptr, nullptr);  // worker 1 exists
  EXPECT_EQ(out, test::RunFrame(*fresh, scene, 3, 16));
}

// A prepared scene holds only while the sensor's size and the scene fit do:
// a sensor smaller than the scene crops it or scales it down.
TEST(Reconfigure, TheRendererDropsItsSceneWhenItsFitChanges) {
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  ASSERT_TRUE(host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, &origins, &error)) << error;
  rc.width = kW / 2;
  rc.height = kH / 2;
  const io::SceneFrame scene = GreyScene();
  host::FrameRenderer r(1, 0);
  ASSERT_TRUE(r.Configure(rc, origins, kW, kH, nullptr, &error)) << error;
  ASSERT_TRUE(r.SetScene(scene, &error)) << error;
  host::RunConfig next = rc;
  next.core.exposure.exposure_time_us *= 2;
  ASSERT_TRUE(r.Configure(next, origins, kW, kH, nullptr, &error)) << error;
  EXPECT_TRUE(r.has_scene()) << "same size and fit";
  next.fit = host::SceneFit::kScale;
  ASSERT_TRUE(r.Configure(next, origins, kW, kH, nullptr, &error)) << error;
  EXPECT_FALSE(r.has_scene()) << "the cropped scene does not hold for a scaled one";
}

}  // namespace
}  // namespace camsim
