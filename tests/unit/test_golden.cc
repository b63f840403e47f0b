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
      // A cut whose every stage is left out (only flare, off) has no output.
      if (!b->status.ok() && std::string(b->status.message()) == "every listed stage was left out") continue;
      ASSERT_TRUE(b->status.ok()) << b->status.message();
      if (!b->pipeline.plan().entries[n - 1].runs) continue;  // identical to the previous cut
      const std::string key = std::string(scene_name) + ":" + StageName(c.order[n - 1]);
      got[key] = test::Hex64(HashSamples(test::RunFrame(*b, scene, 1, 32)));
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
