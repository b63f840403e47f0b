// End to end: the `camsim` command on the bundled scene, and its errors on bad
// input (clear message, exit code, nothing already written lost).
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/io/image_write.h"
#include "host_tools/render.h"
#include "tests/support/exr_fixture.h"

namespace {

struct Result {
  int code = -1;
  std::string err;
  std::string out;  // standard output
};

std::string TempDir(const std::string& name) {
  const std::string d = testing::TempDir() + "camsim_cli_" + name + "_" + std::to_string(getpid());
  std::system(("rm -rf '" + d + "' && mkdir -p '" + d + "'").c_str());
  return d;
}

// Runs `camsim ARGS` (in directory `cwd` when given).
Result CamsimIn(const std::string& cwd, const std::string& args) {
  const std::string err_file = testing::TempDir() + "camsim_cli_stderr_" + std::to_string(getpid());
  const std::string out_file = testing::TempDir() + "camsim_cli_stdout_" + std::to_string(getpid());
  const std::string cmd = (cwd.empty() ? std::string() : "cd '" + cwd + "' && ") + CAMSIM_BINARY + " " + args +
                          " 2>'" + err_file + "' >'" + out_file + "'";
  Result r;
  const int status = std::system(cmd.c_str());
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  for (const auto& [file, text] : {std::make_pair(err_file, &r.err), std::make_pair(out_file, &r.out)}) {
    std::ifstream in(file);
    std::stringstream s;
    s << in.rdbuf();
    *text = s.str();
  }
  return r;
}

Result Camsim(const std::string& args) { return CamsimIn("", args); }

bool Exists(const std::string& p) {
  struct stat st;
  return stat(p.c_str(), &st) == 0 && st.st_size > 0;
}

std::string Slurp(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const std::string kScene = std::string(CAMSIM_SOURCE_DIR) + "/scenes/aisle_0001.exr";
const std::string kConfig = std::string(CAMSIM_SOURCE_DIR) + "/configs/camera.toml";

TEST(Cli, RunWritesRawRgbAndReport) {
  const std::string out = TempDir("run");
  const Result r = Camsim("run --config " + kConfig + " --input " + kScene + " --out " + out + " --report " + out +
                          "/report.json --threads 2");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Exists(out + "/aisle_0001.png"));
  EXPECT_TRUE(Exists(out + "/aisle_0001.raw.pgm"));
  EXPECT_TRUE(Exists(out + "/aisle_0001.raw.json"));
  const std::string raw = Slurp(out + "/aisle_0001.raw");
  EXPECT_EQ(raw.size(), 640u * 480u * 2u);
  EXPECT_EQ(Slurp(out + "/aisle_0001.raw.pgm").substr(0, 15), "P5\n640 480\n4095");
  const std::string report = Slurp(out + "/report.json");
  EXPECT_NE(report.find("\"left_out_because\": \"colour matrix is the identity\""), std::string::npos) << report;
  EXPECT_NE(report.find("\"mean_electrons\""), std::string::npos);
  // The demo camera's Bayer CFA runs ahead of exposure and vignetting, and the report says why.
  EXPECT_NE(report.find("{\"name\": \"cfa\", \"runs\": true, \"output\": \"radiance Q16.16\", \"channels\": 1"),
            std::string::npos) << report;
  EXPECT_NE(report.find("\"moved_because\": \"runs ahead of the exposure and vignetting configured before it"),
            std::string::npos)
      << report;
  EXPECT_NE(report.find("\"workspace_bytes\""), std::string::npos);
  EXPECT_NE(report.find("\"error\": null"), std::string::npos);
}

TEST(Cli, ThreadsAndStripRowsGiveTheSameBytes) {
  const std::string a = TempDir("same_a"), b = TempDir("same_b");
  ASSERT_EQ(Camsim("run --config " + kConfig + " --input " + kScene + " --out " + a + " --quiet").code, 0);
  ASSERT_EQ(Camsim("run --config " + kConfig + " --input " + kScene + " --out " + b +
                   " --quiet --threads 3 --strip-rows 5")
                .code,
            0);
  EXPECT_EQ(Slurp(a + "/aisle_0001.png"), Slurp(b + "/aisle_0001.png"));
  EXPECT_EQ(Slurp(a + "/aisle_0001.raw"), Slurp(b + "/aisle_0001.raw"));
}

// Without --strip-rows each thread runs one strip (the fewest rows
// recomputed at strip edges; host::StripRows); an explicit height wins. The
// report says what was used.
TEST(Cli, DefaultStripsFollowTheThreadCount) {
  EXPECT_EQ(camsim::host::StripRows(0, 1080, 1), 1080);
  EXPECT_EQ(camsim::host::StripRows(0, 1080, 2), 540);
  EXPECT_EQ(camsim::host::StripRows(0, 1080, 3), 360);
  EXPECT_EQ(camsim::host::StripRows(0, 7, 3), 3);
  EXPECT_EQ(camsim::host::StripRows(0, 1080, 0), 1080);
  EXPECT_EQ(camsim::host::StripRows(0, 1, 4), 1);
  EXPECT_EQ(camsim::host::StripRows(5, 1080, 2), 5);
  const std::string out = TempDir("auto_strip");
  const Result r = Camsim("run --config " + kConfig + " --input " + kScene + " --out " + out +
                          " --quiet --threads 2 --report " + out + "/report.json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(Slurp(out + "/report.json").find("\"threads\": 2, \"strip_rows\": 240,"), std::string::npos);
  EXPECT_NE(Camsim("run --config " + kConfig + " --input " + kScene + " --out " + out + " --strip-rows 0").code, 0)
      << "an explicit strip height must be >= 1";
}

// The planner's savings in the report: depth of field at f/4 focused at 5 m
// leaves the in-focus part of the bundled scene unblurred; motion blur from
// the scene's vectors (nearly all zero) skips over 99 % of the pixels; flare
// skips the tiles without a bright pixel. Each says which pixels it skipped.
// --measure-savings times the frame again with skipping off: DoF's and
// motion blur's savings are measured (motion blur's clearly above the
// noise: it would sample every pixel), flare's cannot be (its skipped pixels
// source nothing).
TEST(Cli, ReportSaysWhatWasSkippedAndTheTimeSaved) {
  const std::string out = TempDir("savings");
  const std::string run = "run --config " + std::string(CAMSIM_SOURCE_DIR) + "/configs/tradeoff.toml --input " +
                          kScene + " --out " + out + " --set exposure.f_number=4 --set dof.focus_distance_m=5" +
                          " --set motion.source=\\\"vectors\\\" --set flare.enabled=true --report " + out +
                          "/report.json";
  const Result plain = Camsim(run);
  ASSERT_EQ(plain.code, 0) << plain.err;
  EXPECT_EQ(Slurp(out + "/report.json").find("\"time_saved_ms_per_frame\": 0"), std::string::npos)
      << "no time saved without --measure-savings";
  EXPECT_NE(Slurp(out + "/report.json").find("\"time_saved_ms_per_frame\": null"), std::string::npos);
  const Result r = Camsim(run + " --measure-savings 3");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("skipped"), std::string::npos) << r.err;
  const std::string report = Slurp(out + "/report.json");
  auto stage = [&](const std::string& name) {
    const size_t at = report.find("\"name\": \"" + name + "\"");
    return at == std::string::npos ? std::string() : report.substr(at, report.find('}', report.find('}', at) + 1) - at);
  };
  for (const char* name : {"dof_rows", "dof_columns"}) {
    const std::string s = stage(name);
    const size_t f = s.find("\"skipped_fraction\": ");
    ASSERT_NE(f, std::string::npos) << name << ": " << s;
    const double skipped = std::atof(s.c_str() + f + 20);
    EXPECT_GT(skipped, 0.2) << name;
    EXPECT_LT(skipped, 0.6) << name;
    const size_t t = s.find("\"time_saved_ms_per_frame\": ");
    ASSERT_NE(t, std::string::npos) << name;
    const char* v = s.c_str() + t + 27;
    EXPECT_TRUE(*v == '-' || (*v >= '0' && *v <= '9')) << name << ": measured, a number: " << s;
    EXPECT_NE(s.find("\"skipped_pixels_are\": \"linked to no neighbour"), std::string::npos) << name << ": " << s;
  }
  const std::string motion = stage("motion_blur");
  const size_t mf = motion.find("\"skipped_fraction\": ");
  ASSERT_NE(mf, std::string::npos) << motion;
  EXPECT_GT(std::atof(motion.c_str() + mf + 20), 0.99) << motion;
  const size_t mt = motion.find("\"time_saved_ms_per_frame\": ");
  ASSERT_NE(mt, std::string::npos) << motion;
  // A wall-clock difference: a number here; what it saves is a benchmark's business (docs/performance.md).
  const char* mv = motion.c_str() + mt + 27;
  EXPECT_TRUE(*mv == '-' || (*mv >= '0' && *mv <= '9')) << "measured, a number: " << motion;
  EXPECT_NE(motion.find("\"skipped_pixels_are\": \"not moving, copied\""), std::string::npos) << motion;
  // Flare: the scene's few bright tiles source it; the rest are skipped (Flare.CountsThePixelsOfTilesWithoutABrightPixel).
  const std::string flare = stage("flare");
  const size_t ff = flare.find("\"skipped_fraction\": ");
  ASSERT_NE(ff, std::string::npos) << flare;
  EXPECT_GT(std::atof(flare.c_str() + ff + 20), 0.9) << flare;
  EXPECT_LT(std::atof(flare.c_str() + ff + 20), 1.0) << flare;
  EXPECT_NE(flare.find("\"skipped_pixels_are\": \"in tiles without a bright pixel"), std::string::npos) << flare;
  EXPECT_NE(flare.find("\"time_saved_ms_per_frame\": null"), std::string::npos) << "nothing to run on flare's skipped pixels";
  EXPECT_NE(r.err.find("of pixels: in tiles without a bright pixel"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not moving, copied, saved "), std::string::npos) << r.err;
  EXPECT_NE(report.find("\"savings_measured\": {\"rounds\": 3, \"frames\": 1, \"wall_ms_per_frame_skipping\": "),
            std::string::npos) << report;
}

TEST(Cli, SixteenBitOutputAndMonoSensor) {
  const std::string out = TempDir("sixteen");
  const Result r = Camsim("run --config " + kConfig + " --input " + kScene + " --out " + out +
                          " --quiet --set output.bits=16 --set sensor.cfa=Mono --set sensor.width=320"
                          " --set sensor.height=240 --set sensor.scene_fit=scale");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string png = Slurp(out + "/aisle_0001.png");
  ASSERT_GT(png.size(), 26u);
  // IHDR: width and height (big-endian) at 16 and 20, bit depth at 24, colour type at 25 (0 = grey).
  const auto be32 = [&](size_t at) {
    uint32_t v = 0;
    for (size_t i = 0; i < 4; ++i) v = v << 8 | static_cast<unsigned char>(png[at + i]);
    return v;
  };
  EXPECT_EQ(be32(16), 320u);
  EXPECT_EQ(be32(20), 240u);
  EXPECT_EQ(static_cast<unsigned char>(png[24]), 16);
  EXPECT_EQ(static_cast<unsigned char>(png[25]), 0);
}

TEST(Cli, StagesAndDumpWriteIntermediates) {
  const std::string out = TempDir("stages");
  const Result r = Camsim("run --config " + kConfig + " --input " + kScene + " --out " + out +
                          " --stages exposure,vignetting --dump-stages --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Exists(out + "/aisle_0001.exr"));  // photons as float EXR
  EXPECT_TRUE(Exists(out + "/aisle_0001.0_exposure.exr"));
  EXPECT_TRUE(Exists(out + "/aisle_0001.1_vignetting.exr"));
  // What they hold: the last dump is the output; the exposure dump is the
  // scene times one factor; the vignetting dump is the exposure dump times a
  // gain of 1 at the centre, falling towards the corners (cos4).
  camsim::io::SceneFrame scene, exposed, vignetted, output;
  std::string error;
  ASSERT_TRUE(camsim::io::LoadSceneExr(kScene, "", &scene, &error)) << error;
  ASSERT_TRUE(camsim::io::LoadSceneExr(out + "/aisle_0001.0_exposure.exr", "", &exposed, &error)) << error;
  ASSERT_TRUE(camsim::io::LoadSceneExr(out + "/aisle_0001.1_vignetting.exr", "", &vignetted, &error)) << error;
  ASSERT_TRUE(camsim::io::LoadSceneExr(out + "/aisle_0001.exr", "", &output, &error)) << error;
  ASSERT_EQ(exposed.width, scene.width);
  ASSERT_EQ(exposed.height, scene.height);
  EXPECT_TRUE(output.r.data == vignetted.r.data && output.g.data == vignetted.g.data &&
              output.b.data == vignetted.b.data);
  double lo = INFINITY, hi = 0;
  for (size_t i = 0; i < scene.g.data.size(); ++i)
    if (scene.g.data[i] > 0.05f) {  // well above the Q16.16 radiance and Q24.8 photon steps
      const double ratio = exposed.g.data[i] / scene.g.data[i];
      lo = std::min(lo, ratio);
      hi = std::max(hi, ratio);
    }
  ASSERT_GT(lo, 0.0);
  EXPECT_LT(hi / lo, 1.001) << "exposure is one factor for every pixel";
  const int w = scene.width, h = scene.height;
  const auto gain = [&](int x, int y) {
    const float e = exposed.g.at(x, y);
    return e > 0 ? vignetted.g.at(x, y) / e : 1.0f;
  };
  EXPECT_NEAR(gain(w / 2, h / 2), 1.0f, 0.01f);
  EXPECT_LT(gain(0, 0), 0.9f * gain(w / 2, h / 2));
  for (size_t i = 0; i < exposed.g.data.size(); ++i)
    ASSERT_LE(vignetted.g.data[i], exposed.g.data[i] * 1.0001f + 0.01f) << "pixel " << i << " brightened";
}

// A repeated name used to be kept once per listing, past the end of a
// stack array of one entry per stage.
TEST(Cli, StagesRefuseARepeatedName) {
  const std::string out = TempDir("stages_twice");
  const Result twice = Camsim("run --input " + kScene + " --out " + out + " --stages exposure,sensor,sensor");
  EXPECT_EQ(twice.code, 1);
  EXPECT_NE(twice.err.find("--stages: stage 'sensor' is named more than once"), std::string::npos) << twice.err;
  std::string many = "sensor";
  for (int i = 0; i < 16; ++i) many += ",sensor";
  const Result overflow = Camsim("run --input " + kScene + " --out " + out + " --stages " + many);
  EXPECT_EQ(overflow.code, 1);
  EXPECT_NE(overflow.err.find("'sensor' is named more than once"), std::string::npos) << overflow.err;
}

// Review finding: `--stages 'exposure, sensor'` was refused over the space
// ("unknown stage ' sensor'"): spaces around a name are not part of it.
TEST(Cli, StagesTakeSpacesAroundNames) {
  const std::string out = TempDir("stages_spaces");
  const Result spaced = Camsim("run --input " + kScene + " --out " + out + " --quiet --stages ' exposure, sensor '" +
                               " --report " + out + "/r.json");
  ASSERT_EQ(spaced.code, 0) << spaced.err;
  const std::string report = Slurp(out + "/r.json");
  EXPECT_NE(report.find("{\"name\": \"sensor\", \"runs\": true"), std::string::npos) << report;
  EXPECT_NE(report.find("{\"name\": \"exposure\", \"runs\": true"), std::string::npos) << report;
  EXPECT_EQ(report.find("\"gamma\""), std::string::npos) << report;
  const Result inside = Camsim("run --input " + kScene + " --out " + out + " --quiet --stages 'expo sure'");
  EXPECT_EQ(inside.code, 1);
  EXPECT_NE(inside.err.find("--stages: unknown stage 'expo sure'"), std::string::npos) << inside.err;
}

// The raw file holds each sample in the low adc_bits of a little-endian
// 16-bit word; the sidecar says so, and names the GenICam PFNC format only
// where one describes that layout (none does for 8 bits in 2 bytes).
TEST(Cli, RawSidecarDescribesTheSamples) {
  const std::string out = TempDir("sidecar");
  const std::string small = " --quiet --set sensor.width=64 --set sensor.height=48";
  ASSERT_EQ(Camsim("run --config " + kConfig + " --input " + kScene + " --out " + out + small).code, 0);
  const std::string twelve = Slurp(out + "/aisle_0001.raw.json");
  EXPECT_NE(twelve.find("\"pixel_format\": \"BayerRG12\", \"cfa\": \"BayerRG\", \"adc_bits\": 12, "
                        "\"bytes_per_pixel\": 2, \"significant_bits\": 12, \"alignment\": \"lsb\", "
                        "\"byte_order\": \"little\""),
            std::string::npos)
      << twelve;
  ASSERT_EQ(Camsim("run --config " + kConfig + " --input " + kScene + " --out " + out + small +
                   " --set sensor.adc_bits=8 --set sensor.cfa=Mono")
                .code,
            0);
  const std::string eight = Slurp(out + "/aisle_0001.raw.json");
  EXPECT_NE(eight.find("\"pixel_format\": null, \"cfa\": \"Mono\", \"adc_bits\": 8, \"bytes_per_pixel\": 2, "
                       "\"significant_bits\": 8, \"alignment\": \"lsb\""),
            std::string::npos)
      << eight;
  const std::string raw = Slurp(out + "/aisle_0001.raw");
  ASSERT_EQ(raw.size(), 64u * 48u * 2u);
  int high = 0, low = 0;  // bytes set in the high and low halves of the samples
  for (size_t i = 0; i < raw.size(); i += 2) {
    low += raw[i] != 0;
    high += raw[i + 1] != 0;
  }
  EXPECT_GT(low, 0);
  EXPECT_EQ(high, 0);  // 8-bit samples in the low byte
}

// Without a CFA stage the sensor puts out three channels (one sensor per
// colour): the raw files hold all of them, interleaved as RGB, as a 16-bit PPM
// and a sidecar that says so. They used to hold a third of it labelled Bayer.
TEST(Cli, RawOutputOfAnRgbSensorKeepsAllThreeChannels) {
  const std::string out = TempDir("raw_rgb");
  const Result r = Camsim("run --input " + kScene + " --out " + out + " --stages exposure,sensor --quiet --report " +
                          out + "/report.json --set sensor.width=64 --set sensor.height=48");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string side = Slurp(out + "/aisle_0001.raw.json");
  EXPECT_NE(side.find("\"width\": 64, \"height\": 48, \"channels\": 3, \"channel_order\": \"RGB\", "
                      "\"pixel_format\": \"RGB12\", \"cfa\": null, \"adc_bits\": 12, \"bytes_per_pixel\": 6, "
                      "\"significant_bits\": 12"),
            std::string::npos)
      << side;
  EXPECT_FALSE(Exists(out + "/aisle_0001.raw.pgm"));
  const std::string ppm = Slurp(out + "/aisle_0001.raw.ppm");
  const std::string header = "P6\n64 48\n4095\n";
  ASSERT_EQ(ppm.size(), header.size() + 64u * 48u * 3u * 2u);
  EXPECT_EQ(ppm.substr(0, header.size()), header);
  const std::string raw = Slurp(out + "/aisle_0001.raw");
  ASSERT_EQ(raw.size(), 64u * 48u * 3u * 2u);
  // The PPM holds the .raw samples (big-endian there), and their per-channel
  // means are the sensor stage's means in the report.
  double sum[3] = {0, 0, 0};
  for (size_t i = 0; i < raw.size() / 2; ++i) {
    const unsigned lo = static_cast<unsigned char>(raw[2 * i]), hi = static_cast<unsigned char>(raw[2 * i + 1]);
    ASSERT_EQ(static_cast<unsigned char>(ppm[header.size() + 2 * i]), hi) << "sample " << i;
    ASSERT_EQ(static_cast<unsigned char>(ppm[header.size() + 2 * i + 1]), lo) << "sample " << i;
    sum[i % 3] += hi * 256 + lo;
  }
  const std::string report = Slurp(out + "/report.json");
  const size_t sensor = report.find("\"name\": \"sensor\"");
  ASSERT_NE(sensor, std::string::npos) << report;
  EXPECT_NE(report.find("\"channels\": 3, \"mosaic\": false", sensor), std::string::npos) << report;
  const size_t mean = report.find("\"mean\": {", sensor);
  ASSERT_NE(mean, std::string::npos) << report;
  const char* names[3] = {"\"R\": ", "\"G\": ", "\"B\": "};
  for (int c = 0; c < 3; ++c) {
    const size_t at = report.find(names[c], mean);
    ASSERT_NE(at, std::string::npos) << report;
    EXPECT_NEAR(sum[c] / (64 * 48), std::stod(report.substr(at + 5)), 0.01) << "channel " << c;
  }
  EXPECT_NE(report.find("\"outputs\": [\"" + out + "/aisle_0001.raw.ppm\", \"" + out + "/aisle_0001.raw\", \"" + out +
                        "/aisle_0001.raw.json\"]"),
            std::string::npos)
      << report;
}

// Outputs are named after the input's stem in --out: refused before anything
// is written when that would overwrite an input or another frame's output.
TEST(Cli, RunRefusesToOverwriteAnInputOrAnotherFramesOutput) {
  const std::string dir = TempDir("clobber");
  std::system(("mkdir -p '" + dir + "/a' '" + dir + "/b' '" + dir + "/c' && cp '" + kScene + "' '" + dir +
               "/a/0001.exr' && cp '" + kScene + "' '" + dir + "/b/0001.exr' && cp '" + kScene + "' '" + dir +
               "/c/x.exr' && cp '" + kScene + "' '" + dir + "/c/x.EXR'")
                  .c_str());
  const std::string scene = Slurp(kScene);
  // --stages exposure ends in photons, written as <stem>.exr: the input itself.
  const Result self = Camsim("run --input " + dir + "/a/0001.exr --out " + dir + "/a/. --stages exposure --quiet");
  EXPECT_EQ(self.code, 1);
  EXPECT_NE(self.err.find("frame 0 (" + dir + "/a/0001.exr) would write '" + dir + "/a/./0001.exr', overwriting "
                          "the input '" + dir + "/a/0001.exr'"),
            std::string::npos)
      << self.err;
  EXPECT_TRUE(Slurp(dir + "/a/0001.exr") == scene);
  const Result report = Camsim("run --input " + dir + "/a/0001.exr --out " + dir + "/out --report " + dir +
                               "/a/0001.exr --quiet");
  EXPECT_EQ(report.code, 1);
  EXPECT_NE(report.err.find("--report would write '" + dir + "/a/0001.exr', overwriting the input"), std::string::npos)
      << report.err;
  EXPECT_TRUE(Slurp(dir + "/a/0001.exr") == scene);
  // Two inputs with one stem, for a mosaic and for a 3-channel sensor (whose raw image is a PPM).
  for (const auto& [stages, raw] :
       {std::pair{"exposure,cfa,sensor", "raw.pgm"}, std::pair{"exposure,sensor", "raw.ppm"}}) {
    const Result same = Camsim("run --input " + dir + "/a/0001.exr " + dir + "/b/0001.exr --out " + dir +
                               "/out --stages " + stages + " --quiet");
    EXPECT_EQ(same.code, 1);
    EXPECT_NE(same.err.find("frame 0 (" + dir + "/a/0001.exr) and frame 1 (" + dir + "/b/0001.exr) would both write '" +
                            dir + "/out/0001." + raw + "'"),
              std::string::npos)
        << same.err;
    EXPECT_FALSE(Exists(dir + "/out/0001." + raw));
  }
  const Result cased = Camsim("run --input " + dir + "/c --out " + dir + "/out --stages exposure,cfa,sensor --quiet");
  EXPECT_EQ(cased.code, 1);
  EXPECT_NE(cased.err.find("would both write '" + dir + "/out/x.raw.pgm'"), std::string::npos) << cased.err;
  EXPECT_FALSE(Exists(dir + "/out/0001.raw.pgm"));
  EXPECT_FALSE(Exists(dir + "/out/x.raw.pgm"));
  // The same directory is fine when no output takes an input's name.
  const Result beside = Camsim("run --input " + dir + "/a/0001.exr --out " + dir + "/a --stages exposure,cfa,sensor "
                               "--quiet");
  EXPECT_EQ(beside.code, 0) << beside.err;
  EXPECT_TRUE(Exists(dir + "/a/0001.raw"));
  EXPECT_TRUE(Slurp(dir + "/a/0001.exr") == scene);
}

// One depth file cannot describe a sequence; it used to be dropped silently.
TEST(Cli, DepthFileWithASequenceIsAnError) {
  const std::string dir = TempDir("depth_seq");
  std::system(("cp '" + kScene + "' '" + dir + "/seq_0001.exr' && cp '" + kScene + "' '" + dir + "/seq_0002.exr'")
                  .c_str());
  const Result r = Camsim("run --input " + dir + "/seq_%04d.exr --depth " + kScene + " --out " + dir +
                          "/out --stages exposure,cfa,sensor --quiet");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--depth " + kScene + ": the inputs are 2 frames, and one depth file cannot describe a "
                       "sequence"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(Exists(dir + "/out/seq_0001.raw"));
  const Result one = Camsim("run --input " + dir + "/seq_0001.exr --depth " + kScene + " --out " + dir +
                            "/out --stages exposure,cfa,sensor --quiet");
  EXPECT_EQ(one.code, 0) << one.err;
}

// A directory opens as a file on Linux and reads as nothing: it used to pass
// as an empty (all defaults) configuration.
TEST(Cli, ConfigThatIsADirectoryIsRefused) {
  const std::string dir = TempDir("config_dir");
  const Result check = Camsim("config --check " + dir);
  EXPECT_EQ(check.code, 1);
  EXPECT_NE(check.err.find(dir + ": cannot read configuration file: is a directory"), std::string::npos)
      << check.err;
  const Result run = Camsim("run --config " + dir + " --input " + kScene + " --out " + dir + "/out");
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find(dir + ": cannot read configuration file"), std::string::npos) << run.err;
}

// A pipe is read like a file (--config <(...), /dev/stdin): only directories are refused.
TEST(Cli, ConfigFromAPipeIsRead) {
  const std::string err = TempDir("config_pipe") + "/err";
  const auto check = [&](const std::string& toml) {
    const std::string cmd = "printf '" + toml + "' | " + CAMSIM_BINARY + " config --check /dev/stdin 2>'" + err + "'";
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  EXPECT_EQ(check("[sensor]\\nadc_bits = 10\\n"), 0) << Slurp(err);
  EXPECT_EQ(check("[sensor]\\nful_well_e = 1\\n"), 1);  // read, and its typo found
  EXPECT_NE(Slurp(err).find("did you mean 'sensor.full_well_e'"), std::string::npos) << Slurp(err);
}

TEST(Cli, ConfigTypoNamesKeyAndLine) {
  const std::string dir = TempDir("typo");
  std::ofstream(dir + "/bad.toml") << "[sensor]\nadc_bits = 12\nful_well_e = 100\n";
  const Result r = Camsim("run --config " + dir + "/bad.toml --input " + kScene + " --out " + dir);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("bad.toml:3"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("did you mean 'sensor.full_well_e'"), std::string::npos) << r.err;
  // A known section that is not a table (it used to be "unknown section 'sensor' (did you mean 'sensor'?)").
  camsim::host::RunConfig rc;
  camsim::host::Origins origins;
  std::string error;
  EXPECT_FALSE(camsim::host::ParseConfig("[[sensor]]\nadc_bits = 12\n", "a.toml", &rc, &origins, &error));
  EXPECT_NE(error.find("'sensor' must be a table: write [sensor] (one pair of brackets, not [[sensor]])"),
            std::string::npos)
      << error;
  EXPECT_FALSE(camsim::host::ParseConfig("sensor = 1\n", "b.toml", &rc, &origins, &error));
  EXPECT_NE(error.find("b.toml:1: 'sensor' must be a table: write [sensor] and its keys below it"), std::string::npos)
      << error;
}

TEST(Cli, OutOfRangeValueNamesKeyAndLine) {
  const std::string dir = TempDir("range");
  std::ofstream(dir + "/bad.toml") << "[exposure]\n\nf_number = 0.1\n";
  const Result r = Camsim("run --config " + dir + "/bad.toml --input " + kScene + " --out " + dir);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("bad.toml:3: exposure.f_number must be in [0.5, 128]"), std::string::npos) << r.err;
  const Result s = Camsim("run --set sensor.adc_bits=20 --input " + kScene + " --out " + dir);
  EXPECT_NE(s.err.find("--set sensor.adc_bits=20: sensor.adc_bits"), std::string::npos) << s.err;
  // Review finding: a range error the core finds echoes the --set argument, as parse errors do.
  const Result negative = Camsim("run --set exposure.exposure_time_us=-1 --input " + kScene + " --out " + dir);
  EXPECT_EQ(negative.code, 1);
  EXPECT_NE(negative.err.find("camsim: --set exposure.exposure_time_us=-1: exposure.exposure_time_us "),
            std::string::npos)
      << negative.err;
  const Result nan = Camsim("run --set exposure.f_number=nan --input " + kScene + " --out " + dir);
  EXPECT_EQ(nan.code, 1);
  EXPECT_NE(nan.err.find("exposure.f_number"), std::string::npos) << nan.err;
  // A mask mode without its image names the mode's --set.
  const Result mask = Camsim("run --set vignetting.mode=mask --input " + kScene + " --out " + dir);
  EXPECT_EQ(mask.code, 1);
  EXPECT_NE(mask.err.find("--set vignetting.mode=mask: vignetting.mode: 'mask' needs a mask image (vignetting.mask)"),
            std::string::npos)
      << mask.err;
  // A core message that is a clause of its own follows the key after a
  // colon, from a --set or a file (it read "distortion.k1 the radial model ...").
  const Result fold = Camsim("run --set distortion.model=brown --set distortion.k1=-5 --input " + kScene + " --out " + dir);
  EXPECT_EQ(fold.code, 1);
  EXPECT_NE(fold.err.find("camsim: --set distortion.k1=-5: distortion.k1: the radial model folds over"),
            std::string::npos)
      << fold.err;
  std::ofstream(dir + "/fold.toml") << "[distortion]\nmodel = \"brown\"\nk1 = -5\n";
  const Result fold_file = Camsim("run --config " + dir + "/fold.toml --input " + kScene + " --out " + dir);
  EXPECT_EQ(fold_file.code, 1);
  EXPECT_NE(fold_file.err.find("fold.toml:3: distortion.k1: the radial model folds over"), std::string::npos)
      << fold_file.err;
}

// Every file a run reads is an input no output may replace: the --config
// file and the files the configuration names, not only the scenes.
TEST(Cli, RunRefusesToOverwriteTheConfigOrAFileItNames) {
  const std::string dir = TempDir("clobber_config");
  std::ofstream(dir + "/cam.toml") << "[sensor]\nadc_bits = 12\n";
  std::ofstream(dir + "/defects.txt") << "1,1,hot\n";
  const std::string config = Slurp(dir + "/cam.toml"), defects = Slurp(dir + "/defects.txt");
  const Result report = Camsim("run --input " + kScene + " --out " + dir + "/out --config " + dir + "/cam.toml" +
                               " --report " + dir + "/cam.toml --quiet");
  EXPECT_EQ(report.code, 1);
  EXPECT_NE(report.err.find("--report would write '" + dir + "/cam.toml', overwriting the input '" + dir +
                            "/cam.toml' (--config)"),
            std::string::npos)
      << report.err;
  EXPECT_EQ(Slurp(dir + "/cam.toml"), config);
  const Result listed = Camsim("run --input " + kScene + " --out " + dir + "/out --set sensor.defects_file=" + dir +
                               "/defects.txt --report " + dir + "/defects.txt --quiet");
  EXPECT_EQ(listed.code, 1);
  EXPECT_NE(listed.err.find("overwriting the input '" + dir + "/defects.txt' (sensor.defects_file)"), std::string::npos)
      << listed.err;
  EXPECT_EQ(Slurp(dir + "/defects.txt"), defects);
  // A frame's output named like the vignetting mask: <stem>.png in --out.
  std::system(("cp '" + kScene + "' '" + dir + "/scene.exr'").c_str());
  ASSERT_EQ(Camsim("preview --input " + kScene + " --out " + dir + "/scene.png").code, 0);
  const std::string mask = Slurp(dir + "/scene.png");
  const Result frame = Camsim("run --input " + dir + "/scene.exr --out " + dir + " --set vignetting.mode=mask" +
                              " --set vignetting.mask=" + dir + "/scene.png --quiet");
  EXPECT_EQ(frame.code, 1);
  EXPECT_NE(frame.err.find("overwriting the input '" + dir + "/scene.png' (vignetting.mask)"), std::string::npos)
      << frame.err;
  EXPECT_EQ(Slurp(dir + "/scene.png"), mask);
}

TEST(Cli, PreviewRefusesToOverwriteItsInput) {
  const std::string dir = TempDir("preview_self");
  std::system(("cp '" + kScene + "' '" + dir + "/s.exr' && ln -s s.exr '" + dir + "/link.exr'").c_str());
  const std::string scene = Slurp(dir + "/s.exr");
  for (const std::string& out : {dir + "/s.exr", dir + "/./s.exr", dir + "/link.exr"}) {
    const Result r = Camsim("preview --input " + dir + "/s.exr --out " + out);
    EXPECT_EQ(r.code, 1) << out;
    EXPECT_NE(r.err.find("would overwrite the input"), std::string::npos) << r.err;
  }
  EXPECT_EQ(Slurp(dir + "/s.exr"), scene);
}

// A vignetting mask or metering image with values the core cannot hold is
// refused, naming the key, the file and the pixel (they used to be clamped
// or read as 0 without a word).
TEST(Cli, MaskAndMeteringImageValuesAreChecked) {
  const std::string dir = TempDir("mask_values");
  std::vector<float> values(4 * 3, 1.0f);
  const auto write = [&](const std::string& name, int at, float v) {
    std::vector<float> m = values;
    m[static_cast<size_t>(at)] = v;
    std::string error;
    ASSERT_TRUE(camsim::io::WriteExrFloat(dir + "/" + name, 4, 3, {{"Y", m.data(), 4}}, &error)) << error;
  };
  write("nan.exr", 6, std::nanf(""));
  write("huge.exr", 5, 1e30f);
  write("negative.exr", 0, -0.5f);
  const std::string mask = "run --input " + kScene + " --out " + dir + "/out --quiet --set vignetting.mode=mask";
  const Result nan = Camsim(mask + " --set vignetting.mask=" + dir + "/nan.exr");
  EXPECT_EQ(nan.code, 1);
  EXPECT_NE(nan.err.find("vignetting.mask: " + dir + "/nan.exr: pixel (2, 1) is nan; values must be numbers in "
                         "[0, 3.99994]"),
            std::string::npos)
      << nan.err;
  const Result huge = Camsim(mask + " --set vignetting.mask=" + dir + "/huge.exr");
  EXPECT_EQ(huge.code, 1);
  EXPECT_NE(huge.err.find("pixel (1, 1) is 1e+30"), std::string::npos) << huge.err;
  const Result missing = Camsim(mask + " --set vignetting.mask=" + dir + "/none.png");
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.err.find("vignetting.mask: cannot open '" + dir + "/none.png'"), std::string::npos) << missing.err;
  const Result metering = Camsim("run --input " + kScene + " --out " + dir + "/out --quiet --set auto_exposure.mode=continuous" +
                                 " --set auto_exposure.metering=image --set auto_exposure.metering_image=" + dir +
                                 "/negative.exr");
  EXPECT_EQ(metering.code, 1);
  EXPECT_NE(metering.err.find("auto_exposure.metering_image: " + dir + "/negative.exr: pixel (0, 0) is -0.5"),
            std::string::npos)
      << metering.err;
  EXPECT_FALSE(Exists(dir + "/out/aisle_0001.raw.pgm"));
}

// Planner refusals name the stage list (they used to say "(default value)").
TEST(Cli, AStageOrderErrorNamesPipelineStages) {
  const std::string dir = TempDir("stage_order");
  const Result flag = Camsim("run --input " + kScene + " --out " + dir + " --stages sensor --quiet");
  EXPECT_EQ(flag.code, 1);
  EXPECT_NE(flag.err.find("camsim: --stages: pipeline.stages: sensor needs"), std::string::npos) << flag.err;
  std::ofstream(dir + "/order.toml") << "[pipeline]\nstages = [\"sensor\", \"exposure\"]\n";
  const Result file = Camsim("run --input " + kScene + " --out " + dir + " --config " + dir + "/order.toml --quiet");
  EXPECT_EQ(file.code, 1);
  EXPECT_NE(file.err.find("order.toml:2: pipeline.stages: sensor needs"), std::string::npos) << file.err;
}

// An out-of-range adc_bits with a defects file: the range error, not
// undefined behaviour in the defects reader (which used to shift by it).
TEST(Cli, ConfigCheckOfAdcBitsWithADefectsFile) {
  const std::string dir = TempDir("adc_defects");
  std::ofstream(dir + "/d.txt") << "1,1,stuck\n";
  std::ofstream(dir + "/cam.toml") << "[sensor]\nwidth = 64\nheight = 48\nadc_bits = 100\ndefects_file = \"" + dir +
                                          "/d.txt\"\n";
  const Result r = Camsim("config --check " + dir + "/cam.toml");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("cam.toml:4: sensor.adc_bits must be 8 to 16"), std::string::npos) << r.err;
  // Without a sensor size the check runs at a stand-in size, and says so
  // when the error can depend on the size (a defect outside 640x480)...
  std::ofstream(dir + "/far.txt") << "700,10,stuck\n";
  std::ofstream(dir + "/nosize.toml") << "[sensor]\ndefects_file = \"far.txt\"\n";
  const Result stand_in = Camsim("config --check " + dir + "/nosize.toml");
  EXPECT_EQ(stand_in.code, 1);
  EXPECT_NE(stand_in.err.find("used a 640x480 stand-in"), std::string::npos) << stand_in.err;
  // ... and (review finding) not after an error no size can change.
  for (const char* text : {"[sensor]\nadc_bits = 17\n", "[exposure]\nf_number = 200\n"}) {
    std::ofstream(dir + "/nosize.toml") << text;
    const Result fixed = Camsim("config --check " + dir + "/nosize.toml");
    EXPECT_EQ(fixed.code, 1) << text;
    EXPECT_NE(fixed.err.find("nosize.toml:2: "), std::string::npos) << text << fixed.err;
    EXPECT_EQ(fixed.err.find("stand-in"), std::string::npos) << text << fixed.err;
  }
}

// `camsim emva` and `camsim tradeoff` name the file and line of an
// out-of-range value, as `camsim run` does (they used to say "(default value)").
TEST(Cli, EmvaAndTradeoffRangeErrorsNameKeyAndLine) {
  const std::string dir = TempDir("range_tools");
  std::ofstream(dir + "/bad.toml") << "[exposure]\n\nf_number = 0.1\n";
  const Result emva = Camsim("emva --config " + dir + "/bad.toml --size 16 --levels 20");
  EXPECT_EQ(emva.code, 1);
  EXPECT_NE(emva.err.find("bad.toml:3: exposure.f_number must be in [0.5, 128]"), std::string::npos) << emva.err;
  const Result tradeoff = Camsim("tradeoff --config " + dir + "/bad.toml --input " + kScene + " --out " + dir +
                                 "/out --frames 1");
  EXPECT_EQ(tradeoff.code, 1);
  EXPECT_NE(tradeoff.err.find("bad.toml:3: exposure.f_number must be in [0.5, 128]"), std::string::npos)
      << tradeoff.err;
}

// A bad --set is named once, as `camsim run` and `camsim emva` name it
// (tradeoff used to print "--set X: --set X: ...").
TEST(Cli, TradeoffNamesABadSetOnce) {
  const std::string dir = TempDir("tradeoff_set");
  const std::string expected = "camsim: --set sensor.gain_db: expected section.key=value\n";
  const Result tradeoff = Camsim("tradeoff --input " + kScene + " --out " + dir + "/out --set sensor.gain_db");
  EXPECT_EQ(tradeoff.code, 1);
  EXPECT_EQ(tradeoff.err, expected);
  const Result run = Camsim("run --input " + kScene + " --out " + dir + "/out --set sensor.gain_db");
  EXPECT_EQ(run.code, 1);
  EXPECT_EQ(run.err, expected);
  const Result emva = Camsim("emva --size 16 --set sensor.gain_db");
  EXPECT_EQ(emva.code, 1);
  EXPECT_EQ(emva.err, expected);
}

// tradeoff.csv, .md and .png belong together: when one cannot be written the
// old three stay. The output directory must be made (it used to be ignored).
TEST(Cli, TradeoffWritesAllThreeOrNone) {
  const std::string dir = TempDir("tradeoff_all");
  const std::string args = "tradeoff --input " + kScene + " --frames 1 --set sensor.width=64 --set sensor.height=48" +
                           " --set 'pipeline.stages=[\"exposure\", \"cfa\", \"sensor\"]' --out ";
  std::ofstream(dir + "/file") << "x";
  const Result nodir = Camsim(args + dir + "/file/sub");
  EXPECT_EQ(nodir.code, 2);
  EXPECT_NE(nodir.err.find("cannot create output directory '" + dir + "/file/sub'"), std::string::npos) << nodir.err;
  const std::string out = dir + "/out";
  std::system(("mkdir -p '" + out + "/tradeoff.png'").c_str());  // the PNG cannot replace a directory
  std::ofstream(out + "/tradeoff.csv") << "old csv";
  std::ofstream(out + "/tradeoff.md") << "old md";
  const Result blocked = Camsim(args + out);
  EXPECT_EQ(blocked.code, 2);
  EXPECT_NE(blocked.err.find(out + "/tradeoff.png"), std::string::npos) << blocked.err;
  EXPECT_EQ(Slurp(out + "/tradeoff.csv"), "old csv");
  EXPECT_EQ(Slurp(out + "/tradeoff.md"), "old md");
  EXPECT_FALSE(Exists(out + "/tradeoff.csv.new"));
  std::system(("rmdir '" + out + "/tradeoff.png'").c_str());
  const Result ok = Camsim(args + out);
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(Slurp(out + "/tradeoff.csv").rfind("knob,value,", 0), 0u);
  EXPECT_EQ(Slurp(out + "/tradeoff.png").substr(1, 3), "PNG");
}

// The review's finding on `camsim run`'s outputs held for tradeoff's three
// files, preview's and pattern's too: a FIFO in the way was replaced by a
// regular file (after the work), a symbolic link by the file. Now a FIFO is
// refused before the work, and a link written through.
TEST(Cli, TradeoffPreviewAndPatternRefuseAFifoAndFollowALink) {
  const std::string dir = TempDir("tool_outputs");
  const std::string out = dir + "/out";
  std::system(("mkdir -p '" + out + "'").c_str());
  ASSERT_EQ(mkfifo((out + "/tradeoff.md").c_str(), 0644), 0);
  const std::string args = "tradeoff --input " + kScene + " --frames 1 --set sensor.width=64 --set sensor.height=48" +
                           " --set 'pipeline.stages=[\"exposure\", \"cfa\", \"sensor\"]' --out " + out;
  const Result fifo = Camsim(args);
  EXPECT_EQ(fifo.code, 2);
  EXPECT_NE(fifo.err.find("cannot write '" + out + "/tradeoff.md': it is a FIFO"), std::string::npos) << fifo.err;
  EXPECT_EQ(fifo.err.find("wrote"), std::string::npos) << fifo.err;
  struct stat st;
  EXPECT_TRUE(lstat((out + "/tradeoff.md").c_str(), &st) == 0 && S_ISFIFO(st.st_mode));
  std::remove((out + "/tradeoff.md").c_str());
  ASSERT_EQ(symlink("../kept.csv", (out + "/tradeoff.csv").c_str()), 0);
  const Result linked = Camsim(args);
  ASSERT_EQ(linked.code, 0) << linked.err;
  EXPECT_TRUE(lstat((out + "/tradeoff.csv").c_str(), &st) == 0 && S_ISLNK(st.st_mode));
  EXPECT_EQ(Slurp(dir + "/kept.csv").rfind("knob,value,", 0), 0u);
  EXPECT_FALSE(Exists(dir + "/kept.csv.new"));

  ASSERT_EQ(mkfifo((dir + "/p.exr").c_str(), 0644), 0);
  const Result pattern = Camsim("pattern checkerboard --width 64 --height 48 --out " + dir + "/p.exr");
  EXPECT_EQ(pattern.code, 2);
  EXPECT_NE(pattern.err.find("'" + dir + "/p.exr': it is a FIFO"), std::string::npos) << pattern.err;
  ASSERT_EQ(mkfifo((dir + "/v.png").c_str(), 0644), 0);
  const Result preview = Camsim("preview --input " + kScene + " --out " + dir + "/v.png");
  EXPECT_EQ(preview.code, 2);
  EXPECT_NE(preview.err.find("'" + dir + "/v.png': it is a FIFO"), std::string::npos) << preview.err;
  EXPECT_TRUE(lstat((dir + "/v.png").c_str(), &st) == 0 && S_ISFIFO(st.st_mode));
}

TEST(Cli, BadInputsFailClearlyAndKeepEarlierOutputs) {
  const std::string dir = TempDir("badin");
  // A sequence: a good frame, then a truncated one.
  std::system(("cp '" + kScene + "' '" + dir + "/seq_0001.exr'").c_str());
  std::system(("head -c 10000 '" + kScene + "' > '" + dir + "/seq_0002.exr'").c_str());
  const Result r = Camsim("run --config " + kConfig + " --input " + dir + "/seq_%04d.exr --out " + dir + "/out");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("seq_0002.exr"), std::string::npos) << r.err;
  // The run says where the pattern's sequence starts and ends.
  EXPECT_NE(r.err.find("inputs: 2 frames, " + dir + "/seq_0001.exr .. " + dir + "/seq_0002.exr"), std::string::npos)
      << r.err;
  EXPECT_TRUE(Exists(dir + "/out/seq_0001.png"));  // frame 1's outputs were kept
  // Garbage and missing files.
  std::ofstream(dir + "/garbage.exr") << "this is not an EXR file";
  EXPECT_EQ(Camsim("run --input " + dir + "/garbage.exr --out " + dir).code, 1);
  const Result missing = Camsim("run --input " + dir + "/nope.exr --out " + dir);
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.err.find("nope.exr"), std::string::npos);
}

// A run that fails before its first frame still writes its report (the
// error), so an older report at that path cannot pass for it; names with
// any bytes stay valid JSON, and an EXR's channel names reach the terminal
// printable.
TEST(Cli, AFailedRunReplacesAnOlderReportWithItsError) {
  const std::string dir = TempDir("failreport");
  const std::string report = dir + "/report.json";
  ASSERT_EQ(Camsim("run --config " + kConfig + " --input " + kScene + " --out " + dir + "/out --report " + report).code,
            0);
  ASSERT_NE(Slurp(report).find("\"error\": null"), std::string::npos);
  const std::string missing = dir + "/no\xff\xfe such.exr";  // not UTF-8
  const Result r = Camsim("run --config " + kConfig + " --input '" + missing + "' --out " + dir + "/out --report " +
                          report);
  EXPECT_EQ(r.code, 1);
  const std::string text = Slurp(report);
  EXPECT_EQ(text.find("\"error\": null"), std::string::npos) << text;
  EXPECT_NE(text.find("\"error\": \"") , std::string::npos) << text;
  EXPECT_NE(text.find("no\\ufffd\\ufffd such.exr"), std::string::npos) << text;
  for (char c : text) EXPECT_LT(static_cast<unsigned char>(c), 0x80u) << "a raw byte in " << text;

  // A failure before the inputs are known (a --set typo, an unknown stage)
  // replaces an earlier camsim report too, and writes one where none is.
  ASSERT_EQ(Camsim("run --config " + kConfig + " --input " + kScene + " --out " + dir + "/out --report " + report).code,
            0);
  const Result typo = Camsim("run --config " + kConfig + " --set sensor.ful_well_e=1 --input " + kScene + " --out " +
                             dir + "/out --report " + report);
  EXPECT_EQ(typo.code, 1);
  EXPECT_NE(Slurp(report).find("\"error\": \"--set sensor.ful_well_e=1: unknown key 'sensor.ful_well_e'"),
            std::string::npos)
      << Slurp(report);
  const std::string fresh = dir + "/fresh.json";
  EXPECT_EQ(Camsim("run --stages exposure,nosuch --input " + kScene + " --out " + dir + "/out --report " + fresh).code,
            1);
  EXPECT_NE(Slurp(fresh).find("\"error\": \"--stages"), std::string::npos) << Slurp(fresh);
  // A report that cannot be written stops the run before its first frame.
  const Result into_dir = Camsim("run --input " + kScene + " --out " + dir + "/out2 --report " + dir);
  EXPECT_EQ(into_dir.code, 2);
  EXPECT_NE(into_dir.err.find("--report '" + dir + "': is a directory"), std::string::npos) << into_dir.err;
  const Result no_dir = Camsim("run --input " + kScene + " --out " + dir + "/out2 --report " + dir + "/none/r.json");
  EXPECT_EQ(no_dir.code, 2);
  EXPECT_NE(no_dir.err.find("its directory does not exist"), std::string::npos) << no_dir.err;
  EXPECT_FALSE(Exists(dir + "/out2/aisle_0001.png"));
  // Anything else at that path may be a file the broken configuration names:
  // it is left alone.
  const std::string notes = dir + "/notes.json";
  std::ofstream(notes) << "{\"mine\": 1}\n";
  const Result other = Camsim("run --set sensor.ful_well_e=1 --input " + kScene + " --out " + dir + "/out --report " +
                              notes);
  EXPECT_EQ(other.code, 1);
  EXPECT_EQ(Slurp(notes), "{\"mine\": 1}\n");
  EXPECT_NE(other.err.find("--report '" + notes + "' is not a camsim report: left as it is"), std::string::npos)
      << other.err;

  const std::string odd = dir + "/odd_channels.exr";
  camsim::test::WriteExrFixture(odd, camsim::test::Box(0, 0, 3, 3), camsim::test::Box(0, 0, 3, 3),
                        {{"Q\x1b[31mred", Imf::FLOAT, std::vector<float>(16, 1.0f)}});
  const Result o = Camsim("run --config " + kConfig + " --input " + odd + " --out " + dir + "/out2");
  EXPECT_EQ(o.code, 1);
  EXPECT_NE(o.err.find("Q\\x1b[31mred"), std::string::npos) << o.err;
  EXPECT_EQ(o.err.find('\x1b'), std::string::npos) << "an escape sequence reached the terminal";
}

// A strip taller than the frame is the whole frame: before, the strip
// index times the height overflowed int and workers rendered the frame again
// from row 0, concurrently (a data race, and stage statistics counted twice).
TEST(Cli, AStripTallerThanTheFrameIsOneStrip) {
  EXPECT_EQ(camsim::host::StripRows(2147483647, 480, 4), 480);
  EXPECT_EQ(camsim::host::StripRows(5, 480, 4), 5);
  const std::string a = TempDir("tall_a"), b = TempDir("tall_b");
  ASSERT_EQ(Camsim("run --input " + kScene + " --out " + a + " --quiet --threads 2 --report " + a + "/r.json").code, 0);
  ASSERT_EQ(Camsim("run --input " + kScene + " --out " + b + " --quiet --threads 4 --strip-rows 2147483647 --report " +
                   b + "/r.json")
                .code,
            0);
  EXPECT_EQ(Slurp(a + "/aisle_0001.png"), Slurp(b + "/aisle_0001.png"));
  EXPECT_NE(Slurp(b + "/r.json").find("\"strip_rows\": 480,"), std::string::npos) << Slurp(b + "/r.json");
}

// Review findings on the run's errors: a refused run leaves a file its
// --report clashes with alone; a bad option, and an empty --stages, fail
// through the report like a bad --set; a scene without what a key needs
// names the key and where it was set.
TEST(Cli, RefusedRunsKeepFilesAndReportTheirErrors) {
  const std::string dir = TempDir("refused");
  ASSERT_EQ(Camsim("run --input " + kScene + " --out " + dir + " --quiet").code, 0);
  const std::string png = Slurp(dir + "/aisle_0001.png");
  ASSERT_FALSE(png.empty());
  const Result clash = Camsim("run --input " + kScene + " --out " + dir + " --quiet --report " + dir + "/aisle_0001.png");
  EXPECT_EQ(clash.code, 1);
  EXPECT_NE(clash.err.find("would both write"), std::string::npos) << clash.err;
  EXPECT_EQ(Slurp(dir + "/aisle_0001.png"), png);

  const std::string report = dir + "/r.json";
  for (const char* bad : {"--threads 0", "--strip-rows x", "--bogus", "--stages ''"}) {
    ASSERT_EQ(Camsim("run --input " + kScene + " --out " + dir + " --quiet --report " + report).code, 0);
    const Result r = Camsim("run --input " + kScene + " --out " + dir + " --quiet " + bad + " --report " + report);
    EXPECT_EQ(r.code, 1) << bad;
    EXPECT_EQ(Slurp(report).find("\"error\": null"), std::string::npos) << bad << ": " << Slurp(report);
  }
  EXPECT_NE(Camsim("run --input " + kScene + " --out " + dir + " --threads 65").err.find("[1, 64]"), std::string::npos);

  const std::string board = dir + "/board.exr";
  ASSERT_EQ(Camsim("pattern checkerboard --width 64 --height 48 --out " + board).code, 0);
  const Result vectors = Camsim("run --input " + board + " --out " + dir + " --set motion.source=vectors");
  EXPECT_EQ(vectors.code, 1);
  EXPECT_NE(vectors.err.find("--set motion.source=vectors: motion.source"), std::string::npos) << vectors.err;
}

// Flare left out by --stages: no flare pre-pass and no flare numbers in the
// report (they came from a stage that did not run: all zero).
TEST(Cli, AFlareLeftOutReportsNoFlare) {
  const std::string dir = TempDir("flare_out");
  const std::string env = std::string(CAMSIM_SOURCE_DIR) + "/scenes/environment/sky_env.exr";
  const std::string common = "run --input " + kScene + " --out " + dir + " --quiet --set flare.enabled=true" +
                             " --set flare.environment_map=" + env + " --report " + dir + "/r.json";
  ASSERT_EQ(Camsim(common).code, 0);
  EXPECT_NE(Slurp(dir + "/r.json").find("\"flare_environment\""), std::string::npos);
  ASSERT_EQ(Camsim(common + " --stages exposure,cfa,sensor").code, 0);
  EXPECT_EQ(Slurp(dir + "/r.json").find("\"flare_environment\""), std::string::npos) << Slurp(dir + "/r.json");
}

// A flare environment map whose texels were replaced (NaN, inf, negative)
// is named on stderr once, as a scene frame is; it was only counted in the
// report.
TEST(Cli, AnEnvironmentMapsReplacedTexelsAreWarnedAbout) {
  const std::string dir = TempDir("dirty_env");
  const std::string env = dir + "/dirty_env.exr";
  std::vector<float> r(8 * 4, 1.0f), g(8 * 4, 2.0f), b(8 * 4, 3.0f);
  r[5] = std::nanf("");
  b[7] = INFINITY;
  camsim::test::WriteExrFixture(env, camsim::test::Box(0, 0, 7, 3), camsim::test::Box(0, 0, 7, 3),
                                {{"R", Imf::FLOAT, r}, {"G", Imf::FLOAT, g}, {"B", Imf::FLOAT, b}});
  const Result run = Camsim("run --input " + kScene + " --out " + dir + " --quiet --set flare.enabled=true" +
                            " --set flare.environment_map=" + env);
  ASSERT_EQ(run.code, 0) << run.err;
  const std::string line = "camsim: warning: flare.environment_map '" + env +
                           "': 1 NaN, 1 +inf colour samples replaced (first: channel R at x=5, y=0)\n";
  EXPECT_NE(run.err.find(line), std::string::npos) << run.err;
  EXPECT_EQ(run.err.find(line), run.err.rfind(line)) << "said twice: " << run.err;
}

// tradeoff checks its input as `camsim run` does: a stage without its depth
// plane is an error naming it (it used to read a plane that is not there).
TEST(Cli, TradeoffRefusesAnInputWithoutTheDepthItNeeds) {
  const std::string dir = TempDir("tradeoff_depth");
  const std::string flat = dir + "/rgb_only.exr";
  const std::vector<float> grey(64 * 32, 0.5f);
  camsim::test::WriteExrFixture(flat, camsim::test::Box(0, 0, 63, 31), camsim::test::Box(0, 0, 63, 31),
                                {{"R", Imf::FLOAT, grey}, {"G", Imf::FLOAT, grey}, {"B", Imf::FLOAT, grey}});
  for (const std::string set : {"dof.method=diffusion", "dof.method=gather", "motion.source=vectors",
                                "motion.source=camera --set 'motion.linear_velocity_m_s=[1,0,0]'"}) {
    const Result r = Camsim("tradeoff --config " + kConfig + " --input " + flat + " --out " + dir + "/out --set " + set +
                            " --frames 1");
    EXPECT_EQ(r.code, 1) << set;
    EXPECT_NE(r.err.find(flat + ": "), std::string::npos) << set << ": " << r.err;
    EXPECT_NE(r.err.find(set[0] == 'd' ? "depth of field needs a sensor-sized depth plane"
                                       : set == "motion.source=vectors" ? "needs sensor-sized motion vector planes"
                                                                        : "camera translation needs"),
              std::string::npos)
        << set << ": " << r.err;
    EXPECT_FALSE(Exists(dir + "/out/tradeoff.csv")) << set;
  }
  // With the planes it needs, the same run works (flare's pre-pass included).
  EXPECT_EQ(Camsim("tradeoff --config " + kConfig + " --input " + kScene + " --out " + dir +
                   "/ok --set dof.method=diffusion --set flare.enabled=true --set sensor.width=96"
                   " --set sensor.height=64 --frames 1")
                .code,
            0);
  EXPECT_TRUE(Exists(dir + "/ok/tradeoff.csv"));
}

// An input named like the old fixed temporary name of an output
// (`OUT.tmp`) is read, not overwritten and renamed away.
TEST(Cli, AnInputNamedLikeAnOutputsTemporaryFileSurvives) {
  const std::string dir = TempDir("tmpname");
  std::system(("cp '" + kScene + "' '" + dir + "/shot.png.tmp'").c_str());
  const std::string before = Slurp(dir + "/shot.png.tmp");
  const Result r = Camsim("preview --input " + dir + "/shot.png.tmp --out " + dir + "/shot.png");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Slurp(dir + "/shot.png.tmp") == before);
  EXPECT_EQ(Slurp(dir + "/shot.png").substr(1, 3), "PNG");
}

// The report counts what the EXR reader replaced in the depth channel too
// (NaN, infinities, negative depths), per frame, with the first sample
// replaced; stderr gets a warning naming the file.
TEST(Cli, ReportCountsTheDepthsTheReaderReplaced) {
  const std::string dir = TempDir("depthstats");
  const std::string exr = dir + "/rgbz.exr";
  std::vector<float> z(16, 2.0f);
  z[1] = std::nanf("");
  z[2] = -1.0f;
  z[3] = -3.0f;
  z[4] = INFINITY;
  const std::vector<float> grey(16, 0.5f);
  camsim::test::WriteExrFixture(exr, camsim::test::Box(0, 0, 3, 3), camsim::test::Box(0, 0, 3, 3),
                                {{"R", Imf::FLOAT, grey}, {"G", Imf::FLOAT, grey}, {"B", Imf::FLOAT, grey},
                                 {"Z", Imf::FLOAT, z}});
  const Result r = Camsim("run --config " + kConfig + " --input " + exr + " --out " + dir + "/out --report " + dir +
                          "/report.json");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string report = Slurp(dir + "/report.json");
  EXPECT_NE(report.find("\"depth_sanitised\": {\"nan\": 1, \"pos_inf\": 1, \"neg_inf\": 0, \"negative\": 2, "
                        "\"first_replaced\": {\"channel\": \"Z\", \"x\": 1, \"y\": 0}}"),
            std::string::npos)
      << report;
  EXPECT_NE(report.find("\"sanitised\": {\"nan\": 0, \"pos_inf\": 0, \"neg_inf\": 0, \"negative\": 0, "
                        "\"first_replaced\": null}"),
            std::string::npos)
      << report;
  EXPECT_NE(r.err.find("camsim: warning: '" + exr + "': 1 NaN depth sample replaced by +inf (first: channel Z at "
                       "x=1, y=0)\n"),
            std::string::npos)
      << r.err;
}

TEST(Cli, OptionErrorsNameTheOptionAndValue) {
  struct Case {
    const char* args;
    const char* says;
  };
  const Case cases[] = {
      {"tradeoff --input a.exr --frames", "--frames needs a value"},
      // Review finding: a value out of range now says the range.
      {"tradeoff --input a.exr --frames 0", "bad option '--frames 0': expected a whole number in [1, 1000]"},
      {"tradeoff --inptu a.exr", "bad option '--inptu a.exr': unknown option '--inptu'"},
      {"emva --preset x --size 8", "bad option '--size 8': expected a whole number in [16, 4096]"},
      {"emva --size 5", "bad option '--size 5': expected a whole number in [16, 4096]"},
      {"emva --levels 19", "bad option '--levels 19': expected a whole number in [20, 1000]"},
      {"preview --input a.exr --out b.png --scale abc", "bad option '--scale abc': expected a finite number > 0"},
      {"preview --input a.exr --out b.png --scale -1", "bad option '--scale -1': expected a finite number > 0"},
      {"preview --scale 0", "bad option '--scale 0': expected a finite number > 0"},
      {"preview --input a.exr --out", "--out needs a value"},
      // ... and a missing --out is named (it printed the usage alone).
      {"preview --input a.exr", "camsim: preview needs --out PNG\n"},
      {"preview --out b.png", "camsim: preview needs --input EXR\n"},
      {"config --chek a.toml", "camsim: config: unknown option '--chek'"},
  };
  for (const Case& c : cases) {
    const Result r = Camsim(c.args);
    EXPECT_EQ(r.code, 1) << c.args;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.args << ": " << r.err;
  }
}

bool IsFifo(const std::string& p) {
  struct stat st;
  return lstat(p.c_str(), &st) == 0 && S_ISFIFO(st.st_mode);
}

bool IsSymlink(const std::string& p) {
  struct stat st;
  return lstat(p.c_str(), &st) == 0 && S_ISLNK(st.st_mode);
}

// Review finding: a report or output path that was a symbolic link became a
// regular file (its target untouched), and a FIFO was replaced. Now a link
// is followed (its target replaced), and a FIFO (or device, socket,
// directory) is refused, naming it, before any frame is rendered, and is
// left as it is, also by a run that fails on its options.
TEST(Cli, ReportAndOutputsFollowLinksAndRefuseWhatIsNotAFile) {
  const std::string dir = TempDir("not_a_file");
  std::ofstream(dir + "/real.json") << "{\"mine\": 1}\n";
  ASSERT_EQ(symlink("real.json", (dir + "/link.json").c_str()), 0);
  const Result linked = Camsim("run --input " + kScene + " --out " + dir + "/out --quiet --report " + dir + "/link.json");
  ASSERT_EQ(linked.code, 0) << linked.err;
  EXPECT_TRUE(IsSymlink(dir + "/link.json"));
  EXPECT_NE(Slurp(dir + "/real.json").find("\"error\": null"), std::string::npos) << Slurp(dir + "/real.json");

  const std::string fifo = dir + "/fifo.json";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0644), 0);
  const Result to_fifo = Camsim("run --input " + kScene + " --out " + dir + "/out2 --quiet --report " + fifo);
  EXPECT_EQ(to_fifo.code, 2);
  EXPECT_NE(to_fifo.err.find("'" + fifo + "': it is a FIFO"), std::string::npos) << to_fifo.err;
  EXPECT_TRUE(IsFifo(fifo));
  EXPECT_FALSE(Exists(dir + "/out2/aisle_0001.png")) << "refused before the first frame";
  const Result bad_option = Camsim("run --input " + kScene + " --out " + dir + "/out2 --threads 0 --report " + fifo);
  EXPECT_EQ(bad_option.code, 1);
  EXPECT_NE(bad_option.err.find("it is a FIFO"), std::string::npos) << bad_option.err;
  EXPECT_TRUE(IsFifo(fifo));

  // A frame's output: a FIFO in its place stops the run before it renders;
  // a link is written through.
  std::system(("mkdir -p '" + dir + "/out3' '" + dir + "/out4'").c_str());
  ASSERT_EQ(mkfifo((dir + "/out3/aisle_0001.png").c_str(), 0644), 0);
  const Result out_fifo = Camsim("run --input " + kScene + " --out " + dir + "/out3 --quiet");
  EXPECT_EQ(out_fifo.code, 2);
  EXPECT_NE(out_fifo.err.find("'" + dir + "/out3/aisle_0001.png': it is a FIFO"), std::string::npos) << out_fifo.err;
  EXPECT_TRUE(IsFifo(dir + "/out3/aisle_0001.png"));
  EXPECT_FALSE(Exists(dir + "/out3/aisle_0001.raw"));
  ASSERT_EQ(symlink("../elsewhere.png", (dir + "/out4/aisle_0001.png").c_str()), 0);
  ASSERT_EQ(Camsim("run --input " + kScene + " --out " + dir + "/out4 --quiet").code, 0);
  EXPECT_TRUE(IsSymlink(dir + "/out4/aisle_0001.png"));
  EXPECT_EQ(Slurp(dir + "/elsewhere.png").substr(1, 3), "PNG");
  // Through a link, the target is what no other output may claim.
  ASSERT_EQ(symlink("out4/aisle_0001.raw", (dir + "/raw_link.json").c_str()), 0);
  const Result clash = Camsim("run --input " + kScene + " --out " + dir + "/out4 --quiet --report " + dir +
                              "/raw_link.json");
  EXPECT_EQ(clash.code, 1);
  EXPECT_NE(clash.err.find("would both write"), std::string::npos) << clash.err;
}

// --report - writes the report to standard output (a failed run's too).
TEST(Cli, ReportToStandardOutput) {
  const std::string dir = TempDir("report_stdout");
  const Result ok = Camsim("run --input " + kScene + " --out " + dir + " --quiet --report -");
  ASSERT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(ok.out.rfind("{\n  \"camsim_version\": \"", 0), 0u) << ok.out;
  EXPECT_NE(ok.out.find("\"error\": null\n}\n"), std::string::npos) << ok.out;
  EXPECT_FALSE(Exists(dir + "/-"));
  const Result failed = Camsim("run --input " + kScene + " --out " + dir + " --quiet --threads 0 --report -");
  EXPECT_EQ(failed.code, 1);
  EXPECT_NE(failed.out.find("\"error\": \"--threads: '0' is not a whole number in [1, 64]\""), std::string::npos)
      << failed.out;
  EXPECT_NE(Camsim("run --help").out.find("--report FILE|-"), std::string::npos);
}

// Review finding: only `camsim --help` and `camsim run --help` worked
// (`emva --help`: "--help needs a value", `pattern --help`: "unknown pattern",
// `camsim -h` failed), and an unknown command did not say so.
TEST(Cli, EveryCommandHasHelp) {
  for (const std::string command : {"run", "config", "pattern", "emva", "tradeoff", "preview"})
    for (const std::string flag : {"--help", "-h"}) {
      const Result r = Camsim(command + " " + flag);
      EXPECT_EQ(r.code, 0) << command << " " << flag << ": " << r.err;
      EXPECT_EQ(r.out.rfind("usage:\n  camsim " + command + " ", 0), 0u) << command << " " << flag << ": " << r.out;
      EXPECT_EQ(r.err, "") << command << " " << flag;
    }
  // Anywhere on the line, and nothing runs.
  const std::string dir = TempDir("help");
  const Result late = Camsim("pattern checkerboard --out " + dir + "/p.exr --help");
  EXPECT_EQ(late.code, 0) << late.err;
  EXPECT_EQ(late.out.rfind("usage:\n  camsim pattern ", 0), 0u) << late.out;
  EXPECT_FALSE(Exists(dir + "/p.exr"));
  EXPECT_EQ(Camsim("emva --preset nosuch -h").code, 0);
  for (const std::string flag : {"--help", "-h", "help"}) {
    const Result all = Camsim(flag);
    EXPECT_EQ(all.code, 0) << flag;
    for (const char* command : {"camsim run ", "camsim config ", "camsim pattern ", "camsim emva ", "camsim tradeoff ",
                                "camsim preview "})
      EXPECT_NE(all.out.find(command), std::string::npos) << flag << ": " << command;
  }
  const Result bogus = Camsim("bogus");
  EXPECT_EQ(bogus.code, 1);
  EXPECT_EQ(bogus.err.rfind("camsim: unknown command 'bogus'\nusage:\n", 0), 0u) << bogus.err;
  const Result none = Camsim("");
  EXPECT_EQ(none.code, 1);
  EXPECT_NE(none.err.find("camsim: no command given"), std::string::npos) << none.err;
}

// Review finding: an option without its value (`--config` last) exited at
// once, leaving the report of an earlier, successful run at --report's path.
TEST(Cli, AMissingOptionValueIsRecordedInTheReport) {
  const std::string dir = TempDir("missing_value");
  const std::string report = dir + "/o.json";
  for (const char* last : {"--config", "--threads", "--set", "--report"}) {
    ASSERT_EQ(Camsim("run --input " + kScene + " --out " + dir + " --quiet --report " + report).code, 0);
    ASSERT_NE(Slurp(report).find("\"error\": null"), std::string::npos);
    const Result r = Camsim("run --input " + kScene + " --out " + dir + " --quiet --report " + report + " " + last);
    EXPECT_EQ(r.code, 1) << last;
    EXPECT_NE(r.err.find(std::string("camsim: ") + last + " needs "), std::string::npos) << last << ": " << r.err;
    // (A last --report without its path: the one given before records the failure.)
    EXPECT_NE(Slurp(report).find(std::string("\"error\": \"") + last + " needs "), std::string::npos)
        << last << ": " << Slurp(report);
  }
}

// Review finding: a relative path in a configuration file (a defect list,
// mask, map, calibration) was taken from the current directory, so a
// configuration worked only when run from one place. It is now relative to
// the file's directory (through a link: the real file's; a pipe: the
// current directory); --set keeps the current directory; an error about the
// file names the configuration file and line that set it.
TEST(Cli, PathsInAConfigFileAreRelativeToIt) {
  const std::string dir = TempDir("relpaths");
  std::system(("mkdir -p '" + dir + "/cfg' '" + dir + "/elsewhere'").c_str());
  std::ofstream(dir + "/cfg/d.txt") << "1,1,stuck\n";
  std::ofstream(dir + "/cfg/cam.toml") << "[sensor]\nwidth = 64\nheight = 48\ndefects_file = \"d.txt\"\n";
  const Result from_elsewhere = CamsimIn(dir + "/elsewhere", "config --check ../cfg/cam.toml");
  EXPECT_EQ(from_elsewhere.code, 0) << from_elsewhere.err;
  const Result run = CamsimIn(dir + "/elsewhere", "run --config ../cfg/cam.toml --input " + kScene +
                                                      " --out out --quiet --report out/r.json");
  EXPECT_EQ(run.code, 0) << run.err;
  EXPECT_NE(Slurp(dir + "/elsewhere/out/r.json").find("\"error\": null"), std::string::npos);
  ASSERT_EQ(symlink("../cfg/cam.toml", (dir + "/elsewhere/link.toml").c_str()), 0);
  const Result linked = CamsimIn(dir + "/elsewhere", "config --check link.toml");
  EXPECT_EQ(linked.code, 0) << linked.err;
  const Result redirected = CamsimIn(dir + "/elsewhere", "config --check /dev/stdin < ../cfg/cam.toml");
  EXPECT_EQ(redirected.code, 0) << redirected.err;
  // A pipe has no directory: the current one.
  const std::string piped = "cd '" + dir + "/cfg' && cat cam.toml | " + CAMSIM_BINARY +
                            " config --check /dev/stdin >/dev/null 2>&1";
  EXPECT_EQ(std::system(piped.c_str()), 0);

  // The file and line that set the key, and the path as resolved.
  std::ofstream(dir + "/cfg/bad.toml") << "[sensor]\nwidth = 64\nheight = 48\n\ndefects_file = \"none.txt\"\n";
  const Result missing = CamsimIn(dir + "/elsewhere", "config --check ../cfg/bad.toml");
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.err.find("camsim: ../cfg/bad.toml:5: sensor.defects_file: "), std::string::npos) << missing.err;
  EXPECT_NE(missing.err.find("../cfg/none.txt"), std::string::npos) << missing.err;
  std::ofstream(dir + "/cfg/map.toml") << "[flare]\nenabled = true\nenvironment_map = \"no_map.exr\"\n";
  const Result map = CamsimIn(dir + "/elsewhere", "run --config ../cfg/map.toml --input " + kScene + " --out out");
  EXPECT_EQ(map.code, 1);
  EXPECT_NE(map.err.find("camsim: ../cfg/map.toml:3: flare.environment_map: "), std::string::npos) << map.err;
  EXPECT_NE(map.err.find("../cfg/no_map.exr"), std::string::npos) << map.err;

  // --set: the current directory.
  const Result set_here = CamsimIn(dir + "/cfg", "run --input " + kScene +
                                                    " --out ../out --quiet --set sensor.defects_file=d.txt");
  EXPECT_EQ(set_here.code, 0) << set_here.err;
  const Result set_elsewhere = CamsimIn(dir + "/elsewhere", "run --config ../cfg/cam.toml --input " + kScene +
                                                                " --out out --quiet --set sensor.defects_file=d.txt");
  EXPECT_EQ(set_elsewhere.code, 1);
  EXPECT_NE(set_elsewhere.err.find("camsim: --set sensor.defects_file=d.txt: sensor.defects_file: "),
            std::string::npos)
      << set_elsewhere.err;

  // The bundled demo camera's commented-out map works from anywhere once uncommented.
  std::string demo = Slurp(kConfig);
  const std::string commented = "# [flare]\n# enabled = true\n# environment_map = ";
  ASSERT_NE(demo.find(commented), std::string::npos);
  demo.replace(demo.find(commented), commented.size(), "[flare]\nenabled = true\nenvironment_map = ");
  std::system(("mkdir -p '" + dir + "/configs'").c_str());
  std::ofstream(dir + "/configs/camera.toml") << demo;
  std::system(("ln -s '" + std::string(CAMSIM_SOURCE_DIR) + "/scenes' '" + dir + "/scenes'").c_str());
  const Result demo_run = CamsimIn(dir + "/elsewhere", "config --check ../configs/camera.toml");
  EXPECT_EQ(demo_run.code, 0) << demo_run.err;
}

// The names in `dir` that look like a writer's temporary file (NAME.tmp.PID.N).
std::vector<std::string> Temporaries(const std::string& dir) {
  std::vector<std::string> found;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) found.push_back(e.path().string());
  return found;
}

// A run killed while it writes an output (held there by the writers' test
// hook, CAMSIM_TEST_HOOK_WRITE_PAUSE_MS, once the temporary file exists)
// removes the temporary file and still dies by the signal; the file the
// write would have replaced keeps its content.
TEST(Cli, KilledMidWriteLeavesNoTemporaryFile) {
  for (const int sig : {SIGTERM, SIGINT, SIGHUP}) {
    SCOPED_TRACE(strsignal(sig));
    const std::string dir = TempDir("killed_" + std::to_string(sig));
    const std::string out = dir + "/p.exr", err = dir + "/stderr";
    std::ofstream(out) << "previous";
    std::vector<std::string> args = {CAMSIM_BINARY, "pattern", "checkerboard", "--out", out,
                                     "--width",     "64",      "--height",     "48"};
    std::vector<std::string> env = {"CAMSIM_TEST_HOOK_WRITE_PAUSE_MS=60000"};
    for (char** e = environ; *e != nullptr; ++e) env.emplace_back(*e);
    std::vector<char*> argv, envp;
    for (std::string& a : args) argv.push_back(a.data());
    for (std::string& e : env) envp.push_back(e.data());
    argv.push_back(nullptr);
    envp.push_back(nullptr);
    // The signal's default action in the child, whatever this process inherited.
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    sigset_t defaults, none;
    sigemptyset(&defaults);
    sigaddset(&defaults, sig);
    sigemptyset(&none);
    posix_spawnattr_setsigdefault(&attr, &defaults);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
    posix_spawn_file_actions_t files;
    posix_spawn_file_actions_init(&files);
    posix_spawn_file_actions_addopen(&files, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    pid_t pid = 0;
    const int spawned = posix_spawn(&pid, CAMSIM_BINARY, &files, &attr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&files);
    posix_spawnattr_destroy(&attr);
    ASSERT_EQ(spawned, 0) << std::strerror(spawned);
    // The hook says when the temporary file exists and is registered.
    bool paused = false;
    for (int i = 0; i < 3000 && !paused; ++i) {
      paused = Slurp(err).find("test hook: pausing") != std::string::npos;
      if (!paused) usleep(10000);
    }
    const std::vector<std::string> during = Temporaries(dir);
    kill(pid, sig);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(paused) << Slurp(err);
    EXPECT_EQ(during.size(), 1u);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << "status " << status << "\n" << Slurp(err);
    EXPECT_EQ(Temporaries(dir), std::vector<std::string>{});
    EXPECT_EQ(Slurp(out), "previous");
  }
}

TEST(Cli, ConfigDefaultRoundTrips) {
  const std::string dir = TempDir("default");
  const std::string cmd = std::string(CAMSIM_BINARY) + " config --default > '" + dir + "/d.toml'";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const std::string text = Slurp(dir + "/d.toml");
  EXPECT_NE(text.find("[sensor]"), std::string::npos);
  EXPECT_NE(text.find("# exposure time, microseconds"), std::string::npos);
  EXPECT_EQ(Camsim("config --check " + dir + "/d.toml").code, 0);
  // Read back, the printed file is the configuration it was printed from:
  // printed again, the same text.
  camsim::host::RunConfig read;
  camsim::host::Origins origins;
  std::string error;
  ASSERT_TRUE(camsim::host::LoadConfigFile(dir + "/d.toml", &read, &origins, &error)) << error;
  EXPECT_EQ(camsim::host::ConfigToToml(read, true), text);
}

}  // namespace
