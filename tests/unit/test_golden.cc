// Golden bit-exact hashes: each stage's output (the pipeline cut after it) and
// the whole pipeline on the bundled scenes with configs/camera.toml.
//
// A change that alters any output byte fails here. When the change is
// intended, regenerate and commit tests/golden/hashes.txt:
//   CAMSIM_UPDATE_GOLDEN=1 ./build/release/tests/camsim_tests --gtest_filter='Golden*'
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "host_tools/io/exr_scene.h"
#include "host_tools/scene_input.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

const char kHashFile[] = CAMSIM_SOURCE_DIR "/tests/golden/hashes.txt";

std::map<std::string, std::string> ReadHashes() {
  std::map<std::string, std::string> m;
  std::ifstream in(kHashFile);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string name, hash;
    if (fields >> name >> hash) m[name] = hash;
  }
  return m;
}

void WriteHashes(const std::map<std::string, std::string>& m) {
  std::ofstream out(kHashFile);
  out << "# FNV-1a 64 of little-endian uint32 stage outputs; see tests/unit/test_golden.cc\n";
  for (const auto& [k, v] : m) out << k << " " << v << "\n";
}

uint64_t HashSamples(const std::vector<uint32_t>& v) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (uint32_t s : v) {
    const uint8_t b[4] = {uint8_t(s), uint8_t(s >> 8), uint8_t(s >> 16), uint8_t(s >> 24)};
    h = test::Fnv1a64(b, 4, h);
  }
  return h;
}

test::Scene LoadScene(const std::string& name) {
  io::SceneFrame frame;
  std::string error;
  EXPECT_TRUE(io::LoadSceneExr(std::string(CAMSIM_SOURCE_DIR "/scenes/") + name, "", &frame, &error)) << error;
  host::CoreInput in;
  host::PrepareInput(frame, frame.width, frame.height, host::SceneFit::kCrop, &in);
  test::Scene s;
  s.width = in.width;
  s.height = in.height;
  for (int c = 0; c < 3; ++c) s.plane[c] = in.radiance[c];
  s.inverse_depth = in.inverse_depth;
  return s;
}

// Only CAMSIM_UPDATE_GOLDEN=1 rewrites the hash files (=0 or empty must not).
bool UpdateRequested() {
  const char* v = std::getenv("CAMSIM_UPDATE_GOLDEN");
  return v != nullptr && std::string(v) == "1";
}

TEST(Golden, StageOutputsOnBundledScenes) {
  const bool update = UpdateRequested();
  std::map<std::string, std::string> expected = ReadHashes(), got;
  for (const char* scene_name : {"aisle_0001.exr", "aisle_0002.exr"}) {
    const test::Scene scene = LoadScene(scene_name);
    const PipelineConfig full = test::DemoConfig(scene.width, scene.height);
    for (int n = 1; n <= full.order_count; ++n) {
      PipelineConfig c = full;
      c.order_count = n;
      auto b = test::Build(c);
      if (!b->status.ok() && b->pipeline.plan().running == 0) continue;  // a cut of only left-out stages
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      if (!b->pipeline.plan().entries[n - 1].runs) continue;  // identical to the previous cut
      const std::string key = std::string(scene_name) + ":" + StageName(c.order[n - 1]);
      got[key] = test::Hex64(HashSamples(test::RunFrame(*b, scene, 1, 32)));
    }
    // Lens distortion (a typical barrel calibration with tangential terms and
    // lateral chromatic aberration): the stage alone, then the whole demo
    // pipeline (the CFA site-only path) for each filter.
    PipelineConfig lens = full;
    LensModel& m = lens.distortion.lens;
    m.model = DistortionModel::kBrown;
    m.fx = m.fy = 0.8 * scene.width;
    m.cx = (scene.width - 1) / 2.0 + 2.5;
    m.cy = (scene.height - 1) / 2.0 - 1.75;
    m.k[0] = -0.28;
    m.k[1] = 0.07;
    m.p1 = 0.0012;
    m.p2 = -0.0007;
    lens.distortion.chromatic_scale[0] = 1.003;
    lens.distortion.chromatic_scale[2] = 0.998;
    for (ResampleFilter f : {ResampleFilter::kBilinear, ResampleFilter::kBicubic, ResampleFilter::kLanczos3, ResampleFilter::kLanczos4}) {
      static constexpr const char* kFilterNames[4] = {"bilinear", "bicubic", "lanczos3", "lanczos4"};
      lens.distortion.filter = f;
      int cut = 0;  // the order up to distortion (the scene-space stages before it are off)
      while (lens.order[cut] != StageId::kDistortion) ++cut;
      for (int n : {cut + 1, lens.order_count}) {
        PipelineConfig c = lens;
        c.order_count = n;
        auto b = test::Build(c);
        ASSERT_TRUE(b->status.ok()) << b->status.message();
        const std::string key = std::string(scene_name) + ":lens_" + kFilterNames[static_cast<int>(f)] + ":" +
                                StageName(c.order[n - 1]);
        got[key] = test::Hex64(HashSamples(test::RunFrame(*b, scene, 1, 32)));
      }
    }
  }
  // Motion blur and rolling shutter on aisle_0002 (the camera dollies forward
  // between frames): the cut after exposure (motion blur runs on radiance just
  // before it), from the camera's motion (with the scene's depth) and from the
  // scene's Vector pass.
  {
    io::SceneFrame frame;
    std::string error;
    ASSERT_TRUE(io::LoadSceneExr(CAMSIM_SOURCE_DIR "/scenes/aisle_0002.exr", "", &frame, &error)) << error;
    host::CoreInput in;
    host::PrepareInput(frame, frame.width, frame.height, host::SceneFit::kCrop, &in);
    ASSERT_FALSE(in.inverse_depth.empty());
    ASSERT_FALSE(in.motion[0].empty());
    for (const MotionSource source : {MotionSource::kCamera, MotionSource::kVectors}) {
      PipelineConfig c = test::DemoConfig(in.width, in.height);
      // Cut after exposure: the stages before it other than motion blur are off.
      int exposure = 0, motion = -1;
      for (; c.order[exposure] != StageId::kExposure; ++exposure)
        if (c.order[exposure] == StageId::kMotionBlur) motion = exposure;
      ASSERT_GE(motion, 0);
      c.order_count = exposure + 1;
      MotionBlurConfig& m = c.motion_blur;
      m.source = source;
      m.angular_velocity_rad_s[0] = 0.2;
      m.angular_velocity_rad_s[1] = 0.6;
      m.linear_velocity_m_s[2] = 2.0;
      m.line_time_us = 20.0;
      m.vector_fps = 50.0;  // 10 ms of the 20 ms between frames: half the vectors
      auto b = test::Build(c);
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      ASSERT_TRUE(b->pipeline.plan().entries[motion].runs);
      std::vector<uint32_t> out(static_cast<size_t>(in.width) * in.height * 3);
      Tap t;
      t.format = TapFormat::kU32;
      t.data = out.data();
      t.stride = static_cast<ptrdiff_t>(in.width) * 3;
      const FrameInput view = in.View();
      ASSERT_TRUE(b->pipeline.CheckInput(view).ok());
      b->pipeline.ProcessFrame(view, 1, 32, &t, 1, nullptr, nullptr);
      const std::string key = std::string("aisle_0002.exr:motion_blur.") +
                              (source == MotionSource::kCamera ? "camera" : "vectors");
      got[key] = test::Hex64(HashSamples(out));
    }
  }
  if (update) {
    WriteHashes(got);
    GTEST_SKIP() << "wrote " << got.size() << " hashes to " << kHashFile;
  }
  ASSERT_FALSE(expected.empty()) << "no golden hashes: run with CAMSIM_UPDATE_GOLDEN=1 first";
  EXPECT_EQ(got.size(), expected.size());
  for (const auto& [k, v] : got) EXPECT_EQ(v, expected[k]) << k;
}

// Depth of field and structural blur on a bundled scene (its own hash file,
// so the stage-cut hashes above stay as they are): the radiance after the
// DoF stages and the whole demo pipeline with them.
TEST(Golden, DepthOfFieldOnBundledScene) {
  const char kDofHashFile[] = CAMSIM_SOURCE_DIR "/tests/golden/dof_hashes.txt";
  const bool update = UpdateRequested();
  std::map<std::string, std::string> expected, got;
  {
    std::ifstream in(kDofHashFile);
    std::string line, name, hash;
    while (std::getline(in, line))
      if (!line.empty() && line[0] != '#' && (std::istringstream(line) >> name >> hash)) expected[name] = hash;
  }
  const test::Scene scene = LoadScene("aisle_0001.exr");
  ASSERT_FALSE(scene.inverse_depth.empty());
  struct Case {
    const char* name;
    DofMethod method;
    bool structural;
  };
  for (const Case& k : {Case{"dof_diffusion", DofMethod::kDiffusion, false}, Case{"dof_gather", DofMethod::kGather, false},
                        Case{"structural_blur", DofMethod::kOff, true}}) {
    PipelineConfig full = test::DemoConfig(scene.width, scene.height);
    full.dof.method = k.method;
    // A short focus and a wide aperture: 28 mm at f/1.4 on the demo's 56 um
    // pixels gives CoCs of 2 .. 10 px over the scene (at f/2.8 and 4 m most
    // are below the 2 px a disc needs to cover more than its centre pixel).
    full.dof.focus_distance_m = 1.0;
    full.exposure.f_number = 1.4;
    full.dof.column_window = 24;
    full.dof.max_radius_px = 8;
    if (k.structural) {
      full.dof.structural_only = true;
      full.dof.structural_poly[2] = 6.0;
    }
    for (bool whole : {false, true}) {
      PipelineConfig c = full;
      if (!whole) {
        c.order[0] = StageId::kDofGather;
        c.order[1] = StageId::kDofRows;
        c.order[2] = StageId::kDofColumns;
        c.order_count = 3;
      }
      auto b = test::Build(c);
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      ASSERT_TRUE(b->pipeline.CheckInput(scene.View()).ok());
      got[std::string("aisle_0001.exr:") + k.name + (whole ? "+pipeline" : "")] =
          test::Hex64(HashSamples(test::RunFrame(*b, scene, 1, 32)));
    }
  }
  if (update) {
    std::ofstream out(kDofHashFile);
    out << "# FNV-1a 64 of little-endian uint32 outputs with depth of field; see tests/unit/test_golden.cc\n";
    for (const auto& [key, v] : got) out << key << " " << v << "\n";
    GTEST_SKIP() << "wrote " << got.size() << " hashes to " << kDofHashFile;
  }
  ASSERT_EQ(got.size(), expected.size()) << "run with CAMSIM_UPDATE_GOLDEN=1 to write " << kDofHashFile;
  for (const auto& [key, v] : got) EXPECT_EQ(v, expected[key]) << key;
}

}  // namespace
}  // namespace camsim
