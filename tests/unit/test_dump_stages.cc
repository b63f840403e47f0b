// `camsim run --dump-stages`: each running stage's output as an EXR whose
// FLOAT channels (R, G, B or Y) hold the physical value and whose UINT
// channels (code.R, code.G, code.B or code.Y) hold the stage's uint32 line
// samples exactly, with header attributes that convert one into the other.
// float32 keeps 24 bits: Q24.8 photons above 65536 and Q16.16 radiance
// above 256 (codes above 2^24) lose their low bits in the FLOAT channels;
// the code channels must not.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStringAttribute.h>

#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/io/image_write.h"
#include "host_tools/render.h"
#include "host_tools/run.h"

namespace camsim {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 24, kHeight = 16;

// Radiance from 256 to about 660, no two samples alike: Q16.16 codes above
// 2^24, and Q24.8 photon codes far above, whose low bits float32 cannot keep
// once a stage computes them.
std::string WriteScene(const std::string& dir) {
  std::vector<float> rgb[3];
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x)
        rgb[c].push_back(256.0f + 7.31f * x + 13.77f * y + 0.4173f * c + 0.001953f * ((x * 7 + y * 3) % 11));
  const std::string path = dir + "/scene.exr";
  std::string error;
  EXPECT_TRUE(io::WriteExrFloat(path, kWidth, kHeight,
                                {{"R", rgb[0].data(), kWidth}, {"G", rgb[1].data(), kWidth}, {"B", rgb[2].data(), kWidth}},
                                &error))
      << error;
  return path;
}

// What a dump's header must say of its code channels.
struct Expected {
  const char* stage;
  const char* format;
  const char* unit;
  double scale;
  int channels;
};

struct DumpCase {
  const char* name;
  std::vector<std::string> overrides;  // --set, after configs/camera.toml
  std::vector<Expected> dumps;         // in run order
};

// Distortion's interpolated radiance (the scene's own float values convert
// to Q16.16 exactly) and the photons after it, in colour and on the demo
// camera's Bayer mosaic (distortion then samples each site's colour, in
// place of the cfa stage), and the sensor's DN.
const DumpCase kCases[] = {
    {"rgb",
     {"pipeline.stages=[\"distortion\", \"exposure\", \"vignetting\"]", "distortion.model=\"brown\"",
      "distortion.k1=-0.1"},
     {{"distortion", "radiance Q16.16", "radiance", 1.0 / 65536, 3},
      {"exposure", "photons Q24.8", "photons", 1.0 / 256, 3},
      {"vignetting", "photons Q24.8", "photons", 1.0 / 256, 3}}},
    {"mosaic",
     {"pipeline.stages=[\"distortion\", \"exposure\", \"vignetting\", \"cfa\", \"sensor\"]",
      "distortion.model=\"brown\"", "distortion.k1=-0.1"},
     {{"distortion", "radiance Q16.16", "radiance", 1.0 / 65536, 1},
      {"exposure", "photons Q24.8", "photons", 1.0 / 256, 1},
      {"vignetting", "photons Q24.8", "photons", 1.0 / 256, 1},
      {"sensor", "digital DN", "DN", 1.0, 1}}},
};

std::string TextAttribute(const Imf::Header& h, const std::string& name) {
  const auto* a = h.findTypedAttribute<Imf::StringAttribute>(name);
  return a == nullptr ? "(missing)" : a->value();
}

class DumpStages : public testing::TestWithParam<int> {};

// Every dump reads back, through OpenEXR, bit for bit as the stage's kU32
// tap of the same frame; each FLOAT channel is its code times the header's
// scale rounded to float; the header names the stage and each code
// channel's format, unit and scale.
TEST_P(DumpStages, CodeChannelsAreTheStageOutputExactly) {
  const DumpCase& dc = kCases[GetParam()];
  const std::string dir = testing::TempDir() + "camsim_dump_" + dc.name + "_" + std::to_string(getpid());
  fs::remove_all(dir);
  ASSERT_TRUE(fs::create_directories(dir));
  const std::string scene_path = WriteScene(dir);
  const std::string config = CAMSIM_SOURCE_DIR "/configs/camera.toml";

  host::RunOptions o;
  o.config_path = config;
  o.inputs = {scene_path};
  o.out_dir = dir + "/out";
  o.overrides = dc.overrides;
  o.dump_stages = true;
  o.quiet = true;
  ASSERT_EQ(host::RunCommand(o), 0);

  // The same frame (index 0) through the same configuration, every running stage tapped as kU32.
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  ASSERT_TRUE(host::LoadConfigFile(config, &rc, &origins, &error)) << error;
  for (const std::string& set : dc.overrides) ASSERT_TRUE(host::ApplyOverride(set, &rc, &origins, &error)) << error;
  io::SceneFrame scene;
  ASSERT_TRUE(io::LoadSceneExr(scene_path, "", &scene, &error)) << error;
  host::FrameRenderer renderer(1, 0);
  ASSERT_TRUE(renderer.Configure(rc, origins, scene.width, scene.height, nullptr, &error)) << error;
  ASSERT_TRUE(renderer.SetScene(scene, &error)) << error;
  const Plan& plan = renderer.pipeline().plan();
  const int w = renderer.pipeline().width(), h = renderer.pipeline().height();
  ASSERT_EQ(plan.running, static_cast<int>(dc.dumps.size()));
  for (int i = 0, r = 0; i < plan.count; ++i) {
    if (!plan.entries[i].runs) continue;
    EXPECT_STREQ(StageName(plan.entries[i].id), dc.dumps[static_cast<size_t>(r++)].stage);
  }
  std::vector<std::vector<uint32_t>> want(dc.dumps.size());
  std::vector<Tap> taps(dc.dumps.size());
  for (size_t r = 0; r < taps.size(); ++r) {
    want[r].resize(static_cast<size_t>(w) * h * dc.dumps[r].channels);
    taps[r].stage = static_cast<int>(r);
    taps[r].format = TapFormat::kU32;
    taps[r].data = want[r].data();
    taps[r].stride = static_cast<ptrdiff_t>(w) * dc.dumps[r].channels;
  }
  renderer.Render(0, taps.data(), static_cast<int>(taps.size()), nullptr);

  // Each dump, and a run's own NAME.exr (a run that ends before the sensor:
  // its last stage's output, described as the dumps are).
  std::vector<std::pair<std::string, size_t>> images;  // path, dump index
  for (size_t r = 0; r < dc.dumps.size(); ++r)
    images.push_back({o.out_dir + "/scene." + std::to_string(r) + "_" + dc.dumps[r].stage + ".exr", r});
  if (std::strcmp(dc.dumps.back().stage, "sensor") != 0) images.push_back({o.out_dir + "/scene.exr", dc.dumps.size() - 1});
  for (const auto& [path, r] : images) {
    const Expected& e = dc.dumps[r];
    size_t above_float = 0;  // codes above 2^24 that float32 does not hold
    SCOPED_TRACE(path);
    Imf::InputFile in(path.c_str());
    const Imf::Header& header = in.header();
    EXPECT_EQ(TextAttribute(header, "camsim/stage"), e.stage);
    const char* rgb[3] = {"R", "G", "B"};
    const size_t n = static_cast<size_t>(w) * h;
    for (int c = 0; c < e.channels; ++c) {
      const std::string name = e.channels == 1 ? "Y" : rgb[c], code = "code." + name;
      const Imf::Channel* fc = header.channels().findChannel(name);
      const Imf::Channel* cc = header.channels().findChannel(code);
      ASSERT_NE(fc, nullptr) << name;
      ASSERT_NE(cc, nullptr) << code << " missing";
      EXPECT_EQ(fc->type, Imf::FLOAT) << name;
      EXPECT_EQ(cc->type, Imf::UINT) << code;
      EXPECT_EQ(TextAttribute(header, "camsim/" + code + "/format"), e.format) << code;
      EXPECT_EQ(TextAttribute(header, "camsim/" + code + "/unit"), e.unit) << code;
      const auto* scale = header.findTypedAttribute<Imf::DoubleAttribute>("camsim/" + code + "/scale");
      ASSERT_NE(scale, nullptr) << code;
      EXPECT_EQ(scale->value(), e.scale) << code;

      std::vector<uint32_t> codes(n);
      std::vector<float> values(n);
      Imf::FrameBuffer fb;
      fb.insert(code, Imf::Slice(Imf::UINT, reinterpret_cast<char*>(codes.data()), 4, 4 * static_cast<size_t>(w)));
      fb.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(values.data()), 4, 4 * static_cast<size_t>(w)));
      in.setFrameBuffer(fb);
      in.readPixels(0, h - 1);
      for (size_t i = 0; i < n; ++i) {
        const uint32_t tap = want[r][i * e.channels + c];
        ASSERT_EQ(codes[i], tap) << code << " at pixel " << i;
        const float physical = static_cast<float>(codes[i] * scale->value());
        ASSERT_EQ(std::memcmp(&values[i], &physical, 4), 0)
            << name << " at pixel " << i << ": " << values[i] << ", not " << physical;
        if (static_cast<double>(static_cast<float>(tap)) != static_cast<double>(tap)) ++above_float;
      }
    }
    // The fixed-point stages do reach codes that float32 rounds (an odd
    // code in [2^24, 2^25), ...: about half of distortion's, most of the
    // photons): exactness is tested, not assumed. DN stay far below 2^24.
    if (e.scale < 1.0) {
      EXPECT_GT(above_float, static_cast<size_t>(w) * h * e.channels / 4);
    } else {
      EXPECT_EQ(above_float, 0u);
    }
  }
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Run, DumpStages, testing::Range(0, static_cast<int>(std::size(kCases))),
                         [](const testing::TestParamInfo<int>& p) { return std::string(kCases[p.param].name); });

}  // namespace
}  // namespace camsim
