// Host-side glue: configuration parsing and overrides, scene fitting and the
// conversion to the core's fixed-point input.
#include <gtest/gtest.h>

#include <cmath>

#include "host_tools/config.h"
#include "host_tools/scene_input.h"

namespace camsim::host {
namespace {

TEST(Config, DefaultTextParsesBackToTheDefaults) {
  RunConfig parsed;
  parsed.core.exposure.f_number = 99;  // must be overwritten by the text
  Origins origins;
  std::string error;
  ASSERT_TRUE(ParseConfig(DefaultConfigToml(), "default", &parsed, &origins, &error)) << error;
  EXPECT_EQ(ConfigToToml(parsed, false), ConfigToToml(RunConfig{}, false));
  EXPECT_EQ(origins.size(), ConfigKeys().size());  // every key is printed
}

TEST(Config, OverridesAcceptBareWordsAndNameTheirOrigin) {
  RunConfig c;
  Origins origins;
  std::string error;
  ASSERT_TRUE(ApplyOverride("sensor.cfa=BayerBG", &c, &origins, &error)) << error;
  EXPECT_EQ(c.core.geometry.cfa, Cfa::kBayerBG);
  ASSERT_TRUE(ApplyOverride("white_balance.gain=[2, 1, 1.5]", &c, &origins, &error)) << error;
  EXPECT_EQ(c.core.white_balance.gain[2], 1.5);
  ASSERT_TRUE(ApplyOverride("pipeline.stages=[\"exposure\", \"cfa\", \"sensor\"]", &c, &origins, &error));
  EXPECT_EQ(c.core.order_count, 3);
  EXPECT_EQ(origins["sensor.cfa"], "--set sensor.cfa=BayerBG");  // the argument, echoed in later errors
  EXPECT_FALSE(ApplyOverride("sensor.cfa=BayerXY", &c, &origins, &error));
  EXPECT_NE(error.find("must be one of"), std::string::npos) << error;
  EXPECT_FALSE(ApplyOverride("white_balance.gain=[1, 2]", &c, &origins, &error));
  EXPECT_NE(error.find("exactly 3"), std::string::npos) << error;
  EXPECT_FALSE(ApplyOverride("nonsense", &c, &origins, &error));
  EXPECT_EQ(c.core.geometry.cfa, Cfa::kBayerBG);  // failed overrides change nothing
}

// A string value is taken as written, so paths need no TOML quotes (they used
// to fail as "could not determine value type"); a quoted one is read as TOML.
TEST(Config, OverridesTakePathsAsWritten) {
  RunConfig c;
  Origins origins;
  std::string error;
  for (const std::string path : {"/abs/mask.png", "./rel/mask.png", "../up.exr", "C:\\masks\\m.png", "a b\"c.png"}) {
    ASSERT_TRUE(ApplyOverride("vignetting.mask=" + path, &c, &origins, &error)) << path << ": " << error;
    EXPECT_EQ(c.vignetting_mask, path);
  }
  ASSERT_TRUE(ApplyOverride("vignetting.mask=\"/quoted.png\"", &c, &origins, &error)) << error;
  EXPECT_EQ(c.vignetting_mask, "/quoted.png");
  EXPECT_FALSE(ApplyOverride("sensor.adc_bits=/12", &c, &origins, &error));  // numbers stay numbers
}

// Suggestions come from the key's own section, or name the same key under
// another heading; an unrelated section's look-alike is not offered.
TEST(Config, UnknownKeysSuggestFromTheirSection) {
  RunConfig c;
  Origins o;
  std::string error;
  EXPECT_FALSE(ParseConfig("[sensor]\nful_well_e = 1\n", "f.toml", &c, &o, &error));
  EXPECT_NE(error.find("did you mean 'sensor.full_well_e'"), std::string::npos) << error;
  EXPECT_FALSE(ParseConfig("[exposure]\ngain_db = 6\n", "f.toml", &c, &o, &error));
  EXPECT_NE(error.find("did you mean 'sensor.gain_db'"), std::string::npos) << error;
  EXPECT_FALSE(ParseConfig("[sensr]\nx = 1\n", "f.toml", &c, &o, &error));
  EXPECT_NE(error.find("did you mean 'sensor'"), std::string::npos) << error;
  EXPECT_FALSE(ApplyOverride("sensor.nope=1", &c, &o, &error));
  EXPECT_EQ(error, "--set sensor.nope=1: unknown key 'sensor.nope'");
}

// What the parser refuses for every key, whether its stage runs or not: a
// stage that is off never checks its own ranges.
TEST(Config, RefusesWhatNoKeyMeans) {
  RunConfig c;
  Origins o;
  std::string error;
  EXPECT_FALSE(ParseConfig("[dof]\nfocus_distance_m = nan\n", "f.toml", &c, &o, &error));
  EXPECT_EQ(error, "f.toml:2: dof.focus_distance_m must be a finite number");
  EXPECT_FALSE(ParseConfig("[distortion]\n\nk1 = -inf\n", "f.toml", &c, &o, &error));
  EXPECT_EQ(error, "f.toml:3: distortion.k1 must be a finite number");
  EXPECT_FALSE(ParseConfig("[dof]\nstructural_poly = [0, inf]\n", "f.toml", &c, &o, &error));
  EXPECT_EQ(error, "f.toml:2: dof.structural_poly element 1 must be a finite number");
  EXPECT_FALSE(ApplyOverride("motion.vector_fps=inf", &c, &o, &error));
  EXPECT_NE(error.find("must be a finite number"), std::string::npos) << error;
  // A --set is one key: a line break cannot smuggle in another.
  EXPECT_FALSE(ApplyOverride("sensor.gain_db=3\n[exposure]\nf_number=0.1", &c, &o, &error));
  EXPECT_EQ(error, "--set sensor.gain_db: the value has a line break");
  EXPECT_EQ(o.count("exposure.f_number"), 0u);
  EXPECT_FALSE(ParseConfig("[pipeline]\nstages = [\"exposure\", \"cfa\", \"exposure\"]\n", "f.toml", &c, &o, &error));
  EXPECT_EQ(error, "f.toml:2: pipeline.stages lists stage 'exposure' twice");
  // A key above every header is named with its section.
  EXPECT_FALSE(ParseConfig("seed = 1\n[sensor]\nadc_bits = 12\n", "f.toml", &c, &o, &error));
  EXPECT_EQ(error, "f.toml:1: 'seed' is outside any section: write it under [pipeline] (pipeline.seed)");
  EXPECT_FALSE(ParseConfig("sede = 1\n", "f.toml", &c, &o, &error));
  EXPECT_NE(error.find("unknown section 'sede'"), std::string::npos) << error;
}

TEST(Config, ErrorsNameKeyAndLine) {
  RunConfig c;
  Origins o;
  std::string error;
  EXPECT_FALSE(ParseConfig("[sensor]\n\nadc_bits = \"twelve\"\n", "f.toml", &c, &o, &error));
  EXPECT_EQ(error, "f.toml:3: sensor.adc_bits expects a whole number");
  EXPECT_FALSE(ParseConfig("[sensr]\nx = 1\n", "f.toml", &c, &o, &error));
  EXPECT_NE(error.find("unknown section 'sensr'"), std::string::npos) << error;
  EXPECT_FALSE(ParseConfig("[sensor\n", "f.toml", &c, &o, &error));  // TOML syntax error
  EXPECT_EQ(error.rfind("f.toml:1:", 0), 0u) << error;
  // Range errors come from the core and carry the line of the key.
  ASSERT_TRUE(ParseConfig("[sensor]\nfull_well_e = -5\n", "f.toml", &c, &o, &error));
  EXPECT_FALSE(FinishConfig(&c, 64, 64, o, 1, &error));
  EXPECT_EQ(error, "f.toml:2: sensor.full_well_e must be in [1, 1e6] electrons");
}

// Auto exposure may reach any setting in its range, and a frame may not fail:
// a range the stages refuse at one end is a configuration error, named.
TEST(Config, AutoExposureRangeTheStagesRefuseIsAConfigError) {
  RunConfig c;
  Origins o;
  std::string error;
  const std::string toml =
      "[motion]\nsource = \"vectors\"\nvector_fps = 24\n"
      "[auto_exposure]\nmode = \"continuous\"\nexposure_time_max_us = 1e6\n";
  ASSERT_TRUE(ParseConfig(toml, "f.toml", &c, &o, &error)) << error;
  EXPECT_FALSE(FinishConfig(&c, 64, 48, o, 1, &error));
  EXPECT_NE(error.find("(auto_exposure.exposure_time_max_us = 1e+06, auto_exposure.gain_min_db = 0.0)"), std::string::npos)
      << error;
  EXPECT_NE(error.find("f.toml:3: motion.vector_fps: exposure longer than 16 frame intervals"), std::string::npos)
      << error;
  // 0.5 s is within 16 intervals of 1/24 s: accepted.
  ASSERT_TRUE(ApplyOverride("auto_exposure.exposure_time_max_us=5e5", &c, &o, &error)) << error;
  EXPECT_TRUE(FinishConfig(&c, 64, 48, o, 1, &error)) << error;
}

// A core message that is a clause of its own follows the key after a colon,
// from a file or a --set ("--set distortion.k1=-5: distortion.k1 the radial
// model folds over" read as if k1 were the subject); one that goes on from
// the key's name ("must be ...") follows it directly.
TEST(Config, CoreMessagesReadAfterEveryOrigin) {
  RunConfig c;
  Origins o;
  std::string error;
  ASSERT_TRUE(ParseConfig("[distortion]\nmodel = \"brown\"\n\nk1 = -5\n", "f.toml", &c, &o, &error)) << error;
  EXPECT_FALSE(FinishConfig(&c, 640, 480, o, 1, &error));
  EXPECT_EQ(error.rfind("f.toml:4: distortion.k1: the radial model folds over (stops increasing)", 0), 0u) << error;
  ASSERT_TRUE(ApplyOverride("distortion.k1=-5", &c, &o, &error)) << error;
  EXPECT_FALSE(FinishConfig(&c, 640, 480, o, 1, &error));
  EXPECT_EQ(error.rfind("--set distortion.k1=-5: distortion.k1: the radial model folds over (stops increasing)", 0),
            0u)
      << error;
  // Stage order: the key, then the stage list's own clause.
  ASSERT_TRUE(ApplyOverride("pipeline.stages=[\"dof_columns\",\"exposure\",\"sensor\"]", &c, &o, &error)) << error;
  ASSERT_TRUE(ApplyOverride("distortion.model=off", &c, &o, &error)) << error;
  ASSERT_TRUE(ApplyOverride("dof.method=diffusion", &c, &o, &error)) << error;
  EXPECT_FALSE(FinishConfig(&c, 640, 480, o, 1, &error));
  EXPECT_EQ(error.rfind("--set pipeline.stages=[\"dof_columns\",\"exposure\",\"sensor\"]: pipeline.stages: dof_columns "
                       "needs dof_rows running before it",
                       0),
            0u)
      << error;
  // A predicate goes on from the key.
  ASSERT_TRUE(ApplyOverride("sensor.full_well_e=-5", &c, &o, &error)) << error;
  ASSERT_TRUE(ApplyOverride("pipeline.stages=[\"exposure\",\"sensor\"]", &c, &o, &error)) << error;
  EXPECT_FALSE(FinishConfig(&c, 640, 480, o, 1, &error));
  EXPECT_EQ(error, "--set sensor.full_well_e=-5: sensor.full_well_e must be in [1, 1e6] electrons");
}

// The crop check names the dimension that is too large, with its origin (it
// used to name sensor.width for either).
TEST(Config, CropErrorNamesTheDimensionTooLarge) {
  RunConfig c;
  Origins o;
  std::string error;
  ASSERT_TRUE(ParseConfig("[sensor]\nadc_bits = 12\nheight = 700\n", "f.toml", &c, &o, &error)) << error;
  EXPECT_FALSE(FinishConfig(&c, 800, 600, o, 1, &error));
  EXPECT_EQ(error, "f.toml:3: sensor.height is 700, larger than the input's 600; use sensor.scene_fit = \"scale\"");
  ASSERT_TRUE(ApplyOverride("sensor.width=900", &c, &o, &error)) << error;
  EXPECT_FALSE(FinishConfig(&c, 800, 600, o, 1, &error));  // both too large: the width first
  EXPECT_EQ(error, "--set sensor.width=900: sensor.width is 900, larger than the input's 800; use sensor.scene_fit = "
                   "\"scale\"");
}

// Only a regular file is a configuration: a directory reads as nothing on
// Linux, and a read error used to end the text early instead of failing.
TEST(Config, DirectoryAndReadErrorAreRefused) {
  RunConfig c;
  Origins o;
  std::string error;
  const std::string dir = testing::TempDir();
  EXPECT_FALSE(LoadConfigFile(dir, &c, &o, &error));
  EXPECT_EQ(error, dir + ": cannot read configuration file: is a directory, not a file");
  EXPECT_FALSE(LoadConfigFile("/proc/self/mem", &c, &o, &error));  // reading offset 0 fails (EIO)
  EXPECT_EQ(error.rfind("/proc/self/mem: cannot read configuration file: read failed: ", 0), 0u) << error;
  EXPECT_FALSE(LoadConfigFile("/nonexistent/c.toml", &c, &o, &error));
  EXPECT_EQ(error, "/nonexistent/c.toml: cannot read configuration file: No such file or directory");
}

TEST(SceneInput, CropTakesTheCentreAndScaleAverages) {
  io::FloatPlane in;
  in.width = 4;
  in.height = 2;
  in.data = {0, 1, 2, 3, 4, 5, 6, 7};
  const io::FloatPlane crop = FitPlane(in, 2, 2, SceneFit::kCrop);
  EXPECT_EQ(crop.data, (std::vector<float>{1, 2, 5, 6}));
  const io::FloatPlane half = FitPlane(in, 2, 1, SceneFit::kScale);
  EXPECT_EQ(half.data, (std::vector<float>{2.5f, 4.5f}));  // means of 2x2 blocks
  const io::FloatPlane up = FitPlane(in, 8, 4, SceneFit::kScale);
  EXPECT_EQ(up.data[0], 0.0f);
  EXPECT_EQ(up.data[7], 3.0f);
  EXPECT_EQ(up.data[31], 7.0f);
}

TEST(SceneInput, RadianceBecomesRoundedSaturatedQ16) {
  io::SceneFrame s;
  s.width = 4;
  s.height = 1;
  s.r.width = s.g.width = s.b.width = 4;
  s.r.height = s.g.height = s.b.height = 1;
  s.r.data = {0.0f, 1.0f, 0.5f / 65536.0f, 1e9f};
  s.g.data = s.b.data = s.r.data;
  CoreInput in;
  PrepareInput(s, 4, 1, SceneFit::kCrop, &in);
  EXPECT_EQ(in.radiance[0], (std::vector<uint32_t>{0u, 65536u, 1u, 0xFFFFFFFFu}));  // ties up, saturate
}

TEST(SceneInput, DepthBecomesInverseDepthWithDocumentedSpecials) {
  io::SceneFrame s;
  s.width = 6;
  s.height = 1;
  for (io::FloatPlane* p : {&s.r, &s.g, &s.b, &s.depth}) {
    p->width = 6;
    p->height = 1;
    p->data.assign(6, 0.5f);
  }
  s.has_depth = true;
  s.depth.data = {2.0f, 1e10f, 0.0f, -1.0f, INFINITY, NAN};
  CoreInput in;
  PrepareInput(s, 6, 1, SceneFit::kCrop, &in);
  EXPECT_EQ(in.inverse_depth, (std::vector<uint32_t>{524288u, 0u, kMaxInverseDepth, kInvalidInverseDepth, 0u, 0u}));
  EXPECT_EQ(in.View().inverse_depth.data, in.inverse_depth.data());
  // Scale: 1/z averaged over the footprint; an invalid depth makes it invalid.
  s.depth.data = {1.0f, 0.5f, 4.0f, 1e10f, -1.0f, 2.0f};
  PrepareInput(s, 3, 1, SceneFit::kScale, &in);
  EXPECT_EQ(in.inverse_depth[0], 1572864u);  // mean(1, 2) = 1.5 /m
  EXPECT_EQ(in.inverse_depth[1], 131072u);   // mean(0.25, 0) = 0.125 /m
  EXPECT_EQ(in.inverse_depth[2], kInvalidInverseDepth);
  // No depth: no plane.
  s.has_depth = false;
  PrepareInput(s, 6, 1, SceneFit::kCrop, &in);
  EXPECT_TRUE(in.inverse_depth.empty());
}

}  // namespace
}  // namespace camsim::host
