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
  return s;
}

TEST(Golden, StageOutputsOnBundledScenes) {
  const bool update = std::getenv("CAMSIM_UPDATE_GOLDEN") != nullptr;
  std::map<std::string, std::string> expected = ReadHashes(), got;
  for (const char* scene_name : {"aisle_0001.exr", "aisle_0002.exr"}) {
    const test::Scene scene = LoadScene(scene_name);
    const PipelineConfig full = test::DemoConfig(scene.width, scene.height);
    for (int n = 1; n <= full.order_count; ++n) {
      PipelineConfig c = full;
      c.order_count = n;
      auto b = test::Build(c);
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      if (!b->pipeline.plan().entries[n - 1].runs) continue;  // identical to the previous cut
      const std::string key = std::string(scene_name) + ":" + StageName(c.order[n - 1]);
      got[key] = test::Hex64(HashSamples(test::RunFrame(*b, scene, 1, 32)));
    }
  }
  // Motion blur and rolling shutter on aisle_0002 (the camera dollies forward
  // between frames): the cut after motion_blur, from the camera's motion (with
  // the scene's depth) and from the scene's Vector pass.
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
      c.order_count = 2;  // exposure, motion_blur
      ASSERT_EQ(c.order[1], StageId::kMotionBlur);
      MotionBlurConfig& m = c.motion_blur;
      m.source = source;
      m.angular_velocity_rad_s[0] = 0.2;
      m.angular_velocity_rad_s[1] = 0.6;
      m.linear_velocity_m_s[2] = 2.0;
      m.line_time_us = 20.0;
      m.vector_fps = 50.0;  // 10 ms of the 20 ms between frames: half the vectors
      auto b = test::Build(c);
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      ASSERT_TRUE(b->pipeline.plan().entries[1].runs);
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

}  // namespace
}  // namespace camsim
