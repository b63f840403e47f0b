// Tests for camsim_io: EXR scene loading, writers, mask readers, input expansion.
#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDeepFrameBuffer.h>
#include <OpenEXR/ImfDeepScanLineOutputFile.h>
#include <OpenEXR/ImfDeepScanLineOutputPart.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/openexr.h>
#include <png.h>
#include <zlib.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/support/exr_fixture.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/io/image_read.h"
#include "host_tools/io/image_write.h"
#include "host_tools/io/sequence.h"
#include "host_tools/io/text_read.h"

namespace camsim::io {
namespace {

namespace fs = std::filesystem;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
const std::string kAisle = CAMSIM_SOURCE_DIR "/scenes/aisle_0001.exr";

// A fresh directory per test, removed afterwards.
class IoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static int counter = 0;
    dir_ = fs::path(::testing::TempDir()) /
           ("camsim_io_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(dir_);
    ASSERT_TRUE(fs::create_directories(dir_));
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::vector<std::string> DirEntries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  fs::path dir_;
};

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

using test::Box;
using TestChannel = test::ExrChannel;

void WriteTestExr(const std::string& path, const Imath::Box2i& display, const Imath::Box2i& data,
                  const std::vector<TestChannel>& channels) {
  test::WriteExrFixture(path, display, data, channels);
}

// ---- LoadSceneExr ---------------------------------------------------------

TEST(LoadSceneExr, BundledBlenderScene) {
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(kAisle, "", &f, &error)) << error;
  EXPECT_EQ(f.width, 640);
  EXPECT_EQ(f.height, 480);
  EXPECT_EQ(f.layout, "blender-multilayer ViewLayer");
  EXPECT_EQ(f.source, kAisle);
  ASSERT_TRUE(f.has_depth);
  ASSERT_TRUE(f.has_motion);
  for (const FloatPlane* p : {&f.r, &f.g, &f.b, &f.depth, &f.motion_x, &f.motion_y}) {
    ASSERT_EQ(p->width, 640);
    ASSERT_EQ(p->height, 480);
    ASSERT_EQ(p->data.size(), 640u * 480u);
  }
  float sky = 0.0f;  // sky is 1e10 in Blender's Z pass
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 640; ++x) sky = std::max(sky, f.depth.at(x, y));
  }
  EXPECT_GT(sky, 1e9f);
  float peak = 0.0f;
  for (const FloatPlane* p : {&f.r, &f.g, &f.b}) {
    for (float v : p->data) {
      ASSERT_TRUE(std::isfinite(v));
      ASSERT_GE(v, 0.0f);
      peak = std::max(peak, v);
    }
  }
  EXPECT_GT(peak, 100.0f);  // the emissive lamp, radiance ~400
  EXPECT_LT(peak, 65504.0f);
  // Motion vectors (Vector.X, Y: towards the previous frame) are finite (NaN
  // would slip past std::max). The first frame has no previous one: ~0. The
  // second moves the scene along both axes (the camera dollies forward).
  SceneFrame second;
  ASSERT_TRUE(LoadSceneExr(std::string(CAMSIM_SOURCE_DIR) + "/scenes/aisle_0002.exr", "", &second, &error)) << error;
  ASSERT_TRUE(second.has_motion);
  for (const SceneFrame* s : {&f, &second})
    for (const FloatPlane* p : {&s->motion_x, &s->motion_y}) {
      float max_motion = 0.0f;
      for (float v : p->data) {
        ASSERT_TRUE(std::isfinite(v));
        max_motion = std::max(max_motion, std::abs(v));
      }
      const bool x = p == &s->motion_x;
      if (s == &f) {
        EXPECT_LT(max_motion, 0.01f) << (x ? "x" : "y");
      } else {
        RecordProperty(x ? "max_motion_x_px" : "max_motion_y_px", std::to_string(max_motion));
        EXPECT_GT(max_motion, 0.5f) << (x ? "x" : "y");
        EXPECT_LT(max_motion, 640.0f) << (x ? "x" : "y");
      }
    }
}

TEST_F(IoTest, FloatRoundTripSanitises) {
  // 3x2 frame; R, G, B, Z with planted bad values.
  const std::vector<float> r = {kNaN, 1.0f, -kInf, 0.25f, 2.0f, 1e6f};
  const std::vector<float> g = {-1.0f, 0.5f, 0.0f, -0.0f, kInf, 3.0f};
  const std::vector<float> b = {kInf, kInf, 0.125f, 400.0f, -2.0f, kNaN};
  const std::vector<float> z = {kNaN, -1.0f, 0.0f, 1e10f, kInf, -kInf};
  const std::string path = Path("rgbz.exr");
  std::string error;
  ASSERT_TRUE(WriteExrFloat(path, 3, 2,
                            {{"R", r.data(), 3}, {"G", g.data(), 3}, {"B", b.data(), 3},
                             {"Z", z.data(), 3}},
                            &error))
      << error;
  SceneFrame f;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.layout, "rgb+z");
  EXPECT_FALSE(f.has_motion);
  EXPECT_EQ(f.r.data, (std::vector<float>{0.0f, 1.0f, 0.0f, 0.25f, 2.0f, 1e6f}));
  EXPECT_EQ(f.g.data, (std::vector<float>{0.0f, 0.5f, 0.0f, 0.0f, 65504.0f, 3.0f}));
  EXPECT_EQ(f.b.data, (std::vector<float>{65504.0f, 65504.0f, 0.125f, 400.0f, 0.0f, 0.0f}));
  EXPECT_EQ(f.radiance_stats.nan, 2u);
  EXPECT_EQ(f.radiance_stats.pos_inf, 3u);
  EXPECT_EQ(f.radiance_stats.neg_inf, 1u);
  EXPECT_EQ(f.radiance_stats.negative, 2u);  // -1 and -2; -0.0 is not negative
  ASSERT_TRUE(f.has_depth);
  EXPECT_EQ(f.depth.data, (std::vector<float>{kInf, -1.0f, 0.0f, 1e10f, kInf, -kInf}));
  EXPECT_EQ(f.depth_stats.nan, 1u);
  EXPECT_EQ(f.depth_stats.pos_inf, 1u);
  EXPECT_EQ(f.depth_stats.neg_inf, 1u);
  EXPECT_EQ(f.depth_stats.negative, 1u);
}

// The stats keep the first sample replaced (topmost row, then leftmost; at a
// tie the channel read first), motion is counted too, and the file gets one
// warning line saying so.
TEST_F(IoTest, SanitiseStatsKeepTheFirstSampleReplaced) {
  // 4x3 frame. Replaced: R (3,1) NaN; G (2,1) +inf, (0,2) -1; B (2,1) NaN;
  // Z (3,2) NaN (its -2 at (1,0) is counted but kept); Vector.X (1,2) +inf;
  // Vector.Y (3,1) NaN, (0,2) -inf.
  std::vector<float> r(12, 1.0f), g = r, b = r, z(12, 5.0f), vx(12, 0.5f), vy = vx;
  r[4 + 3] = kNaN;
  g[4 + 2] = kInf;
  g[8 + 0] = -1.0f;
  b[4 + 2] = kNaN;
  z[0 + 1] = -2.0f;
  z[8 + 3] = kNaN;
  vx[8 + 1] = kInf;
  vy[4 + 3] = kNaN;
  vy[8 + 0] = -kInf;
  const std::string path = Path("bad.exr");
  std::string error;
  ASSERT_TRUE(WriteExrFloat(path, 4, 3,
                            {{"R", r.data(), 4}, {"G", g.data(), 4}, {"B", b.data(), 4}, {"Z", z.data(), 4},
                             {"Vector.X", vx.data(), 4}, {"Vector.Y", vy.data(), 4}},
                            &error))
      << error;
  SceneFrame f;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.radiance_stats.nan, 2u);
  EXPECT_EQ(f.radiance_stats.pos_inf, 1u);
  EXPECT_EQ(f.radiance_stats.negative, 1u);
  EXPECT_EQ(f.radiance_stats.first_channel, "G");  // before R's (3,1); B's (2,1) is read after it
  EXPECT_EQ(f.radiance_stats.first_x, 2);
  EXPECT_EQ(f.radiance_stats.first_y, 1);
  EXPECT_EQ(f.depth_stats.first_channel, "Z");  // the NaN, not the -2 that was kept
  EXPECT_EQ(f.depth_stats.first_x, 3);
  EXPECT_EQ(f.depth_stats.first_y, 2);
  ASSERT_TRUE(f.has_motion);
  EXPECT_EQ(f.motion_stats.nan, 1u);
  EXPECT_EQ(f.motion_stats.pos_inf, 1u);
  EXPECT_EQ(f.motion_stats.neg_inf, 1u);
  EXPECT_EQ(f.motion_stats.negative, 0u);  // negative motion is motion
  EXPECT_EQ(f.motion_stats.first_channel, "Vector.Y");
  EXPECT_EQ(f.motion_stats.first_x, 3);
  EXPECT_EQ(f.motion_stats.first_y, 1);
  EXPECT_EQ(f.motion_x.at(1, 2), 0.0f);
  EXPECT_EQ(f.motion_y.at(0, 2), 0.0f);
  EXPECT_EQ(f.warnings,
            std::vector<std::string>{"'" + path +
                                     "': 2 NaN, 1 +inf, 1 negative colour samples replaced (first: channel G at x=2, "
                                     "y=1); 1 NaN depth sample replaced by +inf (first: channel Z at x=3, y=2); 1 NaN, "
                                     "1 +inf, 1 -inf motion samples replaced by 0 (first: channel Vector.Y at x=3, "
                                     "y=1)"});

  // Pixels count from the display window's top-left; a clean file has no warning.
  const std::string offset = Path("offset.exr"), clean = Path("clean.exr");
  WriteTestExr(offset, Box(10, 20, 13, 22), Box(11, 21, 12, 22), {{"Y", Imf::FLOAT, {1, kNaN, 3, 4}}});
  ASSERT_TRUE(LoadSceneExr(offset, "", &f, &error)) << error;
  EXPECT_EQ(f.warnings, std::vector<std::string>{"'" + offset + "': 1 NaN colour sample replaced (first: "
                                                 "channel Y at x=2, y=1)"});
  WriteTestExr(clean, Box(0, 0, 1, 0), Box(0, 0, 1, 0), {{"Y", Imf::FLOAT, {1, 2}}});
  ASSERT_TRUE(LoadSceneExr(clean, "", &f, &error)) << error;
  EXPECT_TRUE(f.warnings.empty());
  EXPECT_TRUE(f.radiance_stats.first_channel.empty());
}

// Blender writes the compositor's output as a layer "Composite" beside the
// view layers; it sorts first, but colour comes from the view layer, which
// holds the depth and motion that go with it.
TEST_F(IoTest, BlenderCompositeLayerComesLast) {
  const std::vector<float> one = {1.0f, 1.0f}, half = {0.5f, 0.5f}, z = {2.0f, 3.0f}, v = {0.25f, -0.25f};
  const std::string path = Path("composite.exr");
  std::string error;
  ASSERT_TRUE(WriteExrFloat(path, 2, 1,
                            {{"Composite.Combined.R", half.data(), 2},
                             {"Composite.Combined.G", half.data(), 2},
                             {"Composite.Combined.B", half.data(), 2},
                             {"ViewLayer.Combined.R", one.data(), 2},
                             {"ViewLayer.Combined.G", one.data(), 2},
                             {"ViewLayer.Combined.B", one.data(), 2},
                             {"ViewLayer.Depth.Z", z.data(), 2},
                             {"ViewLayer.Vector.X", v.data(), 2},
                             {"ViewLayer.Vector.Y", v.data(), 2}},
                            &error))
      << error;
  SceneFrame f;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.layout, "blender-multilayer ViewLayer");
  EXPECT_EQ(f.r.data, one);
  ASSERT_TRUE(f.has_depth);
  EXPECT_EQ(f.depth.data, z);
  EXPECT_TRUE(f.has_motion);
  // Only a Composite layer: it is the colour.
  const std::string only = Path("composite_only.exr");
  ASSERT_TRUE(WriteExrFloat(only, 2, 1,
                            {{"Composite.Combined.R", half.data(), 2},
                             {"Composite.Combined.G", half.data(), 2},
                             {"Composite.Combined.B", half.data(), 2}},
                            &error))
      << error;
  ASSERT_TRUE(LoadSceneExr(only, "", &f, &error)) << error;
  EXPECT_EQ(f.layout, "blender-multilayer Composite");
  EXPECT_EQ(f.r.data, half);
}

TEST_F(IoTest, HalfChannelsAndUintDepth) {
  const std::string path = Path("half.exr");
  WriteTestExr(path, Box(0, 0, 1, 0), Box(0, 0, 1, 0),
               {{"R", Imf::HALF, {0.5f, 1000.0f}},
                {"G", Imf::HALF, {2.0f, 0.0f}},
                {"B", Imf::HALF, {0.25f, 65504.0f}},
                {"A", Imf::HALF, {1.0f, 1.0f}},
                {"Z", Imf::UINT, {7.0f, 12.0f}}});
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.layout, "rgba+z");
  EXPECT_EQ(f.r.data, (std::vector<float>{0.5f, 1000.0f}));
  EXPECT_EQ(f.g.data, (std::vector<float>{2.0f, 0.0f}));
  EXPECT_EQ(f.b.data, (std::vector<float>{0.25f, 65504.0f}));
  EXPECT_EQ(f.depth.data, (std::vector<float>{7.0f, 12.0f}));
}

TEST_F(IoTest, LuminanceOnly) {
  const std::string path = Path("y.exr");
  WriteTestExr(path, Box(0, 0, 2, 0), Box(0, 0, 2, 0), {{"Y", Imf::HALF, {0.5f, -1.0f, 3.0f}}});
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.layout, "y");
  const std::vector<float> want = {0.5f, 0.0f, 3.0f};
  EXPECT_EQ(f.r.data, want);
  EXPECT_EQ(f.g.data, want);
  EXPECT_EQ(f.b.data, want);
  EXPECT_EQ(f.radiance_stats.negative, 1u);
  EXPECT_FALSE(f.has_depth);
}

TEST_F(IoTest, SeparateDepthFile) {
  const std::string colour = Path("rgb.exr"), depth = Path("depth.exr"), sole = Path("sole.exr"),
                    small = Path("small.exr");
  const std::vector<float> ones(6, 1.0f);
  WriteTestExr(colour, Box(0, 0, 2, 1), Box(0, 0, 2, 1),
               {{"R", Imf::FLOAT, ones}, {"G", Imf::FLOAT, ones}, {"B", Imf::FLOAT, ones},
                {"Z", Imf::FLOAT, std::vector<float>(6, 99.0f)}});
  WriteTestExr(depth, Box(0, 0, 2, 1), Box(0, 0, 2, 1),
               {{"R", Imf::FLOAT, std::vector<float>(6, 5.0f)},
                {"Z", Imf::FLOAT, {1, 2, 3, 4, kNaN, 6}}});
  WriteTestExr(sole, Box(0, 0, 2, 1), Box(0, 0, 2, 1),
               {{"distance", Imf::HALF, {8, 8, 8, 8, 8, 8}}});
  WriteTestExr(small, Box(0, 0, 1, 1), Box(0, 0, 1, 1), {{"Z", Imf::FLOAT, {1, 1, 1, 1}}});

  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(colour, depth, &f, &error)) << error;
  EXPECT_EQ(f.layout, "rgb + separate depth");  // the colour file's own Z is not used
  EXPECT_EQ(f.source, colour + " + " + depth);
  ASSERT_TRUE(f.has_depth);
  EXPECT_EQ(f.depth.data, (std::vector<float>{1, 2, 3, 4, kInf, 6}));
  EXPECT_EQ(f.depth_stats.nan, 1u);
  // The warning names the depth file, not the colour file.
  EXPECT_EQ(f.warnings, std::vector<std::string>{"'" + depth + "': 1 NaN depth sample replaced by +inf (first: "
                                                 "channel Z at x=1, y=1)"});

  ASSERT_TRUE(LoadSceneExr(colour, sole, &f, &error)) << error;
  EXPECT_EQ(f.depth.data, std::vector<float>(6, 8.0f));

  SceneFrame untouched;
  EXPECT_FALSE(LoadSceneExr(colour, small, &untouched, &error));
  EXPECT_NE(error.find("2x2"), std::string::npos) << error;
  EXPECT_NE(error.find("3x2"), std::string::npos) << error;
  EXPECT_NE(error.find(small), std::string::npos) << error;
  EXPECT_EQ(untouched.width, 0);

  EXPECT_FALSE(LoadSceneExr(colour, Path("missing_depth.exr"), &f, &error));
  EXPECT_NE(error.find("missing_depth.exr"), std::string::npos) << error;
}

TEST_F(IoTest, DataWindowInsideDisplayWindow) {
  // Display window 4x3 at origin (10,20); data window 2x2 at (11,21).
  const std::string path = Path("window.exr");
  WriteTestExr(path, Box(10, 20, 13, 22), Box(11, 21, 12, 22),
               {{"R", Imf::HALF, {1, 2, 3, 4}},
                {"G", Imf::HALF, {1, 2, 3, 4}},
                {"B", Imf::HALF, {1, 2, 3, 4}},
                {"Z", Imf::FLOAT, {5, 6, 7, 8}}});
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  ASSERT_EQ(f.width, 4);
  ASSERT_EQ(f.height, 3);
  EXPECT_EQ(f.r.data, (std::vector<float>{0, 0, 0, 0, 0, 1, 2, 0, 0, 3, 4, 0}));
  EXPECT_EQ(f.b.data, f.r.data);
  EXPECT_EQ(f.depth.data, (std::vector<float>{kInf, kInf, kInf, kInf, kInf, 5, 6, kInf, kInf, 7,
                                              8, kInf}));
  EXPECT_EQ(f.depth_stats.pos_inf, 0u);  // filled pixels are not counted
}

TEST_F(IoTest, DataOutsideDisplayWindowIsDropped) {
  // Display 2x2 at (0,0); data 3x3 at (-1,-1), so one row and column are dropped.
  const std::string path = Path("overscan.exr");
  const std::vector<float> v = {kNaN, kNaN, kNaN, kNaN, 1, 2, kNaN, 3, 4};
  WriteTestExr(path, Box(0, 0, 1, 1), Box(-1, -1, 1, 1),
               {{"R", Imf::FLOAT, v}, {"G", Imf::FLOAT, v}, {"B", Imf::FLOAT, v}});
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.r.data, (std::vector<float>{1, 2, 3, 4}));
  EXPECT_EQ(f.radiance_stats.nan, 0u);  // the NaNs were all outside
}

TEST_F(IoTest, TallDataWindowReadInSeveralStrips) {
  // 4096 wide: the reader takes 256 rows per strip, so this needs three strips;
  // the data window sticks out 5 rows above and below.
  const int w = 4096, h = 600;
  std::vector<float> v;
  for (int y = -5; y < h + 5; ++y) {
    for (int x = 0; x < w; ++x) v.push_back(static_cast<float>(y * w + x));
  }
  const std::string path = Path("tall.exr");
  WriteTestExr(path, Box(0, 0, w - 1, h - 1), Box(0, -5, w - 1, h + 4), {{"Y", Imf::FLOAT, v}});
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  ASSERT_EQ(f.g.data.size(), static_cast<size_t>(w * h));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) ASSERT_EQ(f.g.at(x, y), static_cast<float>(y * w + x)) << x << "," << y;
  }
  EXPECT_EQ(f.radiance_stats.negative, 0u);  // the negative rows above were dropped
}

TEST_F(IoTest, MultiPartFile) {
  const std::string path = Path("multi.exr");
  {
    std::vector<Imf::Header> headers(2, Imf::Header(2, 1));
    headers[0].setName("depth");
    headers[0].setType(Imf::SCANLINEIMAGE);
    headers[0].channels().insert("Z", Imf::Channel(Imf::FLOAT));
    headers[1].setName("beauty");
    headers[1].setType(Imf::SCANLINEIMAGE);
    for (const char* c : {"R", "G", "B"}) headers[1].channels().insert(c, Imf::Channel(Imf::FLOAT));
    Imf::MultiPartOutputFile file(path.c_str(), headers.data(), 2);
    float z[2] = {3, 4}, rgb[2] = {0.5f, 0.75f};
    Imf::FrameBuffer fb0, fb1;
    fb0.insert("Z", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(z), 4, 8));
    for (const char* c : {"R", "G", "B"}) {
      fb1.insert(c, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(rgb), 4, 8));
    }
    Imf::OutputPart p0(file, 0), p1(file, 1);
    p0.setFrameBuffer(fb0);
    p0.writePixels(1);
    p1.setFrameBuffer(fb1);
    p1.writePixels(1);
  }
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.layout, "rgb+z (multi-part, colour in part 1)");
  EXPECT_EQ(f.g.data, (std::vector<float>{0.5f, 0.75f}));
  EXPECT_EQ(f.depth.data, (std::vector<float>{3, 4}));
}

// Deep parts are skipped; a file of deep parts only, and one OpenEXR 3.1's
// header check refuses, are errors that say why.
TEST_F(IoTest, DeepPartsAreSkippedOrNamed) {
  const Imath::Box2i window = Box(0, 0, 1, 0);
  unsigned counts[2] = {1, 1};
  float samples[2] = {1, 1}, flat[2] = {0.5f, 0.75f};
  float* sample_at[2] = {&samples[0], &samples[1]};
  auto deep_header = [&] {
    Imf::Header h(window, window);
    h.compression() = Imf::ZIPS_COMPRESSION;  // deep files take no block compression
    for (const char* c : {"R", "G", "B"}) h.channels().insert(c, Imf::Channel(Imf::FLOAT));
    h.setType(Imf::DEEPSCANLINE);
    h.setName("deep");
    h.setVersion(1);
    return h;
  };
  auto write_deep = [&](auto& target) {
    Imf::DeepFrameBuffer fb;
    fb.insertSampleCountSlice(Imf::Slice(Imf::UINT, reinterpret_cast<char*>(counts), 4, 8));
    for (const char* c : {"R", "G", "B"})
      fb.insert(c, Imf::DeepSlice(Imf::FLOAT, reinterpret_cast<char*>(sample_at), sizeof(float*), 2 * sizeof(float*), 4));
    target.setFrameBuffer(fb);
    target.writePixels(1);
  };
  auto write_mixed = [&](const std::string& path, bool flat_version) {
    Imf::Header flat_header(window, window);
    for (const char* c : {"R", "G", "B"}) flat_header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    flat_header.setType(Imf::SCANLINEIMAGE);
    flat_header.setName("flat");
    if (flat_version) flat_header.setVersion(1);
    std::vector<Imf::Header> headers = {deep_header(), flat_header};
    Imf::MultiPartOutputFile file(path.c_str(), headers.data(), 2);
    Imf::DeepScanLineOutputPart deep(file, 0);
    write_deep(deep);
    Imf::OutputPart part(file, 1);
    Imf::FrameBuffer fb;
    for (const char* c : {"R", "G", "B"}) fb.insert(c, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(flat), 4, 8));
    part.setFrameBuffer(fb);
    part.writePixels(1);
  };
  SceneFrame f;
  std::string error;
  write_mixed(Path("mixed.exr"), true);
  ASSERT_TRUE(LoadSceneExr(Path("mixed.exr"), "", &f, &error)) << error;
  EXPECT_EQ(f.layout, "rgb (multi-part, colour in part 1)");
  EXPECT_EQ(f.r.data, (std::vector<float>{0.5f, 0.75f}));
  write_mixed(Path("no_version.exr"), false);
  EXPECT_FALSE(LoadSceneExr(Path("no_version.exr"), "", &f, &error));
  EXPECT_NE(error.find("'version' attribute for deep file not found"), std::string::npos) << error;
  {
    Imf::DeepScanLineOutputFile file(Path("deep.exr").c_str(), deep_header());
    write_deep(file);
  }
  EXPECT_FALSE(LoadSceneExr(Path("deep.exr"), "", &f, &error));
  EXPECT_NE(error.find("1 deep part(s) skipped: deep images are not supported"), std::string::npos) << error;
}

TEST_F(IoTest, LoadErrors) {
  SceneFrame f;
  std::string error;
  const std::string missing = Path("nope.exr");
  EXPECT_FALSE(LoadSceneExr(missing, "", &f, &error));
  EXPECT_NE(error.find(missing), std::string::npos) << error;

  const std::string garbage = Path("garbage.exr");
  WriteBytes(garbage, std::string(5000, 'x'));
  EXPECT_FALSE(LoadSceneExr(garbage, "", &f, &error));
  EXPECT_NE(error.find(garbage), std::string::npos) << error;
  EXPECT_NE(error.find("not a readable OpenEXR file"), std::string::npos) << error;

  const std::string truncated = Path("truncated.exr");
  WriteBytes(truncated, ReadBytes(kAisle).substr(0, 10000));
  EXPECT_FALSE(LoadSceneExr(truncated, "", &f, &error));
  EXPECT_NE(error.find(truncated), std::string::npos) << error;
  EXPECT_NE(error.find("not a readable OpenEXR file"), std::string::npos) << error;

  const std::string alpha = Path("alpha.exr");
  WriteTestExr(alpha, Box(0, 0, 0, 0), Box(0, 0, 0, 0), {{"A", Imf::HALF, {1.0f}}});
  EXPECT_FALSE(LoadSceneExr(alpha, "", &f, &error));
  EXPECT_NE(error.find(alpha), std::string::npos) << error;
  EXPECT_NE(error.find("channels present: A"), std::string::npos) << error;

  const std::string huge = Path("huge.exr");  // 20000 x 1 display window, 1 pixel of data
  const std::vector<float> one = {1.0f};
  WriteTestExr(huge, Box(0, 0, 19999, 0), Box(0, 0, 0, 0),
               {{"R", Imf::HALF, one}, {"G", Imf::HALF, one}, {"B", Imf::HALF, one}});
  EXPECT_FALSE(LoadSceneExr(huge, "", &f, &error));
  EXPECT_NE(error.find(huge), std::string::npos) << error;
  EXPECT_NE(error.find("16384"), std::string::npos) << error;

  EXPECT_FALSE(LoadSceneExr(dir_.string(), "", &f, &error));
  EXPECT_NE(error.find("directory"), std::string::npos) << error;
  EXPECT_EQ(f.width, 0);  // never touched by a failed load
}

// The chunks of a single-part scanline or one-level tiled file, in file
// order; *tiled says which.
void ChunkInfos(const std::string& path, std::vector<exr_chunk_info_t>* out, bool* tiled_out) {
  exr_context_t ctx = nullptr;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  ASSERT_EQ(exr_start_read(&ctx, path.c_str(), &init), EXR_ERR_SUCCESS);
  int32_t count = 0, lines = 1, tile_w = 1, tile_h = 1;
  exr_storage_t storage = EXR_STORAGE_SCANLINE;
  exr_attr_box2i_t dw{};
  exr_get_chunk_count(ctx, 0, &count);
  exr_get_storage(ctx, 0, &storage);
  exr_get_data_window(ctx, 0, &dw);
  const bool tiled = storage == EXR_STORAGE_TILED;
  if (tiled) {
    exr_get_tile_sizes(ctx, 0, 0, 0, &tile_w, &tile_h);
  } else {
    exr_get_scanlines_per_chunk(ctx, 0, &lines);
  }
  const int tiles_x = (dw.max.x - dw.min.x + tile_w) / tile_w;
  std::vector<exr_chunk_info_t> chunks(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    exr_chunk_info_t& c = chunks[static_cast<size_t>(i)];
    EXPECT_EQ(tiled ? exr_read_tile_chunk_info(ctx, 0, i % tiles_x, i / tiles_x, 0, 0, &c)
                    : exr_read_scanline_chunk_info(ctx, 0, dw.min.y + i * lines, &c),
              EXR_ERR_SUCCESS);
  }
  exr_finish(&ctx);
  *out = chunks;
  *tiled_out = tiled;
}

// Gives chunk `index` (in file order) of a single-part scanline or one-level
// tiled file `data` in place of its own. The rest stays valid: the chunk's
// size field and the offsets of the chunks after it are changed to match.
void ReplaceChunkData(const std::string& path, int index, const std::string& data) {
  std::vector<exr_chunk_info_t> chunks;
  bool tiled = false;
  ASSERT_NO_FATAL_FAILURE(ChunkInfos(path, &chunks, &tiled));

  // The offset table: where each chunk starts (its header before the data).
  const uint64_t chunk_header = tiled ? 20 : 8;
  auto u64 = [](uint64_t v) {
    std::string b(8, '\0');
    for (int i = 0; i < 8; ++i) b[static_cast<size_t>(i)] = static_cast<char>(v >> (8 * i));
    return b;
  };
  std::string table;
  for (const exr_chunk_info_t& c : chunks) table += u64(c.data_offset - chunk_header);
  std::string bytes = ReadBytes(path);
  const size_t at = bytes.find(table);
  ASSERT_NE(at, std::string::npos);
  const exr_chunk_info_t& target = chunks[static_cast<size_t>(index)];
  ASSERT_LE(data.size(), target.packed_size);
  const uint64_t shrink = target.packed_size - data.size();
  for (size_t i = 0; i < chunks.size(); ++i) {
    if (chunks[i].data_offset > target.data_offset)
      bytes.replace(at + 8 * i, 8, u64(chunks[i].data_offset - chunk_header - shrink));
  }
  bytes.replace(target.data_offset - 4, 4, u64(data.size()).substr(0, 4));
  bytes.replace(target.data_offset, target.packed_size, data);
  WriteBytes(path, bytes);
}

// OpenEXR 3.1's C++ reader does not check that a chunk decompresses to the
// size its rows need: the rows of a short ZIP chunk came from uninitialised
// memory and the load succeeded.
TEST_F(IoTest, ChunkOfTheWrongSizeIsAnError) {
  const std::string zip16("\x78\x9c\x63\x60\x40\x05\x00\x00\x10\x00\x01", 11);  // zlib: 16 zero bytes
  std::vector<float> v(8 * 40);
  for (size_t i = 0; i < v.size(); ++i) v[i] = 0.37f * static_cast<float>(i % 29);
  struct Case {
    const char* name;
    Imf::Compression compression;
    bool tiled;
    int chunk;
    std::string want;
  };
  const Case cases[] = {
      // 16 rows a chunk, 512 bytes
      {"zip.exr", Imf::ZIP_COMPRESSION, false, 1, "corrupt chunk at scan line 16 ("},
      // 4 x 4 tiles (2 a row), 64 bytes
      {"zip_tiled.exr", Imf::ZIP_COMPRESSION, true, 5, "corrupt chunk at tile (1, 2) ("},
      // 1 row a chunk, 32 bytes, given 11
      {"none.exr", Imf::NO_COMPRESSION, false, 3, "corrupt chunk at scan line 3 (11 bytes where its rows need 32)"},
  };
  for (const Case& c : cases) {
    const std::string path = Path(c.name);
    test::WriteExrFixture(path, Box(0, 0, 7, 39), Box(0, 0, 7, 39), {{"Y", Imf::FLOAT, v}}, c.compression, c.tiled);
    SceneFrame f;
    std::string error;
    ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
    ReplaceChunkData(path, c.chunk, zip16);
    SceneFrame untouched;
    EXPECT_FALSE(LoadSceneExr(path, "", &untouched, &error)) << c.name;
    EXPECT_EQ(error.rfind("'" + path + "' is not a readable OpenEXR file: " + c.want, 0), 0u) << error;
    EXPECT_EQ(untouched.width, 0);
    FloatPlane mask;  // every reader checks the chunks
    EXPECT_FALSE(ReadMaskImage(path, &mask, &error)) << c.name;
    EXPECT_NE(error.find(c.want), std::string::npos) << error;
  }
}

// A file of many chunks is checked on several threads; the error still names
// the first bad chunk in file order, however the threads ran.
TEST_F(IoTest, TheFirstBadChunkIsNamedWhateverTheThreads) {
  const std::string zip16("\x78\x9c\x63\x60\x40\x05\x00\x00\x10\x00\x01", 11);  // zlib: 16 zero bytes
  constexpr int kRows = 200;  // ZIPS: one row a chunk, 32 bytes
  std::vector<float> v(8 * kRows);
  for (size_t i = 0; i < v.size(); ++i) v[i] = 0.37f * static_cast<float>(i % 29);
  const std::string path = Path("many.exr");
  test::WriteExrFixture(path, Box(0, 0, 7, kRows - 1), Box(0, 0, 7, kRows - 1), {{"Y", Imf::FLOAT, v}},
                        Imf::ZIPS_COMPRESSION, false);
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  EXPECT_EQ(f.r.data.size(), v.size());
  ReplaceChunkData(path, 170, zip16);
  ReplaceChunkData(path, 150, zip16);
  for (int round = 0; round < 20; ++round) {
    SceneFrame g;
    ASSERT_FALSE(LoadSceneExr(path, "", &g, &error));
    ASSERT_EQ(error.rfind("'" + path + "' is not a readable OpenEXR file: corrupt chunk at scan line 150 (", 0), 0u)
        << error;
  }
}

// ---- DWAA/DWAB chunks -----------------------------------------------------
// OpenEXRCore 3.1 cannot decode DWA; Imf 3.1's DWA decoder does not check its
// sections against the rows: a zlib section (the float depth) that inflated
// short, or a DC count smaller than the blocks, gave rows of uninitialised
// memory (valgrind) and the load succeeded. A DWA chunk: eleven little-endian
// uint64 sizes (version, zlib raw and packed, AC packed, DC packed, RLE
// packed, RLE'd and raw, AC count, DC count, AC compression), the channel
// rules (a uint16 size, itself included), then the zlib, AC, DC and RLE
// sections.
struct DwaChunk {
  enum Field { kVersion, kZlibRaw, kZlibSize, kAcSize, kDcSize, kRleSize, kRleRle, kRleRaw, kAcCount, kDcCount };
  std::string head;  // the sizes and the rules
  std::string zlib, ac, dc, rle;

  uint64_t Get(Field f) const {
    uint64_t v = 0;
    for (int b = 7; b >= 0; --b) v = (v << 8) | static_cast<unsigned char>(head[8 * f + b]);
    return v;
  }
  void Set(Field f, uint64_t v) {
    for (int b = 0; b < 8; ++b) head[8 * f + b] = static_cast<char>(v >> (8 * b));
  }
  std::string Raw() const { return head + zlib + ac + dc + rle; }
  // The sections given, with their sizes in the header.
  std::string Bytes() {
    Set(kZlibSize, zlib.size());
    Set(kAcSize, ac.size());
    Set(kDcSize, dc.size());
    Set(kRleSize, rle.size());
    return Raw();
  }
};

// Chunk `index` (file order) of a single-part scanline or one-level tiled DWA file.
DwaChunk ReadDwaChunk(const std::string& path, int index) {
  std::vector<exr_chunk_info_t> chunks;
  bool tiled = false;
  ChunkInfos(path, &chunks, &tiled);
  const exr_chunk_info_t& c = chunks.at(static_cast<size_t>(index));
  const std::string bytes = ReadBytes(path).substr(c.data_offset, c.packed_size);
  DwaChunk d;
  d.head = bytes.substr(0, 88);
  EXPECT_EQ(d.Get(DwaChunk::kVersion), 2u);
  const size_t rules = static_cast<unsigned char>(bytes[88]) | (size_t{static_cast<unsigned char>(bytes[89])} << 8);
  d.head = bytes.substr(0, 88 + rules);
  size_t at = d.head.size();
  for (auto [part, field] : {std::pair{&d.zlib, DwaChunk::kZlibSize}, {&d.ac, DwaChunk::kAcSize},
                             {&d.dc, DwaChunk::kDcSize}, {&d.rle, DwaChunk::kRleSize}}) {
    *part = bytes.substr(at, d.Get(field));
    at += part->size();
  }
  EXPECT_EQ(at, bytes.size());
  return d;
}

std::string Deflate(const std::string& raw) {
  uLongf n = compressBound(static_cast<uLong>(raw.size()));
  std::string z(n, '\0');
  EXPECT_EQ(compress(reinterpret_cast<Bytef*>(z.data()), &n, reinterpret_cast<const Bytef*>(raw.data()),
                     static_cast<uLong>(raw.size())),
            Z_OK);
  z.resize(n);
  return z;
}

std::string Inflate(const std::string& z, size_t max) {
  std::string raw(max, '\0');
  uLongf n = max;
  EXPECT_EQ(uncompress(reinterpret_cast<Bytef*>(raw.data()), &n, reinterpret_cast<const Bytef*>(z.data()),
                       static_cast<uLong>(z.size())),
            Z_OK);
  raw.resize(n);
  return raw;
}

// Colour half and depth float, as the bundled scenes; smooth, so that DWA
// keeps AC values. Depth is DWA's zlib section (only R, G, B, Y, RY, BY are
// lossy, A is RLE).
std::vector<TestChannel> DwaChannels(int w, int h) {
  std::vector<float> r(static_cast<size_t>(w * h)), g(r.size()), b(r.size()), z(r.size());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y * w + x);
      r[i] = 0.5f + 0.4f * std::sin(0.3f * static_cast<float>(x)) * std::cos(0.1f * static_cast<float>(y));
      g[i] = 0.3f + 0.25f * std::cos(0.17f * static_cast<float>(x) + 0.05f * static_cast<float>(y));
      b[i] = 2.0f + std::sin(0.2f * static_cast<float>(x + y));
      z[i] = 1.0f + 0.01f * static_cast<float>(y) + 0.001f * static_cast<float>(x);
    }
  }
  return {{"R", Imf::HALF, r}, {"G", Imf::HALF, g}, {"B", Imf::HALF, b}, {"Z", Imf::FLOAT, z}};
}

TEST_F(IoTest, DwaChunkThatCannotFillItsRowsIsAnError) {
  const int w = 16, h = 40;  // DWAA: 32 rows a chunk (the second has 8); DWAB: 256
  struct File {
    const char* name;
    Imf::Compression compression;
    bool tiled;
    int chunk, rows;  // the chunk corrupted, and its rows
    std::string where;
  };
  const File files[] = {{"dwaa.exr", Imf::DWAA_COMPRESSION, false, 1, 8, "scan line 32"},
                        {"dwab.exr", Imf::DWAB_COMPRESSION, false, 0, 40, "scan line 0"},
                        {"dwaa_tiled.exr", Imf::DWAA_COMPRESSION, true, 1, 16, "tile (0, 1)"}};  // 16 x 16 tiles
  for (const File& file : files) {
    const std::string path = Path(file.name);
    test::WriteExrFixture(path, Box(0, 0, w - 1, h - 1), Box(0, 0, w - 1, h - 1), DwaChannels(w, h),
                          file.compression, file.tiled, 16);
    SceneFrame f;
    std::string error;
    ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
    const std::string valid = ReadBytes(path);
    const DwaChunk chunk = ReadDwaChunk(path, file.chunk);
    const uint64_t cols = w, depth_bytes = cols * static_cast<uint64_t>(file.rows) * 4;
    const uint64_t dc_count = 3 * ((cols + 7) / 8) * ((static_cast<uint64_t>(file.rows) + 7) / 8);
    ASSERT_EQ(chunk.Get(DwaChunk::kZlibRaw), depth_bytes) << file.name;  // depth is the zlib section
    ASSERT_EQ(chunk.Get(DwaChunk::kDcCount), dc_count) << file.name;
    ASSERT_GT(chunk.ac.size(), 0u) << file.name;

    struct Case {
      const char* what;
      std::function<std::string(DwaChunk)> bytes;
      std::string want;
    };
    const std::string dc_values = Inflate(chunk.dc, 2 * dc_count);
    const Case cases[] = {
        // Imf 3.1 loaded these: rows from uninitialised memory.
        {"zlib section inflates short",
         [](DwaChunk d) {
           d.zlib = Deflate(std::string(16, '\0'));
           return d.Bytes();
         },
         "DWA zlib section inflates to 16 bytes where its rows need " + std::to_string(depth_bytes)},
        {"zlib section empty",
         [](DwaChunk d) {
           d.zlib.clear();
           return d.Bytes();
         },
         "DWA zlib section does not inflate (cut short)"},
        {"zlib section short, the header says so",
         [](DwaChunk d) {
           d.zlib = Deflate(std::string(16, '\0'));
           d.Set(DwaChunk::kZlibRaw, 16);
           return d.Bytes();
         },
         "DWA header says 16 bytes of zlib-compressed channels where its rows need " + std::to_string(depth_bytes)},
        {"fewer DC values, the header says so",
         [&](DwaChunk d) {
           d.dc = Deflate(dc_values.substr(0, 2));
           d.Set(DwaChunk::kDcCount, 1);
           return d.Bytes();
         },
         "DWA header says 1 DC values where its rows need " + std::to_string(dc_count)},
        // Imf 3.1 refused these too.
        {"AC size beyond the chunk",
         [](DwaChunk d) {
           d.Set(DwaChunk::kAcSize, d.ac.size() + 10);
           return d.Raw();
         },
         "DWA sections of "},
        {"zlib section inflates long",
         [&](DwaChunk d) {
           d.zlib = Deflate(std::string(2 * depth_bytes, '\0'));
           return d.Bytes();
         },
         "DWA zlib section inflates to more than the " + std::to_string(depth_bytes) + " bytes its rows need"},
    };
    for (const Case& c : cases) {
      WriteBytes(path, valid);
      const std::string bytes = c.bytes(chunk);
      ReplaceChunkData(path, file.chunk, bytes);
      SceneFrame untouched;
      EXPECT_FALSE(LoadSceneExr(path, "", &untouched, &error)) << file.name << ": " << c.what;
      EXPECT_EQ(error.rfind("'" + path + "' is not a readable OpenEXR file: corrupt chunk at " + file.where +
                                " (" + c.want,
                            0),
                0u)
          << c.what << ": " << error;
      EXPECT_EQ(untouched.width, 0);
      FloatPlane mask;  // every reader checks the chunks
      EXPECT_FALSE(ReadMaskImage(path, &mask, &error)) << file.name << ": " << c.what;
      EXPECT_NE(error.find("corrupt chunk at " + file.where + " (DWA "), std::string::npos) << error;
    }
  }
}

// Subsampled channels and an alpha (DWA's RLE section) are counted as Imf
// decodes them: such valid files load.
TEST_F(IoTest, DwaChunksWithSubsampledAndAlphaChannelsLoad) {
  const int w = 16, h = 42;
  for (const Imf::Compression compression : {Imf::DWAA_COMPRESSION, Imf::DWAB_COMPRESSION}) {
    const std::string path = Path(compression == Imf::DWAA_COMPRESSION ? "dwaa.exr" : "dwab.exr");
    Imf::Header header(w, h);
    header.compression() = compression;
    std::vector<half> full(static_cast<size_t>(w * h)), sub(static_cast<size_t>((w / 2) * (h / 2)));
    for (size_t i = 0; i < full.size(); ++i) full[i] = 0.5f + 0.01f * static_cast<float>(i % 37);
    for (size_t i = 0; i < sub.size(); ++i) sub[i] = 0.25f * static_cast<float>(i % 5);
    Imf::FrameBuffer fb;
    for (const char* name : {"R", "G", "B", "A"}) {
      header.channels().insert(name, Imf::Channel(Imf::HALF));
      fb.insert(name, Imf::Slice(Imf::HALF, reinterpret_cast<char*>(full.data()), 2, 2 * w));
    }
    header.channels().insert("C", Imf::Channel(Imf::HALF, 2, 2));  // half width and height: zlib section
    fb.insert("C", Imf::Slice(Imf::HALF, reinterpret_cast<char*>(sub.data()), 2, w, 2, 2));
    {
      Imf::OutputFile out(path.c_str(), header);
      out.setFrameBuffer(fb);
      out.writePixels(h);
    }
    const DwaChunk first = ReadDwaChunk(path, 0);
    const uint64_t rows = compression == Imf::DWAA_COMPRESSION ? 32 : h;
    EXPECT_EQ(first.Get(DwaChunk::kZlibRaw), (w / 2) * (rows / 2) * 2);
    EXPECT_EQ(first.Get(DwaChunk::kRleRaw), w * rows * 2);
    SceneFrame f;
    std::string error;
    ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
    EXPECT_EQ(f.layout, "rgba");
  }
}

// The same for DWA chunks, which are checked by DwaChunkProblem on the same threads.
TEST_F(IoTest, TheFirstBadDwaChunkIsNamedWhateverTheThreads) {
  constexpr int kRows = 32 * 50;  // DWAA: 32 rows a chunk
  const std::string path = Path("many_dwaa.exr");
  test::WriteExrFixture(path, Box(0, 0, 7, kRows - 1), Box(0, 0, 7, kRows - 1), DwaChannels(8, kRows),
                        Imf::DWAA_COMPRESSION, false);
  SceneFrame f;
  std::string error;
  ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
  for (const int chunk : {40, 30}) {
    DwaChunk d = ReadDwaChunk(path, chunk);
    d.zlib = Deflate(std::string(16, '\0'));
    ReplaceChunkData(path, chunk, d.Bytes());
  }
  for (int round = 0; round < 20; ++round) {
    SceneFrame g;
    ASSERT_FALSE(LoadSceneExr(path, "", &g, &error));
    ASSERT_EQ(error.rfind("'" + path + "' is not a readable OpenEXR file: corrupt chunk at scan line 960 (DWA ", 0),
              0u)
        << error;
  }
}

// The chunk check decompresses with OpenEXRCore: valid files of every
// compression, scanline and tiled, with partial chunks and tiles at the
// edges, still load (the lossless ones exactly).
TEST_F(IoTest, EveryCompressionLoads) {
  const int w = 37, h = 23;
  std::vector<float> v(static_cast<size_t>(w * h));
  for (size_t i = 0; i < v.size(); ++i) v[i] = 0.25f * static_cast<float>(i % 17);  // exact in half
  const Imf::Compression lossless[] = {Imf::NO_COMPRESSION, Imf::RLE_COMPRESSION, Imf::ZIPS_COMPRESSION,
                                       Imf::ZIP_COMPRESSION, Imf::PIZ_COMPRESSION};
  const Imf::Compression lossy[] = {Imf::PXR24_COMPRESSION, Imf::B44_COMPRESSION, Imf::B44A_COMPRESSION,
                                    Imf::DWAA_COMPRESSION, Imf::DWAB_COMPRESSION};
  for (const bool exact : {true, false}) {
    for (const Imf::Compression c : exact ? std::vector<Imf::Compression>(std::begin(lossless), std::end(lossless))
                                          : std::vector<Imf::Compression>(std::begin(lossy), std::end(lossy))) {
      for (const bool tiled : {false, true}) {
        const std::string path = Path("c" + std::to_string(static_cast<int>(c)) + (tiled ? "_tiled" : "") + ".exr");
        test::WriteExrFixture(path, Box(0, 0, w - 1, h - 1), Box(0, 0, w - 1, h - 1),
                              {{"R", Imf::HALF, v}, {"G", Imf::HALF, v}, {"B", Imf::HALF, v}, {"Z", Imf::FLOAT, v}},
                              c, tiled);
        SceneFrame f;
        std::string error;
        ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
        ASSERT_TRUE(f.has_depth);
        if (exact) {
          EXPECT_EQ(f.r.data, v) << path;
          EXPECT_EQ(f.depth.data, v) << path;
        }
      }
    }
  }
}

// The pixels are decoded in the chunk check's one pass (OpenEXRCore
// decompresses, camsim converts; Imf only for DWA and subsampled parts):
// every compression, scanline and tiled, in both line orders, a data window
// sticking out of the display window on three sides, half, float and uint
// channels around one not read. Each plane must equal, bit for bit, what
// Imf's own reader gives, and for the lossless compressions the values
// written; outside the data window 0 (colour) and +inf (depth).
TEST_F(IoTest, EveryCompressionDecodesTheSamePixelsAsImf) {
  const Imath::Box2i display = Box(0, 0, 40, 28), data = Box(-3, 4, 38, 33);
  const int dw = data.max.x - data.min.x + 1, dh = data.max.y - data.min.y + 1;
  auto values = [&](float scale, float offset) {
    std::vector<float> v;
    for (int y = 0; y < dh; ++y) {
      for (int x = 0; x < dw; ++x) v.push_back(offset + scale * static_cast<float>((x * 7 + y * 131) % 997));
    }
    return v;
  };
  const std::vector<TestChannel> channels = {
      {"A", Imf::HALF, values(0.5f, 3.0f)},           // not read: skipped in each row
      {"B", Imf::UINT, values(3.0f, 1.0f)},           // integers: exact as float
      {"G", Imf::FLOAT, values(0.0013f, 0.1f)},       // not exact in half
      {"R", Imf::HALF, values(0.125f, 0.25f)},        // exact in half
      {"Z", Imf::FLOAT, values(0.37f, 1.5f)}};
  auto bits = [](const std::vector<float>& v) {
    std::vector<uint32_t> b(v.size());
    std::memcpy(b.data(), v.data(), v.size() * sizeof(float));
    return b;
  };
  // A display-window plane: `src` (data-window values) where the windows overlap, else `fill`.
  auto expected = [&](const std::vector<float>& src, float fill) {
    std::vector<float> out(static_cast<size_t>(41 * 29), fill);
    for (int y = std::max(data.min.y, 0); y <= std::min(data.max.y, 28); ++y) {
      for (int x = std::max(data.min.x, 0); x <= std::min(data.max.x, 40); ++x) {
        out[static_cast<size_t>(y * 41 + x)] = src[static_cast<size_t>((y - data.min.y) * dw + (x - data.min.x))];
      }
    }
    return out;
  };
  const Imf::Compression compressions[] = {
      Imf::NO_COMPRESSION,    Imf::RLE_COMPRESSION, Imf::ZIPS_COMPRESSION, Imf::ZIP_COMPRESSION,
      Imf::PIZ_COMPRESSION,   Imf::PXR24_COMPRESSION, Imf::B44_COMPRESSION, Imf::B44A_COMPRESSION,
      Imf::DWAA_COMPRESSION,  Imf::DWAB_COMPRESSION};
  for (const Imf::Compression c : compressions) {
    const bool lossless = c <= Imf::PIZ_COMPRESSION;
    for (const bool tiled : {false, true}) {
      for (const Imf::LineOrder order : {Imf::INCREASING_Y, Imf::DECREASING_Y}) {
        const std::string path = Path("c" + std::to_string(static_cast<int>(c)) + (tiled ? "_tiled" : "") +
                                      (order == Imf::DECREASING_Y ? "_down" : "") + ".exr");
        SCOPED_TRACE(path);
        test::WriteExrFixture(path, display, data, channels, c, tiled, 4, order);
        // What Imf reads, as float, over the data window.
        std::vector<std::vector<float>> imf(channels.size(), std::vector<float>(static_cast<size_t>(dw * dh)));
        {
          Imf::InputFile in(path.c_str());
          Imf::FrameBuffer fb;
          for (size_t k = 0; k < channels.size(); ++k) {
            fb.insert(channels[k].name, Imf::Slice::Make(Imf::FLOAT, imf[k].data(), data, sizeof(float),
                                                         sizeof(float) * static_cast<size_t>(dw)));
          }
          in.setFrameBuffer(fb);
          in.readPixels(data.min.y, data.max.y);
        }
        SceneFrame f;
        std::string error;
        ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
        ASSERT_EQ(f.width, 41);
        ASSERT_EQ(f.height, 29);
        ASSERT_TRUE(f.has_depth);
        EXPECT_EQ(bits(f.b.data), bits(expected(imf[1], 0.0f)));
        EXPECT_EQ(bits(f.g.data), bits(expected(imf[2], 0.0f)));
        EXPECT_EQ(bits(f.r.data), bits(expected(imf[3], 0.0f)));
        EXPECT_EQ(bits(f.depth.data), bits(expected(imf[4], kInf)));
        if (lossless) {
          std::vector<float> uints, halves;
          for (float v : channels[1].values) uints.push_back(static_cast<float>(static_cast<uint32_t>(v)));
          for (float v : channels[3].values) halves.push_back(static_cast<float>(half(v)));
          EXPECT_EQ(halves, channels[3].values);  // chosen exact: so R is what was written
          EXPECT_EQ(bits(f.b.data), bits(expected(uints, 0.0f)));
          EXPECT_EQ(bits(f.g.data), bits(expected(channels[2].values, 0.0f)));
          EXPECT_EQ(bits(f.r.data), bits(expected(channels[3].values, 0.0f)));
          EXPECT_EQ(bits(f.depth.data), bits(expected(channels[4].values, kInf)));
        }
        EXPECT_EQ(f.radiance_stats.nan + f.radiance_stats.negative + f.depth_stats.pos_inf, 0u);
      }
    }
  }
}

// A part with a subsampled channel (not read) is read by Imf after the check
// (the one-pass copy handles only channels with a sample per pixel).
TEST_F(IoTest, PartWithASubsampledChannelLoads) {
  const int w = 18, h = 14;
  for (const Imf::Compression compression : {Imf::ZIP_COMPRESSION, Imf::PIZ_COMPRESSION, Imf::NO_COMPRESSION}) {
    const std::string path = Path("sub" + std::to_string(static_cast<int>(compression)) + ".exr");
    Imf::Header header(w, h);
    header.compression() = compression;
    std::vector<half> full(static_cast<size_t>(w * h)), sub(static_cast<size_t>((w / 2) * (h / 2)));
    for (size_t i = 0; i < full.size(); ++i) full[i] = 0.5f + 0.25f * static_cast<float>(i % 37);
    for (size_t i = 0; i < sub.size(); ++i) sub[i] = 0.25f * static_cast<float>(i % 5);
    Imf::FrameBuffer fb;
    for (const char* name : {"R", "G", "B"}) {
      header.channels().insert(name, Imf::Channel(Imf::HALF));
      fb.insert(name, Imf::Slice(Imf::HALF, reinterpret_cast<char*>(full.data()), 2, 2 * w));
    }
    header.channels().insert("C", Imf::Channel(Imf::HALF, 2, 2));
    fb.insert("C", Imf::Slice(Imf::HALF, reinterpret_cast<char*>(sub.data()), 2, w, 2, 2));
    {
      Imf::OutputFile out(path.c_str(), header);
      out.setFrameBuffer(fb);
      out.writePixels(h);
    }
    SceneFrame f;
    std::string error;
    ASSERT_TRUE(LoadSceneExr(path, "", &f, &error)) << error;
    std::vector<float> want(full.begin(), full.end());
    EXPECT_EQ(f.r.data, want) << path;
    EXPECT_EQ(f.b.data, want) << path;
  }
}

// ---- Writers --------------------------------------------------------------

TEST_F(IoTest, Pgm16HeaderAndBigEndianSamples) {
  // 2x2 image inside rows of 3 samples.
  const uint16_t data[] = {0x0102, 0x0fff, 0xdead, 0x0000, 0x0a0b, 0xbeef};
  const std::string path = Path("a.pgm");
  std::string error;
  ASSERT_TRUE(WritePnm16(path, data, 2, 2, 1, 3, 4095, &error)) << error;
  EXPECT_EQ(ReadBytes(path), std::string("P5\n2 2\n4095\n\x01\x02\x0f\xff\x00\x00\x0a\x0b", 20));

  const uint16_t bytes[] = {0, 7, 255};
  ASSERT_TRUE(WritePnm16(path, bytes, 3, 1, 1, 3, 255, &error)) << error;
  EXPECT_EQ(ReadBytes(path), std::string("P5\n3 1\n255\n\x00\x07\xff", 14));

  EXPECT_FALSE(WritePnm16(path, data, 2, 2, 1, 3, 255, &error));  // 0x0102 > 255
  EXPECT_NE(error.find("maxval"), std::string::npos) << error;
  EXPECT_EQ(DirEntries(), std::vector<std::string>{"a.pgm"});
}

TEST_F(IoTest, Raw16LittleEndian) {
  const uint16_t data[] = {0x0102, 0xffff, 0x1234, 0xabcd};
  const std::string path = Path("a.raw");
  std::string error;
  ASSERT_TRUE(WriteRaw16(path, data, 1, 2, 1, 2, &error)) << error;  // column 0 only
  EXPECT_EQ(ReadBytes(path), std::string("\x02\x01\x34\x12", 4));
}

// Three channels: interleaved RGB, a P6 header, samples in R, G, B order.
TEST_F(IoTest, RgbPpmAndRawKeepEveryChannel) {
  // 1x2 RGB pixels inside rows of 4 samples.
  const uint16_t data[] = {0x0102, 0x0304, 0x0506, 0xffff, 0x0a0b, 0x0c0d, 0x0e0f, 0xffff};
  std::string error;
  ASSERT_TRUE(WritePnm16(Path("a.ppm"), data, 1, 2, 3, 4, 4095, &error)) << error;
  EXPECT_EQ(ReadBytes(Path("a.ppm")),
            std::string("P6\n1 2\n4095\n\x01\x02\x03\x04\x05\x06\x0a\x0b\x0c\x0d\x0e\x0f", 24));
  ASSERT_TRUE(WriteRaw16(Path("a.raw"), data, 1, 2, 3, 4, &error)) << error;
  EXPECT_EQ(ReadBytes(Path("a.raw")), std::string("\x02\x01\x04\x03\x06\x05\x0b\x0a\x0d\x0c\x0f\x0e", 12));
  EXPECT_FALSE(WritePnm16(Path("b.ppm"), data, 1, 2, 2, 4, 4095, &error));
  EXPECT_NE(error.find("channels must be 1 or 3, not 2"), std::string::npos) << error;
  EXPECT_FALSE(WritePnm16(Path("b.ppm"), data, 1, 2, 3, 4, 255, &error));  // 0x0102 > 255
  EXPECT_NE(error.find("sample (0,0)R = 258 exceeds maxval 255"), std::string::npos) << error;
}

TEST_F(IoTest, TextFile) {
  const std::string path = Path("r.json");
  std::string error;
  ASSERT_TRUE(WriteTextFile(path, "{\"a\": 1}\n", &error)) << error;
  ASSERT_TRUE(WriteTextFile(path, "{}", &error)) << error;
  EXPECT_EQ(ReadBytes(path), "{}");
  EXPECT_EQ(DirEntries(), std::vector<std::string>{"r.json"});
}

struct RawPng {
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0;
  std::vector<unsigned char> bytes;  // rows as stored (16-bit big-endian)
};

// Reads a PNG with libpng, no transforms. No destructors in this frame (setjmp).
bool ReadRawPng(const char* path, RawPng* out) {
  std::FILE* f = std::fopen(path, "rb");
  if (f == nullptr) return false;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(f);
    return false;
  }
  png_init_io(png, f);
  png_read_png(png, info, PNG_TRANSFORM_IDENTITY, nullptr);
  out->width = png_get_image_width(png, info);
  out->height = png_get_image_height(png, info);
  out->bit_depth = png_get_bit_depth(png, info);
  out->color_type = png_get_color_type(png, info);
  const size_t row_bytes = png_get_rowbytes(png, info);
  png_bytepp rows = png_get_rows(png, info);
  out->bytes.clear();
  for (png_uint_32 y = 0; y < out->height; ++y) {
    out->bytes.insert(out->bytes.end(), rows[y], rows[y] + row_bytes);
  }
  png_destroy_read_struct(&png, &info, nullptr);
  std::fclose(f);
  return true;
}

TEST_F(IoTest, PngRoundTrip8And16Bit) {
  const std::string path = Path("p.png");
  std::string error;
  for (int channels : {1, 3}) {
    const int w = 3, h = 2, stride = w * channels + 2;  // padded rows
    std::vector<uint8_t> d8(static_cast<size_t>(stride * h));
    std::vector<uint16_t> d16(d8.size());
    for (size_t i = 0; i < d8.size(); ++i) {
      d8[i] = static_cast<uint8_t>(i * 37 + 5);
      d16[i] = static_cast<uint16_t>(i * 4099 + 1);
    }
    for (int bits : {8, 16}) {
      const void* data = bits == 8 ? static_cast<const void*>(d8.data()) : d16.data();
      ASSERT_TRUE(WritePng(path, data, w, h, channels, bits, stride, &error)) << error;
      RawPng png;
      ASSERT_TRUE(ReadRawPng(path.c_str(), &png));
      EXPECT_EQ(png.width, 3u);
      EXPECT_EQ(png.height, 2u);
      EXPECT_EQ(png.bit_depth, bits);
      EXPECT_EQ(png.color_type, channels == 1 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB);
      std::vector<unsigned char> want;
      for (int y = 0; y < h; ++y) {
        for (int s = 0; s < w * channels; ++s) {
          const size_t i = static_cast<size_t>(y * stride + s);
          if (bits == 8) {
            want.push_back(d8[i]);
          } else {
            want.push_back(static_cast<unsigned char>(d16[i] >> 8));
            want.push_back(static_cast<unsigned char>(d16[i] & 0xff));
          }
        }
      }
      EXPECT_EQ(png.bytes, want) << channels << " channels, " << bits << " bits";
    }
  }
  const uint8_t one[2] = {};
  EXPECT_FALSE(WritePng(path, one, 1, 1, 2, 8, 2, &error));
  EXPECT_NE(error.find("channels"), std::string::npos) << error;
}

TEST_F(IoTest, AtomicWriteIntoMissingDirectoryLeavesNothing) {
  const std::string path = Path("no_such_dir/out.pgm");
  const uint16_t data[] = {1, 2};
  std::string error;
  EXPECT_FALSE(WritePnm16(path, data, 2, 1, 1, 2, 255, &error));
  EXPECT_NE(error.find(path), std::string::npos) << error;
  const float f[] = {1, 2};
  EXPECT_FALSE(WriteExrFloat(Path("no_such_dir/out.exr"), 2, 1, {{"Y", f, 2}}, &error));
  EXPECT_NE(error.find("out.exr"), std::string::npos) << error;
  EXPECT_TRUE(DirEntries().empty());
}

TEST_F(IoTest, FailedWriteKeepsExistingFile) {
  // A name so long (254 of NAME_MAX's 255 bytes) that no temporary name fits
  // beside it: the write fails before it touches anything.
  const std::string name = std::string(250, 'k') + ".png";
  const std::string path = Path(name);
  { std::ofstream(path) << "before"; }
  const uint8_t second[] = {30, 40};
  std::string error;
  EXPECT_FALSE(WritePng(path, second, 2, 1, 1, 8, 2, &error));
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find("cannot create"), std::string::npos) << error;
  EXPECT_EQ(ReadBytes(path), "before");
  EXPECT_EQ(DirEntries(), (std::vector<std::string>{name}));
  fs::remove(path);

  // Target is an existing directory: the rename fails, the temp file is removed.
  const std::string target_dir = Path("adir");
  fs::create_directory(target_dir);
  EXPECT_FALSE(WriteTextFile(target_dir, "x", &error));
  EXPECT_NE(error.find(target_dir), std::string::npos) << error;
  EXPECT_TRUE(fs::is_directory(target_dir));
  EXPECT_EQ(DirEntries(), std::vector<std::string>{"adir"});  // its temporary file is gone
}

// While it lives, writes past `bytes` in any file fail with EFBIG
// (RLIMIT_FSIZE, SIGXFSZ ignored): a disk that fills up during a write.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    if (getrlimit(RLIMIT_FSIZE, &old_) != 0) return;
    rlimit lower = old_;
    lower.rlim_cur = bytes;
    ok_ = setrlimit(RLIMIT_FSIZE, &lower) == 0;
  }
  ~FileSizeLimit() {
    if (ok_) setrlimit(RLIMIT_FSIZE, &old_);
    std::signal(SIGXFSZ, old_handler_);
  }
  bool ok() const { return ok_; }

 private:
  rlimit old_{};
  void (*old_handler_)(int) = SIG_DFL;
  bool ok_ = false;
};

// OpenEXR's own file stream kept a small file's bytes in its buffer until
// ~OutputFile, which swallows errors: a truncated file replaced the old one
// and the write reported success.
TEST_F(IoTest, ExrWriteThatFailsKeepsExistingFile) {
  std::vector<float> noise(64 * 64);  // random mantissas: ZIP cannot shrink them below the limit
  uint32_t state = 1;
  for (float& v : noise) {
    state = state * 1664525u + 1013904223u;
    v = static_cast<float>(state) / 4294967296.0f;
  }
  const std::string path = Path("frame.exr");
  std::string error;
  ASSERT_TRUE(WriteExrFloat(path, 4, 4, {{"Y", noise.data(), 4}}, &error)) << error;
  const std::string before = ReadBytes(path);
  // 8 x 64: chunks of 16 rows (under 512 bytes each, about 2.5 KB in all)
  // stayed in the stream's buffer until the end. 64 x 64: 16 KB, fails while
  // the pixels are written.
  for (const int width : {8, 64}) {
    bool written = true;
    {
      const FileSizeLimit limit(1024);
      ASSERT_TRUE(limit.ok());
      written = WriteExrFloat(path, width, 64, {{"Y", noise.data(), width}}, &error);
    }
    EXPECT_FALSE(written) << width;
    EXPECT_NE(error.find("'" + path + "'"), std::string::npos) << error;
    EXPECT_NE(error.find(std::strerror(EFBIG)), std::string::npos) << error;
    EXPECT_TRUE(ReadBytes(path) == before) << width;  // (a short message, not the bytes)
    EXPECT_EQ(DirEntries(), std::vector<std::string>{"frame.exr"});  // its temporary file is gone
  }
}

// A file or directory with the old fixed temporary name (`path.tmp`), e.g.
// an input of the same run, is neither written nor removed.
TEST_F(IoTest, TemporaryNamesNeverTouchExistingFiles) {
  const std::string path = Path("frame.png");
  { std::ofstream(path + ".tmp") << "an input"; }
  fs::create_directory(path + ".tmp." + std::to_string(getpid()) + ".x");
  const uint8_t data[] = {10, 20};
  std::string error;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(WritePng(path, data, 2, 1, 1, 8, 2, &error)) << error;
  EXPECT_EQ(ReadBytes(path + ".tmp"), "an input");
  EXPECT_EQ(ReadBytes(path).substr(1, 3), "PNG");
  EXPECT_EQ(DirEntries(), (std::vector<std::string>{"frame.png", "frame.png.tmp",
                                                     "frame.png.tmp." + std::to_string(getpid()) + ".x"}));
}

// RemoveTemporariesOnSignal: a fatal signal removes the files registered at
// that moment (not one registered earlier and since unregistered), and the
// process still dies by it; a signal ignored before (nohup's SIGHUP) stays
// ignored. (Cli.KilledMidWriteLeavesNoTemporaryFile kills `camsim` itself.)
TEST_F(IoTest, FatalSignalRemovesRegisteredFiles) {
  const std::string registered = Path("a.tmp.1.0"), released = Path("b.tmp.1.1"), other = Path("c");
  for (const std::string& p : {registered, released, other}) WriteBytes(p, "x");
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    // Only what is safe after fork: no allocation.
    std::signal(SIGTERM, SIG_DFL);
    std::signal(SIGHUP, SIG_IGN);
    RemoveTemporariesOnSignal();
    { const RemovedOnSignal done(released); }
    const RemovedOnSignal in_flight(registered);
    raise(SIGHUP);  // ignored: nothing happens
    raise(SIGTERM);
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << "status " << status;
  EXPECT_EQ(DirEntries(), (std::vector<std::string>{"b.tmp.1.1", "c"}));
}

// A symbolic link is followed: the file it points to (through relative and
// chained links, and a dangling link's missing target) is replaced, with the
// temporary file in the target's directory; the link stays a link.
TEST_F(IoTest, WritesFollowSymbolicLinks) {
  fs::create_directory(dir_ / "links");
  fs::create_directory(dir_ / "data");
  const std::string target = Path("data/report.json");
  WriteBytes(target, "old");
  fs::create_symlink("../data/report.json", dir_ / "links" / "r.json");  // relative to the link's directory
  fs::create_symlink("r.json", dir_ / "links" / "chain.json");           // a link to a link
  std::string error;
  ASSERT_TRUE(WriteTextFile(Path("links/r.json"), "new", &error)) << error;
  EXPECT_TRUE(fs::is_symlink(dir_ / "links" / "r.json"));
  EXPECT_EQ(ReadBytes(target), "new");
  ASSERT_TRUE(WriteTextFile(Path("links/chain.json"), "newer", &error)) << error;
  EXPECT_TRUE(fs::is_symlink(dir_ / "links" / "chain.json"));
  EXPECT_EQ(ReadBytes(target), "newer");
  const uint8_t px[] = {10, 20};
  fs::create_symlink(dir_ / "data" / "made.png", dir_ / "links" / "dangling.png");  // absolute, target missing
  ASSERT_TRUE(WritePng(Path("links/dangling.png"), px, 2, 1, 1, 8, 2, &error)) << error;
  EXPECT_EQ(ReadBytes(Path("data/made.png")).substr(1, 3), "PNG");
  EXPECT_TRUE(fs::is_symlink(dir_ / "links" / "dangling.png"));
  // No temporary file is left in either directory.
  std::vector<std::string> data, links;
  for (const auto& e : fs::directory_iterator(dir_ / "data")) data.push_back(e.path().filename().string());
  for (const auto& e : fs::directory_iterator(dir_ / "links")) links.push_back(e.path().filename().string());
  std::sort(data.begin(), data.end());
  std::sort(links.begin(), links.end());
  EXPECT_EQ(data, (std::vector<std::string>{"made.png", "report.json"}));
  EXPECT_EQ(links, (std::vector<std::string>{"chain.json", "dangling.png", "r.json"}));
  // A loop is an error, not a hang.
  fs::create_symlink("loop_b", dir_ / "loop_a");
  fs::create_symlink("loop_a", dir_ / "loop_b");
  EXPECT_FALSE(WriteTextFile(Path("loop_a"), "x", &error));
  EXPECT_NE(error.find("too many levels of symbolic links"), std::string::npos) << error;
}

// A FIFO, a directory (or a device or socket) at the path is refused with an
// error naming it, and stays what it was: it used to be replaced by a
// regular file.
TEST_F(IoTest, WritesRefuseWhatIsNotARegularFile) {
  const std::string fifo = Path("pipe.json");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0644), 0) << std::strerror(errno);
  std::string error;
  EXPECT_FALSE(WriteTextFile(fifo, "{}", &error));
  EXPECT_NE(error.find("cannot write '" + fifo + "': it is a FIFO"), std::string::npos) << error;
  EXPECT_EQ(fs::status(fifo).type(), fs::file_type::fifo);
  fs::create_symlink("pipe.json", dir_ / "to_pipe.json");  // through a link too
  EXPECT_FALSE(WriteTextFile(Path("to_pipe.json"), "{}", &error));
  EXPECT_NE(error.find("'" + Path("pipe.json") + "' (its link's target) is a FIFO"), std::string::npos) << error;
  EXPECT_TRUE(fs::is_symlink(dir_ / "to_pipe.json"));
  const uint8_t px[] = {10, 20};
  fs::create_directory(dir_ / "d.png");
  EXPECT_FALSE(WritePng(Path("d.png"), px, 2, 1, 1, 8, 2, &error));
  EXPECT_NE(error.find("is a directory"), std::string::npos) << error;
  EXPECT_TRUE(fs::is_directory(dir_ / "d.png"));
  std::string target;
  EXPECT_FALSE(WritableTarget(fifo, &target, &error));
  EXPECT_TRUE(WritableTarget(Path("absent.png"), &target, &error)) << error;
  EXPECT_EQ(target, Path("absent.png"));
  EXPECT_EQ(DirEntries(), (std::vector<std::string>{"d.png", "pipe.json", "to_pipe.json"}));
}

TEST_F(IoTest, WriteExrFloatRejectsBadChannels) {
  const float f[] = {1, 2};
  std::string error;
  EXPECT_FALSE(WriteExrFloat(Path("x.exr"), 2, 1, {{"Y", f, 2}, {"Y", f, 2}}, &error));
  EXPECT_NE(error.find("'Y'"), std::string::npos) << error;
  EXPECT_FALSE(WriteExrFloat(Path("x.exr"), 2, 1, {{"Y", f, 1}}, &error));  // stride < width
  EXPECT_NE(error.find("stride"), std::string::npos) << error;
  EXPECT_TRUE(DirEntries().empty());
}

// UINT channels keep all 32 bits (FLOAT keeps 24: 2^24 + 1 reads back as
// 2^24), and the attributes come back with their types.
TEST_F(IoTest, WriteExrKeepsUintSamplesAndAttributes) {
  const uint32_t codes[] = {0, 1, (1u << 24) + 1, 4294967295u};
  const float values[] = {0.0f, 1.0f, 16777216.0f, 4294967296.0f};
  const std::string path = Path("codes.exr");
  std::string error;
  ASSERT_TRUE(WriteExr(path, 2, 2, {{"Y", values, 2}, {"code.Y", codes, 2}},
                       {{"camsim/code.Y/format", "photons Q24.8"}, {"camsim/code.Y/scale", 0.00390625}}, &error))
      << error;
  Imf::InputFile in(path.c_str());
  const Imf::Header& h = in.header();
  ASSERT_NE(h.channels().findChannel("code.Y"), nullptr);
  EXPECT_EQ(h.channels().findChannel("code.Y")->type, Imf::UINT);
  EXPECT_EQ(h.channels().findChannel("Y")->type, Imf::FLOAT);
  const auto* format = h.findTypedAttribute<Imf::StringAttribute>("camsim/code.Y/format");
  const auto* scale = h.findTypedAttribute<Imf::DoubleAttribute>("camsim/code.Y/scale");
  ASSERT_TRUE(format != nullptr && scale != nullptr);
  EXPECT_EQ(format->value(), "photons Q24.8");
  EXPECT_EQ(scale->value(), 0.00390625);
  uint32_t back[4] = {};
  float back_f[4] = {};
  Imf::FrameBuffer fb;
  fb.insert("code.Y", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(back), 4, 8));
  fb.insert("Y", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(back_f), 4, 8));
  in.setFrameBuffer(fb);
  in.readPixels(0, 1);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(back[i], codes[i]) << i;
    EXPECT_EQ(back_f[i], values[i]) << i;
  }
}

TEST_F(IoTest, WriteExrRejectsBadAttributes) {
  const float f[] = {1, 2};
  std::string error;
  for (const char* name : {"", "channels", "compression", "dataWindow", "type", "tiles"}) {
    EXPECT_FALSE(WriteExr(Path("x.exr"), 2, 1, {{"Y", f, 2}}, {{name, "x"}}, &error)) << name;
    EXPECT_NE(error.find("attribute name '" + std::string(name) + "'"), std::string::npos) << error;
  }
  EXPECT_FALSE(WriteExr(Path("x.exr"), 2, 1, {{"Y", f, 2}}, {{"camsim/a", 1.0}, {"camsim/a", "b"}}, &error));
  EXPECT_NE(error.find("repeated"), std::string::npos) << error;
  EXPECT_TRUE(DirEntries().empty());
}

// ---- Mask readers ---------------------------------------------------------

TEST_F(IoTest, ReadPngNormalises) {
  const std::string gray = Path("g.png"), rgb = Path("c.png");
  const uint8_t g8[] = {0, 51, 255, 0};
  const uint16_t c16[] = {65535, 0, 0, 0, 65535, 65535};  // mean 1/3 and 2/3
  std::string error;
  ASSERT_TRUE(WritePng(gray, g8, 3, 1, 1, 8, 4, &error)) << error;
  ASSERT_TRUE(WritePng(rgb, c16, 2, 1, 3, 16, 6, &error)) << error;
  FloatPlane p;
  ASSERT_TRUE(ReadPng(gray, &p, &error)) << error;
  EXPECT_EQ(p.width, 3);
  EXPECT_EQ(p.height, 1);
  EXPECT_FLOAT_EQ(p.at(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(p.at(1, 0), 0.2f);
  EXPECT_FLOAT_EQ(p.at(2, 0), 1.0f);
  ASSERT_TRUE(ReadMaskImage(rgb, &p, &error)) << error;
  ASSERT_EQ(p.data.size(), 2u);
  EXPECT_FLOAT_EQ(p.at(0, 0), 1.0f / 3.0f);
  EXPECT_FLOAT_EQ(p.at(1, 0), 2.0f / 3.0f);

  const std::string bad = Path("bad.png");
  WriteBytes(bad, "not a png at all");
  EXPECT_FALSE(ReadPng(bad, &p, &error));
  EXPECT_NE(error.find(bad), std::string::npos) << error;
  EXPECT_EQ(p.data.size(), 2u);  // unchanged
}

// A directory opens on Linux and fails only when read: it used to be
// reported as "not a readable PNG file: Read Error".
TEST_F(IoTest, ReadPngRefusesADirectory) {
  const std::string d = Path("dir.png");
  ASSERT_TRUE(fs::create_directory(d));
  FloatPlane p;
  std::vector<uint16_t> raw;
  int w = 0, h = 0, depth = 0;
  std::string error;
  EXPECT_FALSE(ReadPng(d, &p, &error));
  EXPECT_EQ(error, "'" + d + "' is a directory, not a PNG file");
  EXPECT_FALSE(ReadMaskImage(d, &p, &error));
  EXPECT_EQ(error, "'" + d + "' is a directory, not a PNG file");
  EXPECT_FALSE(ReadPngGrayRaw(d, &raw, &w, &h, &depth, &error));
  EXPECT_EQ(error, "'" + d + "' is a directory, not a PNG file");
}

TEST_F(IoTest, ReadMaskImageExr) {
  const std::string path = Path("mask.EXR");
  WriteTestExr(path, Box(0, 0, 1, 0), Box(0, 0, 1, 0),
               {{"R", Imf::FLOAT, {0.5f, 0.25f}}, {"B", Imf::FLOAT, {9, 9}}});
  FloatPlane p;
  std::string error;
  ASSERT_TRUE(ReadMaskImage(path, &p, &error)) << error;
  EXPECT_EQ(p.data, (std::vector<float>{0.5f, 0.25f}));

  const std::string other = Path("other.exr");
  WriteTestExr(other, Box(0, 0, 0, 0), Box(0, 0, 0, 0),
               {{"b", Imf::HALF, {2}}, {"a", Imf::FLOAT, {-3}}});
  ASSERT_TRUE(ReadMaskImage(other, &p, &error)) << error;
  EXPECT_EQ(p.data, std::vector<float>{-3.0f});  // first channel by name, as stored

  EXPECT_FALSE(ReadMaskImage(Path("mask.tiff"), &p, &error));
  EXPECT_NE(error.find("mask.tiff"), std::string::npos) << error;
}

// ---- ExpandInputs ---------------------------------------------------------

TEST_F(IoTest, ExpandDirectory) {
  for (const char* n : {"b.exr", "a.exr", "c.EXR", "notes.txt"}) WriteBytes(Path(n), "x");
  std::vector<std::string> files;
  std::string error;
  ASSERT_TRUE(ExpandInputs({dir_.string()}, &files, &error)) << error;
  EXPECT_EQ(files, (std::vector<std::string>{Path("a.exr"), Path("b.exr"), Path("c.EXR")}));
}

TEST_F(IoTest, ExpandPatternAndFiles) {
  // f_05.exr and f_00005.exr are not names %04d makes: no gap.
  for (const char* n : {"f_0001.exr", "f_0002.exr", "f_0003.exr", "f_05.exr", "f_00005.exr", "f_0005.exr.bak",
                        "s0.exr", "s1.exr", "t_9.exr"}) {
    WriteBytes(Path(n), "x");
  }
  std::vector<std::string> files;
  std::string error;
  ASSERT_TRUE(ExpandInputs({Path("f_%04d.exr"), Path("s%d.exr"), Path("t_9.exr")}, &files, &error)) << error;
  EXPECT_EQ(files, (std::vector<std::string>{Path("f_0001.exr"), Path("f_0002.exr"), Path("f_0003.exr"),
                                             Path("s0.exr"), Path("s1.exr"), Path("t_9.exr")}));
}

// A sequence may start at any index (VFX renders often start at 1001), and
// wide padding (%010d) is still checked for gaps.
TEST_F(IoTest, ExpandPatternFromAnyIndexAndAnyWidth) {
  for (const char* n : {"v_1001.exr", "v_1002.exr", "w_0000000001.exr", "w_0000000003.exr"}) WriteBytes(Path(n), "x");
  std::vector<std::string> files;
  std::string error;
  ASSERT_TRUE(ExpandInputs({Path("v_%04d.exr")}, &files, &error)) << error;
  EXPECT_EQ(files, (std::vector<std::string>{Path("v_1001.exr"), Path("v_1002.exr")}));
  EXPECT_FALSE(ExpandInputs({Path("w_%010d.exr")}, &files, &error));
  EXPECT_NE(error.find("'" + Path("w_0000000002.exr") + "' is missing but '" + Path("w_0000000003.exr") + "' exists"),
            std::string::npos)
      << error;
}

// A missing frame inside a numbered sequence stops nothing silently.
TEST_F(IoTest, ExpandPatternWithAGapIsAnError) {
  for (const char* n : {"f_0001.exr", "f_0002.exr", "f_0004.exr", "f_0007.exr"}) WriteBytes(Path(n), "x");
  std::vector<std::string> files = {"keep"};
  std::string error;
  EXPECT_FALSE(ExpandInputs({Path("f_%04d.exr")}, &files, &error));
  EXPECT_EQ(error, "input pattern '" + Path("f_%04d.exr") + "' has a gap: '" + Path("f_0003.exr") +
                       "' is missing but '" + Path("f_0004.exr") + "' exists (list the frames to run them anyway)");
  EXPECT_EQ(files, std::vector<std::string>{"keep"});
  // The same where the index names a directory (the next indices are tried).
  for (const char* d : {"d1", "d2", "d9"}) {
    fs::create_directory(Path(d));
    WriteBytes(Path(std::string(d) + "/x.exr"), "x");
  }
  EXPECT_FALSE(ExpandInputs({Path("d%d/x.exr")}, &files, &error));
  EXPECT_NE(error.find("'" + Path("d3/x.exr") + "' is missing but '" + Path("d9/x.exr") + "' exists"),
            std::string::npos)
      << error;
  EXPECT_EQ(files, std::vector<std::string>{"keep"});
}

TEST_F(IoTest, ExpandErrors) {
  std::vector<std::string> files = {"keep"};
  std::string error;
  const std::string missing = Path("missing.exr");
  EXPECT_FALSE(ExpandInputs({missing}, &files, &error));
  EXPECT_NE(error.find(missing), std::string::npos) << error;
  const std::string pattern = Path("g_%03d.exr");
  EXPECT_FALSE(ExpandInputs({pattern}, &files, &error));
  EXPECT_NE(error.find(pattern), std::string::npos) << error;
  EXPECT_FALSE(ExpandInputs({dir_.string()}, &files, &error));  // empty directory
  EXPECT_NE(error.find("no .exr"), std::string::npos) << error;
  EXPECT_FALSE(ExpandInputs({}, &files, &error));
  EXPECT_EQ(files, std::vector<std::string>{"keep"});
}

// A text file is read whole up to a bound: /dev/zero (or a huge file given by
// mistake) is an error, not memory exhausted.
TEST(ReadTextFile, StopsAtItsBound) {
  std::string text = "kept", error;
  EXPECT_FALSE(ReadTextFile("/dev/zero", &text, &error, 100000));
  EXPECT_EQ(error, "larger than 100000 bytes");
  EXPECT_EQ(text, "kept");
  const std::string path = testing::TempDir() + "camsim_text_bound_" + std::to_string(getpid());
  std::ofstream(path) << std::string(4096, 'x');
  EXPECT_FALSE(ReadTextFile(path, &text, &error, 4095));
  ASSERT_TRUE(ReadTextFile(path, &text, &error, 4096)) << error;
  EXPECT_EQ(text.size(), 4096u);
  EXPECT_GE(kMaxTextBytes, size_t{300} << 20);  // a 4096 x 4096 mesh as text
  std::remove(path.c_str());
}

}  // namespace
}  // namespace camsim::io
