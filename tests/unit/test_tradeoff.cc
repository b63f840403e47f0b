// The whole-pipeline double reference (core/pipeline/pipeline_ref.h) and
// `camsim tradeoff`, which measures every stage against it.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include "core/lens/distortion_ref.h"
#include "core/pipeline/pipeline_ref.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

// The demo camera without noise, on a textured scene, every stage tapped.
struct Tapped {
  std::unique_ptr<test::Built> built;
  test::Scene scene;
  std::vector<std::vector<uint32_t>> out;
};

Tapped RunTapped(PipelineConfig c, int w, int h) {
  c.sensor.shot_noise = false;
  c.sensor.dark_noise_e = 0;
  c.sensor.dsnu_e = 0;
  c.sensor.prnu_percent = 0;
  Tapped t;
  t.built = test::Build(c);
  EXPECT_TRUE(t.built->status.ok()) << t.built->status.message();
  t.scene = test::TexturedScene(w, h);
  const Pipeline& p = t.built->pipeline;
  const int n = p.plan().running;
  std::vector<Tap> taps(static_cast<size_t>(n));
  t.out.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    t.out[i].resize(static_cast<size_t>(w) * h * p.running_format(i).channels);
    taps[i].stage = i;
    taps[i].format = TapFormat::kU32;
    taps[i].data = t.out[i].data();
    taps[i].stride = static_cast<ptrdiff_t>(w) * p.running_format(i).channels;
  }
  p.ProcessFrame(t.scene.View(), 0, 7, taps.data(), n, nullptr, nullptr);
  return t;
}

ref::RefImage AsRef(const std::vector<uint32_t>& v, LineFormat f, int w, int h) {
  ref::RefImage r{w, h, std::vector<std::vector<double>>(f.channels, std::vector<double>(static_cast<size_t>(w) * h))};
  for (size_t i = 0; i < r.planes[0].size(); ++i)
    for (int c = 0; c < f.channels; ++c) r.planes[c][i] = ref::SampleToReal(f.domain, v[i * f.channels + c]);
  return r;
}

// Each stage's reference, on the stage's own fixed-point input, is within the
// stage's stated rounding of its output: exposure and vignetting within
// Q24.8 rounding plus the gain's relative quantisation, the CFA exact, the
// sensor within half a DN plus the gain format's relative error, the ISP
// stages within half an LSB.
TEST(PipelineReference, EveryStageWithinItsStatedRounding) {
  constexpr int kW = 61, kH = 37;
  for (DemosaicMethod m : {DemosaicMethod::kBilinear, DemosaicMethod::kMalvar}) {
    PipelineConfig c = test::DemoConfig(kW, kH);
    c.demosaic.method = m;
    c.color_matrix.m[1] = 0.1;  // make the colour matrix run
    c.color_matrix.m[0] = 0.9;
    const Tapped t = RunTapped(c, kW, kH);
    const Pipeline& p = t.built->pipeline;
    ASSERT_EQ(p.plan().running, 9);
    const FrameInput view = t.scene.View();
    for (int i = 0; i < p.plan().running; ++i) {
      const LineFormat f = p.running_format(i);
      const ref::RefImage in = i == 0 ? ref::SceneRadiance(view, kW, kH) : AsRef(t.out[i - 1], p.running_format(i - 1), kW, kH);
      const ref::RefImage want = ref::RunStageReference(p, i, in, view);
      ASSERT_EQ(static_cast<int>(want.planes.size()), f.channels) << p.running_stage(i).name();
      const ref::RefImage got = AsRef(t.out[i], f, kW, kH);
      double worst = 0;  // absolute, or relative above 1000 photons
      for (size_t k = 0; k < want.planes.size(); ++k)
        for (size_t j = 0; j < want.planes[k].size(); ++j) {
          const double d = std::fabs(got.planes[k][j] - want.planes[k][j]);
          worst = std::fmax(worst, f.domain == Domain::kPhotons && want.planes[k][j] > 1000 ? d / want.planes[k][j] * 1000 : d);
        }
      const std::string name = p.running_stage(i).name();
      double bound = 0.5 + 1e-9;
      // Photons, or 1000 x relative: the exposure factor's rounding; for
      // vignetting also the curve's interpolation (< 1e-4, vignetting.h) and
      // the Q2.14 gain step (3e-5).
      if (name == "exposure") bound = 0.01;
      if (name == "vignetting") bound = 0.15;
      if (name == "cfa") bound = 0;
      if (name == "sensor") bound = 0.53;
      EXPECT_LE(worst, bound) << name;
    }
  }
}

// The chain of references from the scene ends near the fixed-point output:
// the ADC's rounding (up to 0.5 DN, amplified by white balance and gamma) is
// the only large difference.
TEST(PipelineReference, ChainFromTheSceneEndsNearTheOutput) {
  constexpr int kW = 40, kH = 30;
  const Tapped t = RunTapped(test::DemoConfig(kW, kH), kW, kH);
  const Pipeline& p = t.built->pipeline;
  const FrameInput view = t.scene.View();
  ref::RefImage chain = ref::SceneRadiance(view, kW, kH);
  for (int i = 0; i < p.plan().running; ++i) chain = ref::RunStageReference(p, i, chain, view);
  const int last = p.plan().running - 1;
  const ref::RefImage got = AsRef(t.out[last], p.running_format(last), kW, kH);
  double sum2 = 0;
  size_t n = 0;
  for (size_t k = 0; k < chain.planes.size(); ++k)
    for (size_t j = 0; j < chain.planes[k].size(); ++j, ++n) sum2 += std::pow(got.planes[k][j] - chain.planes[k][j], 2);
  const double rms = std::sqrt(sum2 / static_cast<double>(n));
  EXPECT_GT(rms, 0.0);     // the ADC does round
  EXPECT_LT(rms, 64.0);    // a quarter of an 8-bit step
}

// Where the remap grid's source and the exact source fall on different sides
// of the frame edge, FillDisagreement marks the pixel: only there (every
// marked pixel's exact source lies within the grid's error of the edge), more
// of them the coarser the grid, and nothing for a stage that is not distortion.
TEST(PipelineReference, FillDisagreementOnlyWhereTheSourceIsNearTheEdge) {
  constexpr int kW = 160, kH = 120;
  size_t marked[2] = {};
  const int steps[2] = {4, 32};
  for (int s = 0; s < 2; ++s) {
    PipelineConfig c = test::DemoConfig(kW, kH);
    c.distortion.lens = test::TypicalLens(kW, kH);
    c.distortion.chromatic_scale[0] = 1.004;
    c.distortion.chromatic_scale[2] = 0.996;
    c.distortion.grid_step = steps[s];
    const auto built = test::Build(c);
    ASSERT_TRUE(built->status.ok()) << built->status.message();
    const Pipeline& p = built->pipeline;
    int at = -1;
    for (int i = 0; i < p.plan().running; ++i) {
      if (std::strcmp(p.running_stage(i).name(), "distortion") == 0) {
        at = i;
      } else {
        EXPECT_TRUE(ref::FillDisagreement(p, i).empty()) << p.running_stage(i).name();
      }
    }
    ASSERT_GE(at, 0);
    const std::vector<uint8_t> flip = ref::FillDisagreement(p, at);
    ASSERT_EQ(flip.size(), static_cast<size_t>(kW) * kH);
    const ReferenceDistortion d(c.distortion, c.geometry);
    const auto& stage = static_cast<const DistortionStage&>(p.running_stage(at));
    // The grid's error: the largest distance between the stage's and the
    // exact source over the frame.
    double grid_error = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x)
        for (int k = 0; k < 3; ++k) {
          int64_t fx, fy;
          double sx, sy;
          ASSERT_TRUE(d.Source(x, y, k, &sx, &sy));
          ASSERT_TRUE(stage.SourcePosition(x, y, k, &fx, &fy));
          grid_error = std::max({grid_error, std::fabs(fx / 65536.0 - sx), std::fabs(fy / 65536.0 - sy)});
        }
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        if (!flip[static_cast<size_t>(y) * kW + x]) continue;
        ++marked[s];
        double edge = 1e9;  // distance of the nearest channel's exact source to the edge, px
        for (int k = 0; k < 3; ++k) {
          double sx, sy;
          ASSERT_TRUE(d.Source(x, y, k, &sx, &sy));
          edge = std::min({edge, std::fabs(sx + 0.5), std::fabs(sx - (kW - 0.5)), std::fabs(sy + 0.5),
                           std::fabs(sy - (kH - 0.5))});
        }
        EXPECT_LE(edge, grid_error) << "pixel " << x << "," << y << " grid step " << steps[s];
      }
  }
  EXPECT_GT(marked[1], 0u);  // a 32 px grid is far enough off to flip some edge pixels
  EXPECT_LE(marked[0], marked[1]);
}

// A sensor without a CFA stage before it is one sensor per colour: its
// reference models three planes, each with its colour's QE.
TEST(PipelineReference, ASensorWithoutACfaIsModelledPerColour) {
  constexpr int kW = 23, kH = 17;
  PipelineConfig c = test::DemoConfig(kW, kH);
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kSensor;
  c.order_count = 2;
  const Tapped t = RunTapped(c, kW, kH);
  const Pipeline& p = t.built->pipeline;
  ASSERT_EQ(p.plan().running, 2);
  const LineFormat f = p.running_format(1);
  ASSERT_EQ(f.channels, 3);
  const ref::RefImage want =
      ref::RunStageReference(p, 1, AsRef(t.out[0], p.running_format(0), kW, kH), t.scene.View());
  ASSERT_EQ(want.planes.size(), 3u);
  const ref::RefImage got = AsRef(t.out[1], f, kW, kH);
  double worst = 0;
  for (size_t k = 0; k < 3; ++k)
    for (size_t j = 0; j < want.planes[k].size(); ++j)
      worst = std::fmax(worst, std::fabs(got.planes[k][j] - want.planes[k][j]));
  EXPECT_LE(worst, 0.53);  // as EveryStageWithinItsStatedRounding's sensor
}

TEST(Tradeoff, WritesEveryKnobValueWithStageErrors) {
  const std::string dir = testing::TempDir() + "camsim_tradeoff_" + std::to_string(getpid());
  // A barrel lens: its grid steps flip different edge pixels to the fill.
  const std::string cmd = std::string(CAMSIM_BINARY) + " tradeoff --config " CAMSIM_SOURCE_DIR
                          "/configs/camera.toml --input " CAMSIM_SOURCE_DIR "/scenes/aisle_0001.exr --set sensor.width=160"
                          " --set sensor.height=120 --set distortion.model=brown --set distortion.k1=-0.1"
                          " --frames 1 --out '" + dir + "' 2>/dev/null";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  std::ifstream csv(dir + "/tradeoff.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "knob,value,configured,scope,ms_per_frame,max_abs,rms,psnr_db,unit,excluded_px,frontier");
  int end_to_end = 0, demosaic_rows = 0, frontier = 0;
  std::set<std::string> left_out;
  std::map<std::string, double> rms, own_rms;  // end to end, by "knob=value"
  while (std::getline(csv, line)) {
    std::stringstream s(line);
    std::string f[11];
    for (std::string& x : f) std::getline(s, x, ',');
    const std::string setting = f[0] + "=" + f[1];
    if (f[3] == "end_to_end") {
      ++end_to_end;
      left_out.insert(f[9]);
      frontier += f[10] == "1";
      rms[setting] = std::stod(f[6]);
    }
    if (f[3] == "end_to_end_own_model") own_rms[setting] = std::stod(f[6]);
    if (f[3] == "demosaic" && f[0] == "demosaic.method") {
      ++demosaic_rows;
      // Each stage against its own model's reference: both round once.
      EXPECT_LE(std::stod(f[5]), 0.5 + 1e-9) << line;
      EXPECT_GT(std::stod(f[4]), 0.0) << line;  // it was timed
    }
  }
  EXPECT_EQ(end_to_end, 4 + 5 + 5 + 2);  // filter, grid step, phases, demosaic.method
  ASSERT_EQ(own_rms.size(), rms.size());
  // End to end, the bilinear demosaic against the configured (Malvar) model
  // shows what the cheaper model costs; against its own, its precision.
  EXPECT_GT(rms["demosaic.method=bilinear"], 20 * own_rms["demosaic.method=bilinear"]);
  EXPECT_LT(own_rms["demosaic.method=bilinear"], 2 * rms["demosaic.method=malvar"]);
  // A knob that sets a precision, not a model: one reference.
  EXPECT_EQ(own_rms["distortion.grid_step=32"], rms["distortion.grid_step=32"]);
  EXPECT_EQ(demosaic_rows, 2);
  EXPECT_GE(frontier, 1);
  // Every setting's end-to-end error leaves out the same pixels.
  ASSERT_EQ(left_out.size(), 1u);
  EXPECT_NE(*left_out.begin(), "0");
  std::ifstream png(dir + "/tradeoff.png", std::ios::binary);
  char sig[8] = {};
  png.read(sig, 8);
  EXPECT_EQ(std::memcmp(sig, "\x89PNG\r\n\x1a\n", 8), 0);
}

}  // namespace
}  // namespace camsim
