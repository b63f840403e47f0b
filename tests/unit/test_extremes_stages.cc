// Numeric extremes for the stages added after the foundation (distortion,
// depth of field, motion blur, flare, blooming, smear, defects and row/column
// patterns), through the whole host path: an OpenEXR file with colour, depth
// and motion channels, the loader's sanitiser, the shared FrameRenderer (its
// flare and smear pre-passes) and the core. test_extremes.cc covers the
// foundation's stages with core-level inputs.
//
// Scenes, written as EXR at every size from 1 x 1 to 17 x 9 (odd widths, not
// multiples of the vector width):
//  - hostile depth and motion in every scene: depth cycles through NaN, 0, -1,
//    +inf, -inf, 1e-30, 0.3 m, 1e10 (sky) and 100 m; motion through NaN, +-inf,
//    +-1e30, +-32767 px, 0 and 3.5 px;
//  - "zero": radiance 0; "max": radiance 1e30 (finite and kept by the loader;
//    saturates Q16.16); "hostile": radiance cycling through NaN, +-inf, -1,
//    1e30, 0, 0.5, 65504 and a denormal.
//
// Documented results, asserted (noise, dark current and patterns off):
//  - "zero": every raw sample is the black level (64 DN): no stage makes light
//    from nothing, whatever the depth or motion says.
//  - "max": every raw sample is the full-well value (4002 DN): a flat field
//    stays flat through depth of field (a
//    renormalised blur), motion blur (an average), flare and smear (which only
//    add to saturated charge) and blooming (spill into full pixels).
//    Distortion (fx = 10 px, so tiny frames are strongly distorted) reads
//    black where its source lies off the rendered frame (docs/lens-
//    distortion.md): there a sample is 4002 or 64, and the pixel at the
//    principal point, whose source is itself, is 4002.
//  - with defects and row/column patterns on, "zero" and "max" are not flat:
//    stuck pixels read the ADC maximum (4095), dead pixels the black level
//    plus the offset patterns; asserted: the stuck value, and every sample
//    within [0, 4095].
// For every case: the same bytes for strip heights 1, 7 and whole and for 1
// and 2 threads, raw samples within the 12-bit range; the debug preset runs
// all of it under ASan and UBSan.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/io/image_write.h"
#include "host_tools/render.h"

namespace camsim {
namespace {

constexpr uint16_t kBlackDn = 64;
constexpr uint16_t kFullWellDn = 4002;  // round(0.375 DN/e- * 10500 e-) + 64
constexpr uint16_t kAdcMaxDn = 4095;

// configs/camera.toml with every random term off, so flat inputs have exact
// answers. A fixed pixel pitch: the default (a 36 mm wide sensor) would give a
// 1-pixel-wide frame a focal length below 1 pixel, which configuration refuses.
const char* kNoiseOff =
    "[sensor]\nshot_noise = false\ndark_noise_e = 0.0\ndsnu_e = 0.0\nprnu_percent = 0.0\n"
    "dark_current_e_per_s = 0.0\npixel_pitch_um = 5.0\n";

struct StageCase {
  const char* name;
  const char* toml;   // parsed after the noise-off section
  bool flat = true;   // "zero" and "max" have the documented flat answers
  bool fill = false;  // distortion: sources off the rendered frame are black
};

const StageCase kCases[] = {
    {"distortion bilinear", "[distortion]\nmodel = \"brown\"\nfx = 10.0\nk1 = -0.3\nk2 = 0.1\np1 = 0.001\nfilter = \"bilinear\"\n", true, true},
    {"distortion lanczos3 + chromatic",
     "[distortion]\nmodel = \"brown\"\nfx = 10.0\nk1 = 0.2\nfilter = \"lanczos3\"\nchromatic_scale = [1.002, 1.0, 0.998]\n", true, true},
    {"dof diffusion", "[dof]\nmethod = \"diffusion\"\nfocus_distance_m = 1.0\n[exposure]\nf_number = 1.4\n"},
    {"dof gather", "[dof]\nmethod = \"gather\"\nfocus_distance_m = 1.0\n[exposure]\nf_number = 1.4\n"},
    {"motion vectors", "[motion]\nsource = \"vectors\"\n"},
    {"motion camera, rolling shutter",
     "[motion]\nsource = \"camera\"\nangular_velocity_rad_s = [0.5, -0.3, 5.0]\nline_time_us = 10.0\n"},
    {"flare", "[flare]\nenabled = true\nthreshold = 1.0\n"},
    {"blooming", "[blooming]\nenabled = true\n"},
    {"smear", "[sensor]\nsmear_row_transfer_us = 1.0\n"},
    {"defects and row/column patterns",
     "[sensor]\nhot_pixel_fraction = 0.01\ndead_pixel_fraction = 0.01\nstuck_pixel_fraction = 0.01\n"
     "row_fpn_e = 3.0\ncolumn_fpn_e = 3.0\n",
     false},
};

enum class Radiance { kZero, kMax, kHostile };
const char* RadianceName(Radiance r) { return r == Radiance::kZero ? "zero" : r == Radiance::kMax ? "max" : "hostile"; }

float Cycle(const std::vector<float>& values, size_t i) { return values[i % values.size()]; }

// Writes the scene as an EXR (so the loader's sanitiser runs) and loads it back.
io::SceneFrame MakeScene(int w, int h, Radiance kind) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> depths = {nan, 0.0f, -1.0f, inf, -inf, 1e-30f, 0.3f, 1e10f, 100.0f};
  const std::vector<float> motions = {nan, inf, -inf, 1e30f, -1e30f, 32767.0f, -32767.0f, 0.0f, 3.5f};
  const std::vector<float> hostile = {nan, inf, -inf, -1.0f, 1e30f, 0.0f, 0.5f, 65504.0f, 1e-40f};
  const size_t n = static_cast<size_t>(w) * h;
  std::vector<float> rgb[3], z(n), mx(n), my(n);
  for (int c = 0; c < 3; ++c) rgb[c].resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c)
      rgb[c][i] = kind == Radiance::kZero  ? 0.0f
                  : kind == Radiance::kMax ? 1e30f
                                           : Cycle(hostile, i + static_cast<size_t>(c) * 3);
    z[i] = Cycle(depths, i);
    mx[i] = Cycle(motions, i);
    my[i] = Cycle(motions, i + 4);
  }
  const std::string path = testing::TempDir() + "camsim_extremes_" + std::to_string(getpid()) + ".exr";
  std::string error;
  EXPECT_TRUE(io::WriteExrFloat(path, w, h,
                                {{"R", rgb[0].data(), w},
                                 {"G", rgb[1].data(), w},
                                 {"B", rgb[2].data(), w},
                                 {"Z", z.data(), w},
                                 {"Vector.X", mx.data(), w},
                                 {"Vector.Y", my.data(), w}},
                                &error))
      << error;
  io::SceneFrame scene;
  EXPECT_TRUE(io::LoadSceneExr(path, "", &scene, &error)) << error;
  std::remove(path.c_str());
  EXPECT_TRUE(scene.has_depth && scene.has_motion);
  return scene;
}

struct Output {
  std::vector<uint16_t> raw;  // the sensor stage's DN
  std::vector<uint8_t> rgb;   // the last stage, 8 bit
};

// Renders frame 3 with the given threads and strip height; an empty output
// when configuration fails (*error says why).
Output Render(const host::RunConfig& rc, const host::Origins& origins, const io::SceneFrame& scene, int threads,
              int strip_rows, std::string* error) {
  host::FrameRenderer r(threads, strip_rows);
  if (!r.Configure(rc, origins, scene.width, scene.height, nullptr, error) || !r.SetScene(scene, error)) return {};
  const int w = r.pipeline().width(), h = r.pipeline().height();
  Output o;
  o.raw.resize(static_cast<size_t>(w) * h);
  o.rgb.resize(static_cast<size_t>(w) * h * 3);
  Tap taps[2];
  taps[0].stage = r.SensorIndex();
  taps[0].format = TapFormat::kU16;
  taps[0].data = o.raw.data();
  taps[0].stride = w;
  taps[1].stage = -1;
  taps[1].format = TapFormat::kU8;
  taps[1].data = o.rgb.data();
  taps[1].stride = static_cast<ptrdiff_t>(w) * 3;
  EXPECT_GE(taps[0].stage, 0);
  r.Render(3, taps, 2, nullptr);
  return o;
}

host::RunConfig Config(const StageCase& c, host::Origins* origins) {
  host::RunConfig rc;
  std::string error;
  EXPECT_TRUE(host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, origins, &error)) << error;
  EXPECT_TRUE(host::ParseConfig(kNoiseOff, "noise off", &rc, origins, &error)) << error;
  EXPECT_TRUE(host::ParseConfig(c.toml, c.name, &rc, origins, &error)) << error;
  return rc;
}

const std::pair<int, int> kSizes[] = {{1, 1}, {1, 17}, {17, 1}, {2, 2}, {3, 5}, {13, 7}, {17, 9}};

class ExtremesStages : public testing::TestWithParam<int> {};

TEST_P(ExtremesStages, FlatHostileAndTinyFrames) {
  {
    const StageCase& c = kCases[GetParam()];
    host::Origins origins;
    const host::RunConfig rc = Config(c, &origins);
    for (auto [w, h] : kSizes)
      for (Radiance kind : {Radiance::kZero, Radiance::kMax, Radiance::kHostile}) {
        const std::string what =
            std::string(c.name) + ", " + std::to_string(w) + "x" + std::to_string(h) + ", " + RadianceName(kind);
        const io::SceneFrame scene = MakeScene(w, h, kind);
        std::string error;
        const Output whole = Render(rc, origins, scene, 1, 4096, &error);
        ASSERT_FALSE(whole.raw.empty()) << what << ": " << error;
        EXPECT_EQ(whole.raw.size(), static_cast<size_t>(w) * h) << what;
        for (const auto& [threads, strip] : {std::pair{1, 1}, std::pair{2, 7}}) {
          const Output other = Render(rc, origins, scene, threads, strip, &error);
          EXPECT_TRUE(other.raw == whole.raw && other.rgb == whole.rgb)
              << what << ": " << threads << " threads, strips of " << strip << " differ from one whole strip";
        }
        for (uint16_t d : whole.raw) ASSERT_LE(d, kAdcMaxDn) << what;
        if (c.flat && kind != Radiance::kHostile) {
          const uint16_t want = kind == Radiance::kZero ? kBlackDn : kFullWellDn;
          for (size_t i = 0; i < whole.raw.size(); ++i)
            if (whole.raw[i] != want && !(c.fill && whole.raw[i] == kBlackDn))
              FAIL() << what << ": pixel " << i % static_cast<size_t>(w) << "," << i / static_cast<size_t>(w)
                     << " is " << whole.raw[i] << ", not " << want;
          // The principal point ((w-1)/2, (h-1)/2) maps to itself: a pixel
          // there (odd sizes) reads the scene.
          if (c.fill && w % 2 == 1 && h % 2 == 1) {
            EXPECT_EQ(whole.raw[static_cast<size_t>(h / 2) * w + w / 2], want) << what << ": the centre";
          }
        }
      }
  }
}

INSTANTIATE_TEST_SUITE_P(EveryNewStage, ExtremesStages,
                         testing::Range(0, static_cast<int>(sizeof kCases / sizeof kCases[0])));

TEST(ExtremesStagesDefects, StuckPixelsReadTheAdcMaximumInDarkAndSaturatedFrames) {
  const StageCase& c = kCases[sizeof kCases / sizeof kCases[0] - 1];
  ASSERT_FALSE(c.flat);
  host::Origins origins;
  host::RunConfig rc = Config(c, &origins);
  std::string error;
  // Only stuck pixels (1 %): every sample is then either the flat answer or 4095.
  ASSERT_TRUE(host::ParseConfig("[sensor]\nhot_pixel_fraction = 0.0\ndead_pixel_fraction = 0.0\nrow_fpn_e = 0.0\n"
                                "column_fpn_e = 0.0\n",
                                "stuck only", &rc, &origins, &error))
      << error;
  for (Radiance kind : {Radiance::kZero, Radiance::kMax}) {
    const io::SceneFrame scene = MakeScene(64, 64, kind);
    const Output o = Render(rc, origins, scene, 1, 4096, &error);
    ASSERT_FALSE(o.raw.empty()) << error;
    const uint16_t flat = kind == Radiance::kZero ? kBlackDn : kFullWellDn;
    size_t stuck = 0;
    for (uint16_t d : o.raw) {
      ASSERT_TRUE(d == flat || d == kAdcMaxDn) << RadianceName(kind) << ": " << d;
      stuck += d == kAdcMaxDn;
    }
    // 1 % of 4096 pixels: a binomial draw with mean 41 and sigma 6.4.
    EXPECT_GT(stuck, 10u) << RadianceName(kind);
    EXPECT_LT(stuck, 90u) << RadianceName(kind);
  }
}

}  // namespace
}  // namespace camsim
