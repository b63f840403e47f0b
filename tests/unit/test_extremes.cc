// Numeric extremes through the whole pipeline, for the demo camera
// (configs/camera.toml) and a mono variant, with every stage's output tapped
// (the cut after each stage) and the pipeline also configured to end after
// each stage: all-zero radiance, all-max radiance (0xFFFFFFFF), highlights far
// above saturation next to dark pixels, and frames from 1 x 1 up, with widths
// 1..17 and sizes that are not multiples of 8 or 16.
//
// Every sample must be in its domain's range (DN <= 2^adc_bits - 1, Q0.16 <=
// 65535), every strip height must give the same bytes, and where the model
// documents an exact answer it is asserted:
//  - all-zero radiance, noise off: photons 0, every raw DN = the black level,
//    the ISP output 0;
//  - all-max radiance, noise off: photons saturate at 2^32 - 1 (exposure), the
//    raw DN is min(round(K * full_well) + BL, 2^bits - 1) everywhere, and the
//    ISP stages give exactly their formula of that value (a flat field stays
//    flat through demosaic). (The demo camera's full well, 4002 DN, is below
//    its 12-bit ADC maximum, so a saturated pixel is not full scale: black
//    level gives 64023, and white balance clips every channel at its
//    smallest gain times that level, so the sRGB output is neutral,
//    (64866, 64866, 64866). Before 2026-11-28 it clipped at 65535 and the
//    output was magenta, (65535, 64866, 65535).)
//  - dark and saturated frames, noise on: the raw DN is within the read-noise
//    and DSNU tails (|z| <= 6.34) of the noise-free value;
//  - highlights next to dark pixels, noise off: the model has no blooming, so a
//    dark pixel differs from the all-dark answer only within the demosaic
//    kernel's radius of a highlight (2 for Malvar, 0 for mono).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/isp/gamma.h"
#include "core/isp/isp_ref.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

using test::Built;
using test::Scene;

enum class Variant { kDemo, kMono };
const char* VariantName(Variant v) { return v == Variant::kDemo ? "demo" : "mono"; }

// The demo camera for any size. DemoConfig derives the cos4 focal length from
// the width (28 mm lens, 36 mm wide sensor: 0.78 * width pixels), which needs
// width >= 2 and vignettes tall narrow frames to almost nothing (2 x 33: gain
// 1e-4 in the corners); here the 36 mm span the longer side, as in DemoConfig
// for every frame at least as wide as it is tall.
PipelineConfig Config(Variant v, int width, int height, bool noise) {
  PipelineConfig c = test::DemoConfig(std::max(width, 2), height);
  c.geometry.width = width;
  c.vignetting.focal_length_px = 28.0 / 36.0 * std::max({width, height, 2});
  if (v == Variant::kMono) c.geometry.cfa = Cfa::kMono;
  if (!noise) test::NoiseOff(&c.sensor);
  return c;
}

// The output of every running stage (interleaved channels), in run order.
struct Cuts {
  std::vector<StageId> id;
  std::vector<LineFormat> format;
  std::vector<std::vector<uint32_t>> out;
};

Cuts RunCuts(const Built& b, const Scene& scene, int strip_rows) {
  Cuts cuts;
  const Plan& plan = b.pipeline.plan();
  for (int e = 0; e < plan.count; ++e)
    if (plan.entries[e].runs) {
      cuts.id.push_back(plan.entries[e].id);
      cuts.format.push_back(plan.entries[e].out);
    }
  const size_t pixels = static_cast<size_t>(scene.width) * scene.height;
  std::vector<Tap> taps(cuts.id.size());
  cuts.out.resize(cuts.id.size());
  for (size_t i = 0; i < taps.size(); ++i) {
    cuts.out[i].assign(pixels * cuts.format[i].channels, 0xDEADBEEFu);
    taps[i].stage = static_cast<int>(i);
    taps[i].format = TapFormat::kU32;
    taps[i].data = cuts.out[i].data();
    taps[i].stride = static_cast<ptrdiff_t>(scene.width) * cuts.format[i].channels;
  }
  b.pipeline.ProcessFrame(scene.View(), 5, strip_rows, taps.data(), static_cast<int>(taps.size()), nullptr,
                          nullptr);
  return cuts;
}

int IndexOf(const Cuts& c, StageId id) {
  for (size_t i = 0; i < c.id.size(); ++i)
    if (c.id[i] == id) return static_cast<int>(i);
  return -1;
}

std::unique_ptr<Built> BuildOk(const PipelineConfig& config, const std::string& what) {
  auto b = test::Build(config);
  EXPECT_TRUE(b->status.ok()) << what << ": " << b->status.message();
  return b;
}

// Runs the scene: every stage's output, checked for the same bytes at strip
// heights 1, 2 and the whole frame, every sample in range and written.
Cuts RunChecked(const Built& b, const Scene& scene, const std::string& what) {
  Cuts cuts = RunCuts(b, scene, scene.height);
  EXPECT_EQ(static_cast<int>(cuts.id.size()), b.pipeline.plan().running) << what;
  for (int rows : {1, 2}) {
    const Cuts again = RunCuts(b, scene, rows);
    EXPECT_TRUE(again.out == cuts.out) << what << ": strip height " << rows << " changed the output";
  }
  const uint32_t max_dn = (1u << b.pipeline.config().geometry.adc_bits) - 1;
  for (size_t i = 0; i < cuts.id.size(); ++i) {
    const Domain d = cuts.format[i].domain;
    const bool q16 = d == Domain::kLinear || d == Domain::kEncoded;  // radiance Q16.16 and photons span 32 bits
    const uint32_t max = d == Domain::kDigital ? max_dn : (q16 ? 65535u : 0xFFFFFFFFu);
    size_t bad = 0, unwritten = 0;
    for (uint32_t v : cuts.out[i]) {
      bad += v > max;
      unwritten += v == 0xDEADBEEFu;
    }
    EXPECT_EQ(bad, 0u) << what << ": " << StageName(cuts.id[i]) << " has samples above " << max;
    EXPECT_EQ(unwritten, 0u) << what << ": " << StageName(cuts.id[i]) << " left samples unwritten";
  }
  return cuts;
}

Scene Flat(int w, int h, uint32_t raw) {
  Scene s;
  s.width = w;
  s.height = h;
  for (auto& p : s.plane) p.assign(static_cast<size_t>(w) * h, raw);
  return s;
}

std::string What(Variant v, int w, int h, const char* scene) {
  return std::string(VariantName(v)) + " " + std::to_string(w) + "x" + std::to_string(h) + " " + scene;
}

// Frame sizes: every width 1..17 at one and three rows, and a few sizes that
// are not multiples of 8 or 16 (and one that is), tall and narrow included.
std::vector<std::pair<int, int>> Sizes() {
  std::vector<std::pair<int, int>> s;
  for (int w = 1; w <= 17; ++w)
    for (int h : {1, 3}) s.emplace_back(w, h);
  for (std::pair<int, int> wh : {std::pair{1, 17}, {2, 33}, {2, 2}, {5, 4}, {23, 9}, {31, 33}, {65, 3}, {100, 7},
                                 {16, 16}})
    s.push_back(wh);
  return s;
}
// Fewer sizes for the costlier checks (every cut as its own pipeline, the 8-bit ADC).
std::vector<std::pair<int, int>> FewSizes() {
  return {{1, 1}, {1, 17}, {2, 1}, {3, 5}, {17, 3}, {2, 33}, {23, 9}, {31, 33}};
}

// Expected values of the ISP stages for one value (the stage formulas in double;
// no result of these lies near a rounding tie).
double RoundUp(double x) { return std::floor(x + 0.5); }
uint32_t ExpectedLinear(const PipelineConfig& c, uint32_t dn) {
  const double bl = c.sensor.black_level_dn, max = (1 << c.geometry.adc_bits) - 1;
  return static_cast<uint32_t>(std::min(RoundUp(std::max(dn - bl, 0.0) * 65535.0 / (max - bl)), 65535.0));
}
// White balance: the gain, clipped at min gain * the sensor's white level
// (when the stage runs: a gain differs from 1).
uint32_t ExpectedBalanced(const PipelineConfig& c, uint32_t linear, int colour) {
  const WhiteBalanceConfig& wb = c.white_balance;
  if (wb.gain[0] == 1.0 && wb.gain[1] == 1.0 && wb.gain[2] == 1.0) return linear;
  const double clip = RoundUp(WhiteBalanceClip(wb, c.geometry.cfa, PipelineWhiteLevel(c)));
  return static_cast<uint32_t>(std::min(RoundUp(linear * wb.gain[colour]), clip));
}
// The gamma table as the pipeline builds it.
std::vector<uint16_t> GammaTable(const PipelineConfig& c) {
  GammaStage g;
  EXPECT_TRUE(g.Configure(c.gamma, c.geometry).ok());
  WorkspaceCounter n;
  g.CountTables(n);
  std::vector<uint8_t> memory(n.bytes());
  Arena arena(Span<uint8_t>{memory.data(), memory.size()});
  EXPECT_TRUE(g.Init(arena).ok());
  return std::vector<uint16_t>(g.table(), g.table() + GammaStage::kTableSize);
}

// The raw DN of a pixel at the full well, noise off: min(round(K * FW + BL), max).
uint32_t SaturatedDn(const PipelineConfig& c) {
  const double k = c.sensor.system_gain_dn_per_e * std::pow(10.0, c.sensor.gain_db / 20.0);
  const double dn = RoundUp(k * c.sensor.full_well_e + c.sensor.black_level_dn);
  return static_cast<uint32_t>(std::min(dn, static_cast<double>((1 << c.geometry.adc_bits) - 1)));
}

// Colour of output channel ch at pixel (x, y) of a cut.
int ColourOf(const LineFormat& f, Cfa cfa, int x, int y, int ch) {
  if (f.channels == 3) return ch;
  return f.mosaic ? CfaColour(cfa, x, y) : kGreen;
}

// All-zero radiance, noise off: photons 0, DN = the black level, linear and encoded 0.
void CheckAllZero(const PipelineConfig& c, const Cuts& cuts, const std::string& what) {
  ASSERT_FALSE(cuts.id.empty()) << what;
  EXPECT_EQ(cuts.id.back(), StageId::kGamma) << what;
  for (size_t i = 0; i < cuts.id.size(); ++i) {
    const uint32_t expected =
        cuts.format[i].domain == Domain::kDigital ? static_cast<uint32_t>(RoundUp(c.sensor.black_level_dn)) : 0u;
    EXPECT_EQ(std::count(cuts.out[i].begin(), cuts.out[i].end(), expected),
              static_cast<ptrdiff_t>(cuts.out[i].size()))
        << what << ": after " << StageName(cuts.id[i]) << " every sample should be " << expected;
  }
}

// All-max radiance (0xFFFFFFFF), noise off: photons saturate at the exposure,
// the charge at the full well (every pixel, even in the vignetted corners),
// and every ISP stage gives exactly its formula of that one raw value.
void CheckAllMax(const PipelineConfig& c, const Cuts& cuts, const std::string& what) {
  ASSERT_FALSE(cuts.id.empty()) << what;
  const int w = c.geometry.width, h = c.geometry.height;
  const uint32_t raw = SaturatedDn(c);
  const std::vector<uint16_t> gamma = GammaTable(c);
  // Reflect-101 keeps the Bayer phase only for frames of 2 x 2 and more: in a
  // single row or column demosaic mixes colours.
  const bool phase_kept = (w >= 2 && h >= 2) || c.geometry.cfa == Cfa::kMono;
  // There each demosaiced sample is the double reference's on the white-balanced
  // mosaic (exact integer kernels and one rounding: the same value).
  std::vector<uint32_t> mixed(static_cast<size_t>(w) * h * 3);
  if (!phase_kept) {
    ref::RefImage m{w, h, {std::vector<double>(static_cast<size_t>(w) * h)}};
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        m.planes[0][static_cast<size_t>(y) * w + x] =
            ExpectedBalanced(c, ExpectedLinear(c, raw), CfaColour(c.geometry.cfa, x, y));
    const ref::RefImage d = c.demosaic.method == DemosaicMethod::kMalvar ? ref::RefDemosaicMalvar(m, c.geometry.cfa)
                                                                          : ref::RefDemosaicBilinear(m, c.geometry.cfa);
    for (size_t k = 0; k < mixed.size(); ++k) mixed[k] = static_cast<uint32_t>(RoundUp(d.planes[k % 3][k / 3]));
  }
  for (size_t i = 0; i < cuts.id.size(); ++i) {
    const LineFormat& f = cuts.format[i];
    size_t wrong = 0;
    uint32_t first_wrong = 0, first_expected = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int ch = 0; ch < f.channels; ++ch) {
          const uint32_t got = cuts.out[i][(static_cast<size_t>(y) * w + x) * f.channels + ch];
          const uint32_t linear = ExpectedLinear(c, raw);
          const uint32_t balanced = ExpectedBalanced(c, linear, ColourOf(f, c.geometry.cfa, x, y, ch));
          uint32_t expected = got;
          switch (cuts.id[i]) {
            case StageId::kExposure: expected = 0xFFFFFFFFu; break;  // saturated photons
            case StageId::kSensor: expected = raw; break;
            case StageId::kBlackLevel: expected = linear; break;
            case StageId::kWhiteBalance: expected = balanced; break;
            case StageId::kDemosaic:  // a flat colour plane stays flat
              expected = phase_kept ? balanced : mixed[(static_cast<size_t>(y) * w + x) * 3 + ch];
              break;
            case StageId::kGamma:
              expected = gamma[phase_kept ? balanced : mixed[(static_cast<size_t>(y) * w + x) * 3 + ch]];
              break;
            default: break;  // vignetting, cfa: saturated photons times a gain (checked via the sensor)
          }
          if (got != expected && wrong++ == 0) first_wrong = got, first_expected = expected;
        }
    EXPECT_EQ(wrong, 0u) << what << ": after " << StageName(cuts.id[i]) << " e.g. " << first_wrong
                         << " instead of " << first_expected;
  }
}

// Highlights next to dark pixels, noise off: the model has no blooming, so a
// pixel differs from the all-dark answer only within the demosaic kernel's
// radius of a highlight (0 before demosaic and for mono), and the highlight
// pixels read the saturated DN.
Scene HighlightScene(const PipelineConfig& c, std::vector<bool>* hot) {
  const int w = c.geometry.width, h = c.geometry.height;
  // Radiance that fills the full well without vignetting, times 1e6: far beyond
  // Q16.16, so it saturates to 0xFFFFFFFF (65536 - 2^-16).
  const double saturation =
      c.sensor.full_well_e / c.sensor.quantum_efficiency[kRed] / ExposurePhotonsPerRadiance(c.exposure);
  const uint32_t highlight = Q<16, 16>::FromDouble(1e6 * saturation).raw;
  EXPECT_EQ(highlight, 0xFFFFFFFFu);
  Scene s = Flat(w, h, 0);
  hot->assign(static_cast<size_t>(w) * h, false);
  auto light = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    for (auto& p : s.plane) p[static_cast<size_t>(y) * w + x] = highlight;
    (*hot)[static_cast<size_t>(y) * w + x] = true;
  };
  light(w / 2, h / 2);  // a single pixel
  light(0, h - 1);      // corners (reflected at two edges)
  light(w - 1, 0);
  for (int dy = 0; dy < 2; ++dy)  // a 2 x 2 block
    for (int dx = 0; dx < 2; ++dx) light(w / 4 + dx, 3 * h / 4 + dy);
  return s;
}

void CheckHighlights(const PipelineConfig& c, const std::vector<bool>& hot, const Cuts& cuts,
                     const std::string& what) {
  ASSERT_FALSE(cuts.id.empty()) << what;
  const int w = c.geometry.width, h = c.geometry.height;
  std::vector<int> dist(hot.size(), 1 << 20);  // Chebyshev distance to the nearest highlight
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int yy = 0; yy < h; ++yy)
        for (int xx = 0; xx < w; ++xx)
          if (hot[static_cast<size_t>(yy) * w + xx]) {
            int& d = dist[static_cast<size_t>(y) * w + x];
            d = std::min(d, std::max(std::abs(x - xx), std::abs(y - yy)));
          }
  const int radius = c.geometry.cfa == Cfa::kMono ? 0 : (c.demosaic.method == DemosaicMethod::kMalvar ? 2 : 1);
  const uint32_t raw_sat = SaturatedDn(c);
  const uint32_t black = static_cast<uint32_t>(c.sensor.black_level_dn);
  bool after_demosaic = false;
  for (size_t i = 0; i < cuts.id.size(); ++i) {
    after_demosaic |= cuts.id[i] == StageId::kDemosaic;
    const LineFormat& f = cuts.format[i];
    const uint32_t dark = f.domain == Domain::kDigital ? black : 0u;
    const int r = after_demosaic ? radius : 0;
    size_t leaked = 0, not_saturated = 0, dark_highlights = 0;
    for (size_t p = 0; p < hot.size(); ++p)
      for (int ch = 0; ch < f.channels; ++ch) {
        const uint32_t got = cuts.out[i][p * f.channels + ch];
        if (dist[p] > r && got != dark) ++leaked;
        if (hot[p] && !after_demosaic && got == dark) ++dark_highlights;
        if (cuts.id[i] == StageId::kSensor && hot[p] && got != raw_sat) ++not_saturated;
      }
    EXPECT_EQ(leaked, 0u) << what << ": after " << StageName(cuts.id[i]) << ", pixels farther than " << r
                          << " from a highlight are not dark";
    EXPECT_EQ(dark_highlights, 0u) << what << ": after " << StageName(cuts.id[i]) << " a highlight is dark";
    EXPECT_EQ(not_saturated, 0u) << what << ": highlight pixels should read " << raw_sat;
  }
}

// A textured scene with black and 0xFFFFFFFF samples sprinkled in.
Scene HostileScene(int w, int h) {
  Scene s = test::TexturedScene(w, h);
  for (size_t i = 0; i < s.plane[0].size(); ++i)
    for (int ch = 0; ch < 3; ++ch) {
      if ((i + static_cast<size_t>(ch)) % 5 == 0) s.plane[ch][i] = 0xFFFFFFFFu;
      if ((i + static_cast<size_t>(ch)) % 7 == 3) s.plane[ch][i] = 0u;
    }
  return s;
}

// ---------------------------------------------------------------------------

TEST(Extremes, NoiseOffZeroMaxAndHighlights) {
  for (Variant v : {Variant::kDemo, Variant::kMono})
    for (auto [w, h] : Sizes()) {
      const PipelineConfig c = Config(v, w, h, false);
      auto b = BuildOk(c, What(v, w, h, "noise off"));
      if (!b->status.ok()) continue;
      // 12 bit: the full well limits the raw value: round(0.375 * 10500) + 64 = 4002.
      ASSERT_EQ(SaturatedDn(c), 4002u);
      std::string what = What(v, w, h, "all-zero");
      CheckAllZero(c, RunChecked(*b, Flat(w, h, 0), what), what);
      what = What(v, w, h, "all-max");
      const Cuts max = RunChecked(*b, Flat(w, h, 0xFFFFFFFFu), what);
      CheckAllMax(c, max, what);
      // Saturated is neutral, below full scale (see the top of the file).
      if (!max.out.empty() && (v == Variant::kMono || (w >= 2 && h >= 2))) {
        const std::vector<uint32_t> saturated_output =
            v == Variant::kMono ? std::vector<uint32_t>{64866u} : std::vector<uint32_t>{64866u, 64866u, 64866u};
        EXPECT_EQ(std::vector<uint32_t>(max.out.back().begin(), max.out.back().begin() + saturated_output.size()),
                  saturated_output)
            << what;
      }
      what = What(v, w, h, "highlights");
      std::vector<bool> hot;
      const Scene s = HighlightScene(c, &hot);
      CheckHighlights(c, hot, RunChecked(*b, s, what), what);
    }
}

TEST(Extremes, AdcClippedPixelsStayAtFullScaleThroughTheIsp) {
  // 8-bit ADC: the full well lies above the ADC's range, so saturated pixels
  // read 255 and must come out of the ISP at full scale (65535) on every channel.
  for (Variant v : {Variant::kDemo, Variant::kMono})
    for (auto [w, h] : FewSizes()) {
      PipelineConfig c = Config(v, w, h, false);
      c.geometry.adc_bits = 8;
      ASSERT_EQ(SaturatedDn(c), 255u);
      const std::string what = What(v, w, h, "all-max, 8 bit");
      auto b = BuildOk(c, what);
      if (!b->status.ok()) continue;
      const Cuts cuts = RunChecked(*b, Flat(w, h, 0xFFFFFFFFu), what);
      CheckAllMax(c, cuts, what);
      const std::vector<uint32_t>& out = cuts.out.back();
      EXPECT_EQ(std::count(out.begin(), out.end(), 65535u), static_cast<ptrdiff_t>(out.size())) << what;
    }
}

TEST(Extremes, NoiseOnZeroMaxAndHostileFrames) {
  for (Variant v : {Variant::kDemo, Variant::kMono})
    for (auto [w, h] : Sizes()) {
      const PipelineConfig c = Config(v, w, h, true);
      auto b = BuildOk(c, What(v, w, h, "noise on"));
      if (!b->status.ok()) continue;
      const int64_t black = static_cast<int64_t>(c.sensor.black_level_dn);
      // Dark frame: black level (64 DN) plus read noise (2.4 e-) and DSNU (1 e-),
      // each at most 6.34 sigma (the Gaussian table's tail), times K (0.375):
      // 8.1 DN, plus a few electrons of dark-current shot noise (mean 0.05 e-).
      std::string what = What(v, w, h, "all-zero, noise");
      Cuts cuts = RunChecked(*b, Flat(w, h, 0), what);
      ASSERT_EQ(cuts.id.size(), v == Variant::kDemo ? 8u : 7u) << what;  // the colour matrix is the identity
      for (uint32_t d : cuts.out[static_cast<size_t>(IndexOf(cuts, StageId::kSensor))])
        ASSERT_LE(std::abs(static_cast<int64_t>(d) - black), 10) << what;
      // Saturated frame: the charge is clipped at the full well, then DSNU and read
      // noise as above: within 8.1 DN (+ rounding) of the noise-free value.
      what = What(v, w, h, "all-max, noise");
      cuts = RunChecked(*b, Flat(w, h, 0xFFFFFFFFu), what);
      const int64_t sat = SaturatedDn(c);
      for (uint32_t d : cuts.out[static_cast<size_t>(IndexOf(cuts, StageId::kSensor))])
        ASSERT_LE(std::abs(static_cast<int64_t>(d) - sat), 9) << what;
      // Gradients and edges with black and 0xFFFFFFFF samples: range and strips.
      RunChecked(*b, HostileScene(w, h), What(v, w, h, "hostile"));
    }
}

TEST(Extremes, EveryCutAsItsOwnPipeline) {
  // The pipeline configured to end after each stage gives exactly that stage's
  // tap of the whole pipeline (the last stage's ring, reflections and margins
  // are set up for whichever stage ends the chain).
  for (Variant v : {Variant::kDemo, Variant::kMono})
    for (auto [w, h] : FewSizes()) {
      const PipelineConfig c = Config(v, w, h, true);
      const std::string what = What(v, w, h, "hostile");
      auto b = BuildOk(c, what);
      if (!b->status.ok()) continue;
      const Scene s = HostileScene(w, h);
      const Cuts cuts = RunChecked(*b, s, what);
      for (int k = 1; k < c.order_count; ++k) {
        int last = IndexOf(cuts, c.order[k - 1]);
        if (last < 0) continue;  // left out (demosaic for mono, the identity colour matrix)
        PipelineConfig p = c;
        p.order_count = k;
        auto pb = BuildOk(p, what + " ending at " + StageName(c.order[k - 1]));
        if (!pb->status.ok()) continue;
        // The planner may have moved a stage (a Bayer CFA ahead of exposure and
        // vignetting): compare with the tap of the stage this pipeline ends at.
        const Plan& cut_plan = pb->pipeline.plan();
        for (int i = 0; i < cut_plan.count; ++i)
          if (cut_plan.entries[i].runs) last = IndexOf(cuts, cut_plan.entries[i].id);
        std::vector<uint32_t> alone = test::RunFrame(*pb, s, 5, 3);
        // Exposure and vignetting run after a Bayer CFA in the whole pipeline
        // (its tap is a mosaic), on RGB when the pipeline ends before the CFA.
        if (alone.size() == 3 * cuts.out[static_cast<size_t>(last)].size())
          for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
              const size_t i = static_cast<size_t>(y) * w + x;
              alone[i] = alone[3 * i + CfaColour(c.geometry.cfa, x, y)];
            }
        alone.resize(cuts.out[static_cast<size_t>(last)].size());
        EXPECT_TRUE(alone == cuts.out[static_cast<size_t>(last)])
            << what << ": the pipeline ending at " << StageName(c.order[k - 1]) << " differs from its tap";
      }
    }
}

// A block or a total that size_t cannot hold is refused, not wrapped: on
// 32-bit targets a sensor's fixed-pattern table (24 bytes a pixel for three
// channels) passed 4 GiB, wrapped to 128 KiB, and Init wrote the pattern past it.
TEST(Extremes, WorkspaceSizesThatOverflowAreRefusedNotWrapped) {
  const size_t huge = MaxWorkspaceCount<uint64_t>() + 1;  // its bytes wrap
  WorkspaceCounter counter;
  counter.Add<uint64_t>(huge);
  EXPECT_TRUE(counter.overflowed());
  WorkspaceCounter total;
  total.AddBytes(MaxWorkspaceCount<uint8_t>() - 2 * kWorkspaceAlign);
  EXPECT_FALSE(total.overflowed());
  total.AddBytes(4 * kWorkspaceAlign);  // the sum wraps
  EXPECT_TRUE(total.overflowed());
  std::vector<uint8_t> memory(4096);
  Arena arena(Span<uint8_t>{memory.data(), memory.size()});
  EXPECT_EQ(arena.Take<uint64_t>(huge), nullptr);
  EXPECT_NE(arena.Take<uint64_t>(8), nullptr);
  // The whole pipeline: 16384 x 16384 x 3 channels of fixed pattern. The
  // cross-architecture run (tests/cross/core_golden) checks the refusal on armhf.
  PipelineConfig c = test::DemoConfig(16384, 16384);
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kSensor;
  c.order_count = 2;
  c.sensor.fixed_pattern_table = true;
  Pipeline p;
  const Status st = p.Configure(c, 2, false);
  if (sizeof(size_t) < 8) {
    EXPECT_EQ(st.code(), StatusCode::kResourceExhausted);
  } else {
    ASSERT_TRUE(st.ok()) << st.message();
    EXPECT_GE(p.WorkspaceBytes(), size_t{24} * 16384 * 16384);
  }
}

}  // namespace
}  // namespace camsim
