// Inputs found by the fuzz targets (fuzz/, scripts/fuzz.sh) or while building
// them, reduced. Each must be refused with an error, or processed with every
// sample in range; none may reach undefined behaviour (the debug preset runs
// this file under ASan + UBSan).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "tests/support/allocations.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

// A pipeline on a workspace full of garbage (the core must not rely on zeroed
// memory: a ring row read before it was written shows up as 0xA5A5A5A5), with
// every running stage tapped into frames prefilled with `fill`.
struct GarbageRun {
  Status status;
  std::vector<LineFormat> format;           // per running stage
  std::vector<std::vector<uint32_t>> out;   // per running stage, interleaved
};
GarbageRun RunOnGarbage(const PipelineConfig& config, const test::Scene& scene, int strip_rows, uint32_t fill) {
  GarbageRun r;
  Pipeline p;
  r.status = p.Configure(config, 1, false);
  if (!r.status.ok()) return r;
  std::vector<uint8_t> workspace(p.WorkspaceBytes(), 0xA5);
  r.status = p.Init(Span<uint8_t>{workspace.data(), workspace.size()});
  if (!r.status.ok()) return r;
  for (int e = 0; e < p.plan().count; ++e)
    if (p.plan().entries[e].runs) r.format.push_back(p.plan().entries[e].out);
  r.out.resize(r.format.size());
  std::vector<Tap> taps(r.format.size());
  for (size_t i = 0; i < taps.size(); ++i) {
    r.out[i].assign(static_cast<size_t>(scene.width) * scene.height * r.format[i].channels, fill);
    taps[i].stage = static_cast<int>(i);
    taps[i].format = TapFormat::kU32;
    taps[i].data = r.out[i].data();
    taps[i].stride = static_cast<ptrdiff_t>(scene.width) * r.format[i].channels;
  }
  p.ProcessFrame(scene.View(), 0, strip_rows, taps.data(), static_cast<int>(taps.size()), nullptr, nullptr);
  return r;
}

// Samples above their domain's range: DN above 12 bits, Linear or Encoded
// above Q0.16's 65535 (Radiance Q16.16 and Photons Q24.8 use all of uint32).
size_t OutOfRange(const GarbageRun& r) {
  size_t bad = 0;
  for (size_t i = 0; i < r.out.size(); ++i) {
    const Domain d = r.format[i].domain;
    const uint32_t max = d == Domain::kDigital ? 4095u
                         : (d == Domain::kLinear || d == Domain::kEncoded) ? 65535u
                                                                             : 0xFFFFFFFFu;
    for (uint32_t v : r.out[i]) bad += v > max;
  }
  return bad;
}

// fuzz_core: Pipeline::Configure accepted a Cfa outside the enum (geometry.cfa
// = 5, reachable through the core API, not through TOML). Every site then
// reads as green, demosaic writes G twice and never writes B, and the ISP
// output's blue channel is whatever the line ring held before.
// Fix: Pipeline::Configure refuses "sensor.cfa" outside Mono..BayerBG; the
// other enums (vignetting.mode, demosaic.method, gamma.curve) are refused too,
// each naming its field.
TEST(FuzzRegressions, EnumValuesOutsideTheirRange) {
  struct Case {
    const char* field;
    void (*set)(PipelineConfig&);
  };
  const Case cases[] = {
      {"sensor.cfa", [](PipelineConfig& c) { c.geometry.cfa = static_cast<Cfa>(5); }},
      {"vignetting.mode", [](PipelineConfig& c) { c.vignetting.mode = static_cast<VignettingMode>(4); }},
      {"demosaic.method", [](PipelineConfig& c) { c.demosaic.method = static_cast<DemosaicMethod>(2); }},
      {"gamma.curve", [](PipelineConfig& c) { c.gamma.curve = static_cast<GammaCurve>(3); }},
  };
  for (const Case& k : cases) {
    PipelineConfig c = test::DemoConfig(8, 6);
    k.set(c);
    Pipeline p;
    const Status status = p.Configure(c, 1, false);
    ASSERT_FALSE(status.ok()) << k.field << " outside its enum was accepted";
    EXPECT_STREQ(status.field(), k.field) << status.message();
  }
}

// What the refusal above protects, on a valid configuration: on a workspace
// full of garbage every stage writes every sample of its frame (the same
// output whatever the taps held before), in its domain's range, and the same
// for any strip height.
TEST(FuzzRegressions, EveryStageWritesEverySampleOnAGarbageWorkspace) {
  const test::Scene scene = test::TexturedScene(8, 6);
  const PipelineConfig c = test::DemoConfig(8, 6);
  const GarbageRun whole = RunOnGarbage(c, scene, 6, 0xDEADBEEFu), strips = RunOnGarbage(c, scene, 1, 0u);
  ASSERT_TRUE(whole.status.ok()) << whole.status.message();
  ASSERT_FALSE(whole.format.empty());
  EXPECT_EQ(OutOfRange(whole), 0u);
  EXPECT_TRUE(whole.out == strips.out) << "a sample was never written, or the output depends on the strip height";
}

// Found reading UScale while writing fuzz_core's number mapping, confirmed
// through fuzz_config under UBSan ("shift exponent -1 is negative"); the
// fuzzers did not reach the half-unit-wide window on their own. A scale factor
// in [2^32 - 0.5, 2^32) made UScale::FromDouble round the mantissa up to 2^32
// and renormalise it to 2^31 with shift -1; UScale::Apply then shifted by -1
// (undefined behaviour on every exposure sample). Reachable from TOML: exposure with
// 1e9 photons/radiance/ms, 1e8 us and f/9.536743164339855 gives a factor of
// 4294967295.75. Fix (core/base/fixed.h, UScale::FromDouble): when the rounded
// mantissa reaches 2^32 and shift is already 0, return the "scale factor too
// large" error instead of decrementing shift.
TEST(FuzzRegressions, ScaleFactorJustBelowTwoToThe32) {
  const Result<UScale> s = UScale::FromDouble(4294967295.75, "factor");
  ASSERT_FALSE(s.ok()) << "shift " << s.value().shift << " mant " << s.value().mant;
  EXPECT_NE(std::string(s.status().message()).find("too large"), std::string::npos) << s.status().message();
  // Just below the window the scale is valid and normalised.
  const Result<UScale> below = UScale::FromDouble(4294967295.25, "factor");
  ASSERT_TRUE(below.ok()) << below.status().message();
  EXPECT_EQ(below.value().shift, 0);
  EXPECT_EQ(below.value().mant, 0xFFFFFFFFu);
  const std::string toml =
      "[pipeline]\nstages = [\"exposure\"]\n"
      "[exposure]\nexposure_time_us = 1e8\nphotons_per_radiance_ms = 1e9\nf_number = 9.536743164339855\n";
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  ASSERT_TRUE(host::ParseConfig(toml, "fuzz.toml", &rc, &origins, &error)) << error;
  const double factor = ExposurePhotonsPerRadiance(rc.core.exposure) / 256.0;  // what UScale gets
  ASSERT_GE(factor, 4294967295.5);
  ASSERT_LT(factor, 4294967296.0);
  // The configuration fails, naming the exposure, instead of shifting by -1.
  EXPECT_FALSE(host::FinishConfig(&rc, 4, 1, origins, 1, &error));
  EXPECT_NE(error.find("exposure"), std::string::npos) << error;
}

// fuzz_config (UBSan, toml++ compiled into the target): toml++ 3.3.0 (Debian
// 12's libtomlplusplus) reaches __builtin_unreachable() in
// is_non_ascii_horizontal_whitespace() for the non-ASCII code points
// U+00A1..U+0499, U+2C5E..U+3057 and U+FB26..U+FEFE (but U+3000) wherever it
// looks for whitespace: between tokens (the fuzzer's first find was U+FEFB at
// the start of the file), and in a multi-line basic string after a
// line-ending backslash (upstream issue
// marzer/tomlplusplus#190, fixed after 3.3.0). In the shipped library that is
// undefined behaviour that happens to fall through; the fix proposed for
// host::ParseConfig refuses non-ASCII outside comments and single-line
// strings, and multi-line strings, before toml++ sees the text.
TEST(FuzzRegressions, TomlNonAsciiWhereWhitespaceMayBe) {
  {
    host::RunConfig rc;
    host::Origins o;
    std::string error;
    EXPECT_FALSE(host::ParseConfig("[white_balance]\ngain = [1.3, 1.0, 1.18\xcf\xbe]\n", "fuzz.toml", &rc, &o, &error));
    EXPECT_EQ(error.rfind("fuzz.toml:2:", 0), 0u) << error;
    // U+FEFB where a table header may start (the fuzzer's first find), U+026B
    // while toml++ scans a value for its type, after a quote that starts no
    // string, and after a quoted key holding a '#'.
    for (const char* text : {"\xef\xbb\xbb[sensor]\nwidth = 1\n", "[sensor]\nadc_bits = 16'\xc9\xab\n",
                             "[sensor]\nadc_bits = 1.'\xc9\xab'\n", "[sensor]\n\"a#\" = 1\xc3\xa9\n"}) {
      EXPECT_FALSE(host::ParseConfig(text, "fuzz.toml", &rc, &o, &error)) << text;
      EXPECT_EQ(error.rfind("fuzz.toml:", 0), 0u) << error;
    }
  }
  {
    // A UTF-8 byte order mark (U+FEFF, whitespace to toml++) is fine.
    host::RunConfig rc;
    host::Origins o;
    std::string error;
    ASSERT_TRUE(host::ParseConfig("\xef\xbb\xbf[sensor]\nwidth = 7\n", "fuzz.toml", &rc, &o, &error)) << error;
    EXPECT_EQ(rc.width, 7);
  }
  {
    // Refused, or read as TOML says: the backslash drops the newline and the
    // whitespace after it, so the mask is "\u00a7m.png".
    host::RunConfig rc;
    host::Origins o;
    std::string error;
    if (host::ParseConfig("[vignetting]\nmask = \"\"\"\\\n\xc2\xa7m.png\"\"\"\n", "fuzz.toml", &rc, &o, &error))
      EXPECT_EQ(rc.vignetting_mask, "\xc2\xa7m.png");
    else
      EXPECT_EQ(error.rfind("fuzz.toml:", 0), 0u) << error;
  }
  {
    // Non-ASCII in comments and in (single-line) strings, e.g. paths, stays fine.
    host::RunConfig rc;
    host::Origins o;
    std::string error;
    ASSERT_TRUE(host::ParseConfig("# sensor at 25 \xc2\xb0" "C\n[vignetting]\nmask = \"m\xc3\xa9.png\"  # \xc2\xa7\n",
                                  "fuzz.toml", &rc, &o, &error))
        << error;
    EXPECT_EQ(rc.vignetting_mask, "m\xc3\xa9.png");
  }
  {
    // fuzz_config with toml++'s internal assertions on: a table header that
    // starts with a character no key may start with trips an assert in
    // parse_key(); the release library reports it as an error.
    host::RunConfig rc;
    host::Origins o;
    std::string error;
    EXPECT_FALSE(host::ParseConfig("[&ipeline]\nseed = 1\n", "fuzz.toml", &rc, &o, &error));
    EXPECT_EQ(error.rfind("fuzz.toml:1:", 0), 0u) << error;
  }
}

// fuzz_config (its round-trip check): host::ConfigToToml wrote
// vignetting.mask between quotes without escaping, so a mask path with `"`
// printed TOML that does not parse, and one with `\` read back differently
// (`\b` became a backspace). Fix (host_tools/config.cc, the mask field's
// get_text): escape `"` and `\` with a backslash and control characters as
// \uXXXX.
TEST(FuzzRegressions, ConfigToTomlRoundTripsTheMaskPath) {
  host::RunConfig rc;
  host::Origins o;
  std::string error;
  ASSERT_TRUE(host::ParseConfig("[vignetting]\nmask = 'dir\\b\"q\".png'\n", "fuzz.toml", &rc, &o, &error)) << error;
  ASSERT_EQ(rc.vignetting_mask, "dir\\b\"q\".png");
  rc.vignetting_mask += "\t\x01";  // control characters (only reachable through the API)
  const std::string printed = host::ConfigToToml(rc, false);
  host::RunConfig again;
  ASSERT_TRUE(host::ParseConfig(printed, "printed.toml", &again, &o, &error)) << error << "\n" << printed;
  EXPECT_EQ(again.vignetting_mask, rc.vignetting_mask);
  EXPECT_EQ(host::ConfigToToml(again, false), printed);
}

// fuzz_exr_loader (2026-11-22): a 329-byte file whose data window starts at
// x = -2^30 made OpenEXR size its RLE line buffer at 3.2 GB when the part was
// opened, before the loader's window checks ran. The checks now read the
// header first; the file is refused without any large allocation.
TEST(FuzzRegressions, HugeDataWindowIsRefusedBeforeOpenExrAllocates) {
  static const char kFile[] =
    "\x76\x2f\x31\x01\x02\x00\x00\x00\x63\x68\x61\x6e\x6e\x65\x6c\x73\x00\x63\x68\x6c\x69\x73\x74\x00"
    "\x13\x00\x00\x00\x59\x00\x01\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00\x01\x00\x00\x00\x00\x63"
    "\x6f\x6d\x70\x72\x65\x73\x73\x69\x6f\x6e\x00\x63\x6f\x6d\x70\x72\x65\x73\x73\x69\x6f\x6e\x00\x01"
    "\x00\x00\x00\x01\x64\x61\x74\x61\x57\x69\x6e\x64\x6f\x77\x00\x62\x6f\x78\x32\x69\x00\x10\x00\x00"
    "\x00\x00\x00\x00\xc1\x00\x00\x00\x00\x04\x00\x00\x00\x01\x00\x00\x00\x64\x69\x73\x70\x6c\x61\x79"
    "\x57\x69\x6e\x64\x6f\x77\x00\x62\x6f\x78\x32\x69\x00\x10\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00"
    "\x00\x04\x00\x00\x00\x01\x00\x00\x00\x6c\x69\x6e\x65\x4f\x72\x64\x65\x72\x00\x6c\x69\x6e\x65\x4f"
    "\x72\x64\x65\x72\x00\x01\x00\x00\x00\x00\x70\x69\x78\x65\x6c\x41\x73\x70\x65\x63\x74\x52\x61\x74"
    "\x69\x6f\x00\x66\x6c\x6f\x61\x74\x00\x04\x00\x00\x00\x00\x00\x80\x3f\x73\x63\x72\x65\x65\x6e\x57"
    "\x69\x6e\x64\x6f\x77\x43\x65\x6e\x74\x65\x72\x00\x76\x32\x66\x00\x08\x00\x00\x00\x00\x00\x00\x00"
    "\x00\x00\x00\x00\x73\x63\x72\x65\x65\x6e\x57\x69\x6e\x64\x6f\x77\x57\x69\x64\x74\x68\x00\x66\x6c"
    "\x6f\x61\x74\x00\x04\x00\x00\x00\x00\x00\x80\x3f\x00\x25\x01\x00\x00\x00\x00\x00\x00\x37\x01\x00"
    "\x00\x00\x00\x00\x00\x00\x00\x00\x00\x0a\x00\x00\x00\x00\x00\x66\x2e\x66\x32\xcd\x34\x66\x36\x01"
    "\x00\x00\x00\x0a\x00\x00\x00\x00\x38\xcd\x38\x9a\x39\x66\x3a\x33\x3b";
  const std::string path = testing::TempDir() + "camsim_huge_window_" + std::to_string(getpid()) + ".exr";
  {
    std::ofstream f(path, std::ios::binary);
    f.write(kFile, sizeof kFile - 1);
  }
  io::SceneFrame scene;
  std::string error;
  test::ResetLargestAllocation();
  EXPECT_FALSE(io::LoadSceneExr(path, "", &scene, &error));
  EXPECT_NE(error.find("data window"), std::string::npos) << error;
  EXPECT_LT(test::LargestAllocation(), size_t{1} << 26) << "bytes in one allocation";
  std::remove(path.c_str());
}

}  // namespace
}  // namespace camsim

namespace camsim {
namespace {

// fuzz_core found taps of a stage missing rows that no later stage read: a
// pincushion distortion's window for output row 0 starts below row 0, so the
// driver never produced the first rows of the stages before it. Every ring
// now produces at least the strip's own rows.
TEST(FuzzRegressions, TapsCoverRowsALaterWindowSkips) {
  constexpr int kW = 16, kH = 24;
  PipelineConfig c = test::DemoConfig(kW, kH);
  c.exposure.exposure_time_us = 2000;  // one stage before distortion at least: exposure -> ... -> distortion
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kDistortion;
  c.order[2] = StageId::kVignetting;
  c.order_count = 3;
  LensModel& m = c.distortion.lens;
  m.model = DistortionModel::kBrown;
  m.fx = m.fy = kW;
  m.cx = (kW - 1) / 2.0;
  m.cy = (kH - 1) / 2.0;
  m.k[0] = 1.0;  // pincushion: the edge rows sample towards the centre
  c.distortion.filter = ResampleFilter::kBilinear;  // two taps: the narrowest window
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  ASSERT_EQ(b->pipeline.plan().running, 3);
  ASSERT_GT(b->pipeline.running_stage(1).InputRows(0, kH).first, 0) << "the case needs a window that skips row 0";
  const test::Scene scene = test::TexturedScene(kW, kH);
  std::vector<uint32_t> first_run;
  for (int strip : {kH, 5, 1}) {
    std::vector<uint32_t> out(static_cast<size_t>(kW) * kH * 3, 0xA5A5A5A5u);
    Tap t;
    t.stage = 0;  // exposure, read by distortion only from row InputRows(0).first on
    t.format = TapFormat::kU32;
    t.data = out.data();
    t.stride = kW * 3;
    b->pipeline.ProcessFrame(scene.View(), 0, strip, &t, 1, nullptr, nullptr);
    for (size_t i = 0; i < out.size(); ++i) ASSERT_NE(out[i], 0xA5A5A5A5u) << "sample " << i << ", strip " << strip;
    if (first_run.empty()) first_run = out;
    EXPECT_EQ(out, first_run) << "strip " << strip;
  }
}

}  // namespace
}  // namespace camsim
