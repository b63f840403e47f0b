// The ISP stages (black level, white balance, demosaic, colour matrix, gamma)
// against their double references (core/isp/isp_ref.h), exact answers, config
// validation, and every small frame size.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <random>
#include <vector>

#include "core/isp/black_level.h"
#include "core/isp/color_matrix.h"
#include "core/isp/demosaic.h"
#include "core/isp/gamma.h"
#include "core/isp/isp_ref.h"
#include "core/isp/white_balance.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

using ref::RefImage;

// Error bounds against the references, in LSB of the output (1/65535 of full scale).
// Black level: one rounding, plus the scale's relative rounding and the offset's (< 2.3e-5, black_level.h).
constexpr double kBlackLevelMaxErr = 0.5 + 1e-4;
// White balance: one rounding, plus the gain's 2^-32 relative rounding on products <= 16 * 65535 (< 3e-4).
constexpr double kWhiteBalanceMaxErr = 0.5 + 1e-3;
// Demosaic: exact integer sums and one rounding, for both methods.
constexpr double kBilinearMaxErr = 0.5;
constexpr double kMalvarMaxErr = 0.5;
// Colour matrix against the quantised (Q5.24) coefficients it uses: one rounding.
constexpr double kColorMatrixMaxErr = 0.5;
// ... and against the configured doubles: plus each row's coefficient rounding
// (row sum and two off-diagonals, 2^-25 each) on samples up to 65535.
constexpr double kColorMatrixConfigMaxErr = 0.5 + 3.0 * 65535.0 / 33554432.0;
// Gamma: one rounding per table entry, plus a margin for the curve's double
// evaluation (detmath::Pow and libm's pow are within an ulp, ~1e-11 LSB).
constexpr double kGammaMaxErr = 0.5 + 1e-4;

constexpr uint32_t kMaxQ16 = 65535;
constexpr Cfa kBayerPhases[] = {Cfa::kBayerRG, Cfa::kBayerGR, Cfa::kBayerGB, Cfa::kBayerBG};
constexpr DemosaicMethod kMethods[] = {DemosaicMethod::kBilinear, DemosaicMethod::kMalvar};
constexpr int kWidths[] = {1, 2, 7, 16, 23};
constexpr int kHeights[] = {1, 2, 3};
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------
// Images and a stand-in for the pipeline's driver.

struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::vector<uint32_t>> planes;  // planes[c][y * width + x]

  uint32_t& at(int c, int x, int y) { return planes[c][static_cast<size_t>(y) * width + x]; }
  uint32_t at(int c, int x, int y) const { return planes[c][static_cast<size_t>(y) * width + x]; }
};

Image MakeImage(int width, int height, int channels, uint32_t value = 0) {
  Image im{width, height, {}};
  im.planes.assign(channels, std::vector<uint32_t>(static_cast<size_t>(width) * height, value));
  return im;
}

Image RandomImage(int width, int height, int channels, uint32_t max, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<uint32_t> dist(0, max);
  Image im = MakeImage(width, height, channels);
  for (auto& p : im.planes)
    for (uint32_t& v : p) v = dist(rng);
  return im;
}

// A diagonal ramp from 0 to max over the frame, shifted per channel.
Image RampImage(int width, int height, int channels, uint32_t max) {
  Image im = MakeImage(width, height, channels);
  const double span = width + height - 2 > 0 ? width + height - 2 : 1;
  for (int c = 0; c < channels; ++c)
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        const double t = std::fmod((x + y) / span + c / 3.0, 1.0);
        im.at(c, x, y) = static_cast<uint32_t>(std::lround(t * max));
      }
  return im;
}

// The 1-channel mosaic of an RGB image.
Image Mosaic(const Image& rgb, Cfa cfa) {
  Image m = MakeImage(rgb.width, rgb.height, 1);
  for (int y = 0; y < rgb.height; ++y)
    for (int x = 0; x < rgb.width; ++x) m.at(0, x, y) = rgb.at(CfaColour(cfa, x, y), x, y);
  return m;
}

RefImage ToRef(const Image& im) {
  RefImage r;
  r.width = im.width;
  r.height = im.height;
  for (const auto& p : im.planes) r.planes.emplace_back(p.begin(), p.end());
  return r;
}

double MaxAbsError(const Image& got, const RefImage& want) {
  EXPECT_EQ(got.planes.size(), want.planes.size());
  double worst = 0.0;
  for (size_t c = 0; c < got.planes.size() && c < want.planes.size(); ++c)
    for (size_t i = 0; i < got.planes[c].size(); ++i)
      worst = std::max(worst, std::abs(static_cast<double>(got.planes[c][i]) - want.planes[c][i]));
  return worst;
}

// Runs a stage over a whole image as the pipeline's driver does: each input
// row padded by reflect-101 to Margin() columns each side, rows outside the
// frame reflected, the stage's InputRows window per call. Every padded
// row, the row window and every output row is its own allocation of exactly
// the size the contract allows, so ASan reports any access outside it.
Image RunStage(const Stage& stage, const Image& in, int out_channels) {
  const int w = in.width, h = in.height, margin = stage.Margin();
  std::vector<std::vector<std::vector<uint32_t>>> padded(in.planes.size());
  for (size_t c = 0; c < in.planes.size(); ++c)
    for (int y = 0; y < h; ++y) {
      std::vector<uint32_t> row(static_cast<size_t>(w + 2 * margin));
      for (int i = -margin; i < w + margin; ++i)
        row[i + margin] = in.at(static_cast<int>(c), Reflect101(i, w), y);
      padded[c].push_back(std::move(row));
    }
  Image out = MakeImage(w, h, out_channels);
  std::vector<std::vector<uint32_t>> out_rows(out_channels, std::vector<uint32_t>(w));
  for (int y = 0; y < h; ++y) {
    const RowWindow window = stage.InputRows(y, h);
    const int count = window.last - window.first + 1;
    std::vector<RowIn> rows(static_cast<size_t>(count));
    for (int k = 0; k < count; ++k)
      for (size_t c = 0; c < in.planes.size(); ++c)
        rows[k].ch[c] = padded[c][Reflect101(window.first + k, h)].data() + margin;
    RowArgs args;
    args.y = y;
    args.width = w;
    args.rows = rows.data();
    args.first_row = window.first;
    args.row_count = count;
    for (int c = 0; c < out_channels; ++c) args.out[c] = out_rows[c].data();
    stage.ProcessRow(args);
    for (int c = 0; c < out_channels; ++c)
      for (int x = 0; x < w; ++x) out.at(c, x, y) = out_rows[c][x];
  }
  return out;
}

using test::InitStage;
using test::StageTables;

SensorGeometry Geometry(int width, int height, Cfa cfa = Cfa::kBayerRG, int adc_bits = 12) {
  SensorGeometry g;
  g.width = width;
  g.height = height;
  g.cfa = cfa;
  g.adc_bits = adc_bits;
  return g;
}

void ExpectInvalid(const Status& s, const char* field) {
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_STREQ(s.field(), field);
}

// ---------------------------------------------------------------------------
// Black level

TEST(IspBlackLevel, ExactEndpoints) {
  BlackLevelStage stage;
  ASSERT_TRUE(stage.Configure(BlackLevelConfig{64.0}, Geometry(4, 1), 0.0).ok());
  Image in = MakeImage(4, 1, 1);
  in.planes[0] = {0, 63, 64, 4095};
  const Image out = RunStage(stage, in, 1);
  EXPECT_EQ(out.planes[0], (std::vector<uint32_t>{0, 0, 0, 65535}));
}

TEST(IspBlackLevel, ExactMidpointsAt16Bits) {
  // BL 0 at 16 bits: the scale is exactly 1.
  BlackLevelStage stage;
  ASSERT_TRUE(stage.Configure(BlackLevelConfig{0.0}, Geometry(3, 1, Cfa::kMono, 16), 0.0).ok());
  Image in = MakeImage(3, 1, 1);
  in.planes[0] = {1, 32768, 65535};
  EXPECT_EQ(RunStage(stage, in, 1).planes[0], (std::vector<uint32_t>{1, 32768, 65535}));
}

TEST(IspBlackLevel, UsesTheSensorBlackLevelByDefault) {
  BlackLevelStage stage;
  ASSERT_TRUE(stage.Configure(BlackLevelConfig{}, Geometry(2, 1), 240.0).ok());
  EXPECT_EQ(stage.black_level_dn(), 240.0);
  Image in = MakeImage(2, 1, 1);
  in.planes[0] = {240, 4095};
  EXPECT_EQ(RunStage(stage, in, 1).planes[0], (std::vector<uint32_t>{0, 65535}));
}

TEST(IspBlackLevel, MatchesReferenceOnRampsAndRandomData) {
  struct Case {
    int adc_bits;
    double black_level;
  };
  const Case cases[] = {{8, 16.0}, {10, 64.0},   {12, 240.0}, {12, 100.5},
                        {14, 0.0}, {16, 4096.0}, {12, 4094.0}};
  for (const Case& k : cases) {
    SCOPED_TRACE(testing::Message() << "adc_bits " << k.adc_bits << " BL " << k.black_level);
    BlackLevelStage stage;
    ASSERT_TRUE(
        stage.Configure(BlackLevelConfig{k.black_level}, Geometry(1, 1, Cfa::kBayerRG, k.adc_bits), 0.0)
            .ok());
    const uint32_t max_dn = (1u << k.adc_bits) - 1;
    // Every code once: a 256-wide ramp.
    Image ramp = MakeImage(256, static_cast<int>((max_dn + 1) / 256), 1);
    for (size_t i = 0; i < ramp.planes[0].size(); ++i) ramp.planes[0][i] = static_cast<uint32_t>(i);
    EXPECT_LE(
        MaxAbsError(RunStage(stage, ramp, 1), ref::RefBlackLevel(ToRef(ramp), k.black_level, k.adc_bits)),
        kBlackLevelMaxErr);
    const Image rgb = RandomImage(31, 9, 3, max_dn, 7);
    EXPECT_LE(MaxAbsError(RunStage(stage, rgb, 3), ref::RefBlackLevel(ToRef(rgb), k.black_level, k.adc_bits)),
              kBlackLevelMaxErr);
  }
}

TEST(IspBlackLevel, RejectsBadValues) {
  BlackLevelStage stage;
  const SensorGeometry g = Geometry(8, 8);  // 12 bits: max 4095
  ExpectInvalid(stage.Configure(BlackLevelConfig{kNaN}, g, 64.0), "black_level.black_level_dn");
  ExpectInvalid(stage.Configure(BlackLevelConfig{-2.0}, g, 64.0), "black_level.black_level_dn");
  ExpectInvalid(stage.Configure(BlackLevelConfig{4095.0}, g, 64.0), "black_level.black_level_dn");
  ExpectInvalid(stage.Configure(BlackLevelConfig{4094.5}, g, 64.0), "black_level.black_level_dn");
  ExpectInvalid(stage.Configure(BlackLevelConfig{}, g, kNaN), "sensor.black_level_dn");
  ExpectInvalid(stage.Configure(BlackLevelConfig{}, g, 4095.0), "sensor.black_level_dn");
  ExpectInvalid(stage.Configure(BlackLevelConfig{}, Geometry(8, 8, Cfa::kBayerRG, 17), 64.0),
                "sensor.adc_bits");
  EXPECT_TRUE(stage.Configure(BlackLevelConfig{4094.0}, g, 64.0).ok());
}

TEST(IspBlackLevel, PlanConvertsDigitalToLinear) {
  BlackLevelStage stage;
  ASSERT_TRUE(stage.Configure(BlackLevelConfig{}, Geometry(8, 8), 64.0).ok());
  EXPECT_EQ(stage.IdentityReason(), nullptr);
  const Result<LineFormat> f = stage.Plan(LineFormat{Domain::kDigital, 1, true});
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f.value().domain, Domain::kLinear);
  EXPECT_EQ(f.value().channels, 1);
  EXPECT_TRUE(f.value().mosaic);
  EXPECT_FALSE(stage.Plan(LineFormat{Domain::kLinear, 1, true}).ok());
}

// ---------------------------------------------------------------------------
// White balance

TEST(IspWhiteBalance, ExactGainsAndSaturation) {
  WhiteBalanceStage stage;
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{{2.0, 1.0, 16.0}}, Geometry(3, 1), 1.0).ok());
  Image in = MakeImage(3, 1, 3);
  in.planes[0] = {0, 1000, 40000};  // R x2
  in.planes[1] = {1, 3, 65535};     // G x1
  in.planes[2] = {1, 4095, 4096};   // B x16: 65520, then saturation
  const Image out = RunStage(stage, in, 3);
  EXPECT_EQ(out.planes[0], (std::vector<uint32_t>{0, 2000, 65535}));
  EXPECT_EQ(out.planes[1], (std::vector<uint32_t>{1, 3, 65535}));
  EXPECT_EQ(out.planes[2], (std::vector<uint32_t>{16, 65520, 65535}));
  // A gain below 1 lowers the clip with it (min gain 0.5 times white 1:
  // 32767.5, rounded up), so every channel of a full well ends equal.
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{{2.0, 0.5, 16.0}}, Geometry(3, 1), 1.0).ok());
  in.planes[1] = {1, 3, 65535};  // G x0.5: 0.5 and 1.5 round up
  const Image half = RunStage(stage, in, 3);
  EXPECT_EQ(half.planes[0], (std::vector<uint32_t>{0, 2000, 32768}));
  EXPECT_EQ(half.planes[1], (std::vector<uint32_t>{1, 2, 32768}));
  EXPECT_EQ(half.planes[2], (std::vector<uint32_t>{16, 32768, 32768}));
}

// A full well is below the ADC's maximum (the demo camera: K W + BL = 4002
// DN of 4095), so after the black level every channel of a blown highlight
// reads the white level; gains above 1 lifted R and B above G: magenta. The
// clip at min gain * white keeps it neutral, in the stage and through the
// whole demo pipeline to 16-bit sRGB.
TEST(IspWhiteBalance, BlownHighlightsStayNeutral) {
  const double white = WhiteLevel(4002.0, 64.0, 12);
  EXPECT_NEAR(white, (4002.0 - 64.0) / (4095.0 - 64.0), 1e-15);
  WhiteBalanceStage stage;
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{{1.9, 1.0, 1.4}}, Geometry(2, 1), white).ok());
  const uint32_t full = static_cast<uint32_t>(std::lround(white * kMaxQ16));
  const Image out = RunStage(stage, MakeImage(2, 1, 3, full), 3);
  EXPECT_EQ(out.planes[0], out.planes[1]);
  EXPECT_EQ(out.planes[2], out.planes[1]);
  EXPECT_EQ(out.planes[1][0], full);

  PipelineConfig c = test::DemoConfig(48, 32);
  c.white_balance.gain[0] = 1.9;
  c.white_balance.gain[2] = 1.4;
  c.exposure.exposure_time_us *= 20;  // every pixel far over its well
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const std::vector<uint32_t> rgb = test::RunFrame(*b, test::FlatScene(48, 32, 1.0, 1.0, 1.0), 0, 32);
  // The read noise and DSNU after the well's clip leave G a few DN of 4095
  // below the clip in some pixels; the tint was 675 of 65535 (sRGB (65535,
  // 64860, 65535)) before the clip.
  double r_minus_g = 0, b_minus_g = 0;
  for (size_t i = 0; i < rgb.size(); i += 3) {
    r_minus_g += double(rgb[i]) - rgb[i + 1];
    b_minus_g += double(rgb[i + 2]) - rgb[i + 1];
  }
  const double n = static_cast<double>(rgb.size() / 3);
  EXPECT_LT(std::fabs(r_minus_g / n), 64.0);
  EXPECT_LT(std::fabs(b_minus_g / n), 64.0);
}

TEST(IspWhiteBalance, MosaicTakesTheSiteColourGain) {
  // RGGB with gains R 2, G 1, B 4 on a flat 1000 field.
  WhiteBalanceStage stage;
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{{2.0, 1.0, 4.0}}, Geometry(2, 2, Cfa::kBayerRG), 1.0).ok());
  const Image out = RunStage(stage, MakeImage(2, 2, 1, 1000), 1);
  EXPECT_EQ(out.planes[0], (std::vector<uint32_t>{2000, 1000, 1000, 4000}));
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{{2.0, 1.0, 4.0}}, Geometry(2, 2, Cfa::kMono), 1.0).ok());
  EXPECT_EQ(RunStage(stage, MakeImage(2, 2, 1, 1000), 1).planes[0],
            (std::vector<uint32_t>{1000, 1000, 1000, 1000}));
  // Mono clips at its own (G) gain times the white level, not at the
  // smallest of gains it never uses: 1.0 * 0.8 * 65535 = 52428.
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{{0.5, 1.0, 2.0}}, Geometry(2, 1, Cfa::kMono), 0.8).ok());
  Image mono = MakeImage(2, 1, 1);
  mono.planes[0] = {40000, 60000};
  EXPECT_EQ(RunStage(stage, mono, 1).planes[0], (std::vector<uint32_t>{40000, 52428}));
  EXPECT_LE(MaxAbsError(RunStage(stage, mono, 1), ref::RefWhiteBalance(ToRef(mono), Cfa::kMono,
                                                                      WhiteBalanceConfig{{0.5, 1.0, 2.0}}, 0.8)),
            kWhiteBalanceMaxErr);
}

TEST(IspWhiteBalance, MatchesReference) {
  const WhiteBalanceConfig configs[] = {
      {{2.0137, 1.0, 1.7321}}, {{0.4, 1.3, 15.9}}, {{0.0, 16.0, 1.0 / 3.0}}};
  for (const WhiteBalanceConfig& config : configs)
    for (Cfa cfa : kBayerPhases)
      for (const double white : {1.0, 0.977, 0.31}) {
        WhiteBalanceStage stage;
        ASSERT_TRUE(stage.Configure(config, Geometry(1, 1, cfa), white).ok());
        const Image inputs[] = {RandomImage(29, 11, 1, kMaxQ16, 3), RampImage(64, 32, 1, kMaxQ16),
                                RandomImage(17, 5, 3, kMaxQ16, 4), RampImage(40, 8, 3, kMaxQ16)};
        for (const Image& in : inputs) {
          const int channels = static_cast<int>(in.planes.size());
          EXPECT_LE(MaxAbsError(RunStage(stage, in, channels), ref::RefWhiteBalance(ToRef(in), cfa, config, white)),
                    kWhiteBalanceMaxErr);
        }
      }
}

TEST(IspWhiteBalance, IdentityAndValidation) {
  WhiteBalanceStage stage;
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{}, Geometry(4, 4), 1.0).ok());
  EXPECT_STREQ(stage.IdentityReason(), "white-balance gains are all 1");
  ASSERT_TRUE(stage.Configure(WhiteBalanceConfig{{1.0, 1.0, 1.001}}, Geometry(4, 4), 1.0).ok());
  EXPECT_EQ(stage.IdentityReason(), nullptr);
  const double bad[] = {kNaN, -0.1, 16.01, std::numeric_limits<double>::infinity()};
  for (double b : bad)
    ExpectInvalid(stage.Configure(WhiteBalanceConfig{{1.0, b, 1.0}}, Geometry(4, 4), 1.0), "white_balance.gain");
  EXPECT_FALSE(stage.Plan(LineFormat{Domain::kDigital, 1, true}).ok());
}

// ---------------------------------------------------------------------------
// Demosaic

DemosaicStage MakeDemosaic(DemosaicMethod method, Cfa cfa, int width = 8, int height = 8) {
  DemosaicStage stage;
  EXPECT_TRUE(stage.Configure(DemosaicConfig{method}, Geometry(width, height, cfa)).ok());
  return stage;
}

RefImage RefDemosaic(DemosaicMethod method, const Image& mosaic, Cfa cfa) {
  return method == DemosaicMethod::kMalvar ? ref::RefDemosaicMalvar(ToRef(mosaic), cfa)
                                           : ref::RefDemosaicBilinear(ToRef(mosaic), cfa);
}

double DemosaicMaxErr(DemosaicMethod method) {
  return method == DemosaicMethod::kMalvar ? kMalvarMaxErr : kBilinearMaxErr;
}

TEST(IspDemosaic, ContextPerMethod) {
  const DemosaicStage bilinear = MakeDemosaic(DemosaicMethod::kBilinear, Cfa::kBayerRG);
  EXPECT_EQ(bilinear.RowsAbove(), 1);
  EXPECT_EQ(bilinear.RowsBelow(), 1);
  EXPECT_EQ(bilinear.Margin(), 1);
  const DemosaicStage malvar = MakeDemosaic(DemosaicMethod::kMalvar, Cfa::kBayerRG);
  EXPECT_EQ(malvar.RowsAbove(), 2);
  EXPECT_EQ(malvar.RowsBelow(), 2);
  EXPECT_EQ(malvar.Margin(), 2);
  EXPECT_EQ(malvar.IdentityReason(), nullptr);
}

TEST(IspDemosaic, FlatFieldStaysFlatAtEverySize) {
  for (DemosaicMethod method : kMethods)
    for (Cfa cfa : kBayerPhases)
      for (int w : kWidths)
        for (int h : kHeights) {
          SCOPED_TRACE(testing::Message() << "method " << static_cast<int>(method) << " cfa " << CfaName(cfa)
                                          << " " << w << "x" << h);
          const Image out = RunStage(MakeDemosaic(method, cfa, w, h), MakeImage(w, h, 1, 12345), 3);
          for (const auto& plane : out.planes)
            for (uint32_t v : plane) ASSERT_EQ(v, 12345u);
        }
}

TEST(IspDemosaic, FlatColourIsReconstructedExactly) {
  // R, G, B constant: every kernel's weights on a colour sum to 1 or 0 (its
  // gradient corrections cancel on a constant plane), and reflect-101 keeps
  // the CFA phase for sizes >= 2, so every pixel is exact.
  constexpr uint32_t kColour[3] = {50000, 20000, 3000};
  for (DemosaicMethod method : kMethods)
    for (Cfa cfa : kBayerPhases)
      for (int w : {2, 7, 16})
        for (int h : {2, 3, 9}) {
          SCOPED_TRACE(testing::Message() << "method " << static_cast<int>(method) << " cfa " << CfaName(cfa)
                                          << " " << w << "x" << h);
          Image rgb = MakeImage(w, h, 3);
          for (int c = 0; c < 3; ++c) rgb.planes[c].assign(rgb.planes[c].size(), kColour[c]);
          const Image out = RunStage(MakeDemosaic(method, cfa, w, h), Mosaic(rgb, cfa), 3);
          for (int c = 0; c < 3; ++c) ASSERT_EQ(out.planes[c], rgb.planes[c]);
        }
}

TEST(IspDemosaic, BilinearImpulseGivesTheKernelWeights) {
  // One sample of 4000 at (3, 3) in a 7x7 zero mosaic: its colour's output is
  // 4000 * K (K_rb or K_g), the other colours stay 0.
  const std::vector<uint32_t> kRbResponse = {1000, 2000, 1000, 2000, 4000, 2000, 1000, 2000, 1000};
  const std::vector<uint32_t> kGResponse = {0, 1000, 0, 1000, 4000, 1000, 0, 1000, 0};
  for (Cfa cfa : kBayerPhases) {
    SCOPED_TRACE(CfaName(cfa));
    Image mosaic = MakeImage(7, 7, 1);
    mosaic.at(0, 3, 3) = 4000;
    const Colour colour = CfaColour(cfa, 3, 3);
    const Image out = RunStage(MakeDemosaic(DemosaicMethod::kBilinear, cfa, 7, 7), mosaic, 3);
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < 7; ++y)
        for (int x = 0; x < 7; ++x) {
          const bool near = c == colour && std::abs(x - 3) <= 1 && std::abs(y - 3) <= 1;
          const auto& k = colour == kGreen ? kGResponse : kRbResponse;
          const uint32_t want = near ? k[(y - 2) * 3 + (x - 2)] : 0;
          ASSERT_EQ(out.at(c, x, y), want) << "c " << c << " at " << x << "," << y;
        }
  }
}

TEST(IspDemosaic, MatchesReferenceOnRandomDataAndRamps) {
  for (DemosaicMethod method : kMethods)
    for (Cfa cfa : kBayerPhases) {
      SCOPED_TRACE(testing::Message() << "method " << static_cast<int>(method) << " cfa " << CfaName(cfa));
      const Image inputs[] = {RandomImage(33, 21, 1, kMaxQ16, 11),
                              Mosaic(RampImage(48, 24, 3, kMaxQ16), cfa)};
      for (const Image& in : inputs) {
        const Image out = RunStage(MakeDemosaic(method, cfa, in.width, in.height), in, 3);
        EXPECT_LE(MaxAbsError(out, RefDemosaic(method, in, cfa)), DemosaicMaxErr(method));
      }
    }
}

TEST(IspDemosaic, MalvarReconstructsASmoothColourRamp) {
  // Linear ramps per colour: the gradient corrections are exact on linear
  // signals, so interior pixels (2 from the border) equal the true ramp up to
  // the one rounding; all pixels match the reference within its bound.
  constexpr int kW = 40, kH = 30;
  Image rgb = MakeImage(kW, kH, 3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      rgb.at(kRed, x, y) = static_cast<uint32_t>(1000 + 700 * x + 300 * y);
      rgb.at(kGreen, x, y) = static_cast<uint32_t>(60000 - 500 * x - 800 * y);
      rgb.at(kBlue, x, y) = static_cast<uint32_t>(20000 + 250 * x + 1000 * y);
    }
  for (Cfa cfa : kBayerPhases) {
    SCOPED_TRACE(CfaName(cfa));
    const Image mosaic = Mosaic(rgb, cfa);
    const Image out = RunStage(MakeDemosaic(DemosaicMethod::kMalvar, cfa, kW, kH), mosaic, 3);
    EXPECT_LE(MaxAbsError(out, ref::RefDemosaicMalvar(ToRef(mosaic), cfa)), kMalvarMaxErr);
    for (int c = 0; c < 3; ++c)
      for (int y = 2; y < kH - 2; ++y)
        for (int x = 2; x < kW - 2; ++x)
          ASSERT_EQ(out.at(c, x, y), rgb.at(c, x, y)) << c << " " << x << "," << y;
  }
}

TEST(IspDemosaic, EverySmallSizeMatchesReference) {
  for (DemosaicMethod method : kMethods)
    for (Cfa cfa : kBayerPhases)
      for (int w : kWidths)
        for (int h : kHeights) {
          SCOPED_TRACE(testing::Message() << "method " << static_cast<int>(method) << " cfa " << CfaName(cfa)
                                          << " " << w << "x" << h);
          const Image in = RandomImage(w, h, 1, kMaxQ16, static_cast<uint32_t>(w * 10 + h));
          const Image out = RunStage(MakeDemosaic(method, cfa, w, h), in, 3);
          EXPECT_LE(MaxAbsError(out, RefDemosaic(method, in, cfa)), DemosaicMaxErr(method));
        }
}

// The row functions run in blocks of 8 columns (a mask table) and finish the
// last width % 8 columns one by one (the mask from x): both must give exactly
// the reference rounded to nearest, ties up, and clamped to [0, 65535]. Every
// tail length 0..7 after one to three blocks, every phase; integer equality,
// not a bound, so any difference between the two paths fails.
TEST(IspDemosaic, BlocksAndTailEqualTheRoundedReference) {
  for (DemosaicMethod method : kMethods)
    for (Cfa cfa : kBayerPhases)
      for (int w = 8; w <= 31; ++w) {
        SCOPED_TRACE(testing::Message() << "method " << static_cast<int>(method) << " cfa " << CfaName(cfa)
                                        << " width " << w);
        const Image in = RandomImage(w, 5, 1, kMaxQ16, static_cast<uint32_t>(100 + w));
        const Image out = RunStage(MakeDemosaic(method, cfa, w, 5), in, 3);
        const RefImage want = RefDemosaic(method, in, cfa);
        for (int c = 0; c < 3; ++c)
          for (int y = 0; y < 5; ++y)
            for (int x = 0; x < w; ++x) {
              // Reference values are multiples of 1/16: exact in double.
              const double v = std::floor(want.planes[c][static_cast<size_t>(y) * w + x] + 0.5);
              const uint32_t rounded = static_cast<uint32_t>(std::clamp(v, 0.0, 65535.0));
              ASSERT_EQ(out.at(c, x, y), rounded) << "c " << c << " at " << x << "," << y;
            }
      }
}

TEST(IspDemosaic, PlanRefusesWhatIsNotALinearBayerMosaic) {
  const DemosaicStage mono = MakeDemosaic(DemosaicMethod::kBilinear, Cfa::kMono);
  const Result<LineFormat> refused = mono.Plan(LineFormat{Domain::kLinear, 1, false});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_STREQ(refused.status().message(), "demosaic needs a Bayer mosaic; the CFA is mono");

  const DemosaicStage bayer = MakeDemosaic(DemosaicMethod::kMalvar, Cfa::kBayerGB);
  EXPECT_FALSE(bayer.Plan(LineFormat{Domain::kLinear, 3, false}).ok());
  EXPECT_FALSE(bayer.Plan(LineFormat{Domain::kDigital, 1, true}).ok());
  const Result<LineFormat> ok = bayer.Plan(LineFormat{Domain::kLinear, 1, true});
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(ok.value().domain, Domain::kLinear);
  EXPECT_EQ(ok.value().channels, 3);
  EXPECT_FALSE(ok.value().mosaic);
}

TEST(IspDemosaic, RejectsUnknownMethod) {
  DemosaicStage stage;
  ExpectInvalid(stage.Configure(DemosaicConfig{static_cast<DemosaicMethod>(7)}, Geometry(4, 4)),
                "demosaic.method");
}

// ---------------------------------------------------------------------------
// Colour matrix

ColorMatrixConfig Matrix(std::initializer_list<double> m) {
  ColorMatrixConfig c;
  std::copy(m.begin(), m.end(), c.m);
  return c;
}

// The coefficients the stage uses, as doubles.
std::vector<double> Quantised(const ColorMatrixStage& stage) {
  std::vector<double> q(9);
  for (int i = 0; i < 9; ++i) q[i] = std::ldexp(static_cast<double>(stage.coefficient(i)), -ColorMatrixStage::kFracBits);
  return q;
}

TEST(IspColorMatrix, IdentityGivesTheInput) {
  ColorMatrixStage stage;
  ASSERT_TRUE(stage.Configure(ColorMatrixConfig{}, Geometry(4, 4)).ok());
  EXPECT_STREQ(stage.IdentityReason(), "colour matrix is the identity");
  const Image in = RandomImage(23, 3, 3, kMaxQ16, 5);
  const Image out = RunStage(stage, in, 3);
  EXPECT_EQ(out.planes, in.planes);
}

TEST(IspColorMatrix, ExactSmallCase) {
  // Coefficients on the Q.24 grid: exact products, one rounding (ties up).
  ColorMatrixStage stage;
  ASSERT_TRUE(stage.Configure(Matrix({0.5, 0.25, 0.25, -0.5, 2.0, -0.5, 0, 0, 1}), Geometry(2, 1)).ok());
  EXPECT_EQ(stage.IdentityReason(), nullptr);
  Image in = MakeImage(2, 1, 3);
  in.planes[0] = {101, 60000};
  in.planes[1] = {0, 60000};
  in.planes[2] = {0, 0};
  const Image out = RunStage(stage, in, 3);
  EXPECT_EQ(out.planes[0], (std::vector<uint32_t>{51, 45000}));  // 50.5 rounds up
  EXPECT_EQ(out.planes[1], (std::vector<uint32_t>{0, 65535}));   // -50.5 and 90000 clamp
  EXPECT_EQ(out.planes[2], (std::vector<uint32_t>{0, 0}));
}

TEST(IspColorMatrix, WhitePreservingRowsKeepGreyExactly) {
  // Rows summing to 1 whose coefficients are not on the Q.24 grid: the
  // diagonal takes each row's rounding remainder, so grey stays grey.
  ColorMatrixStage stage;
  ASSERT_TRUE(
      stage
          .Configure(Matrix({1.6013, -0.4507, -0.1506, -0.2032, 1.4198, -0.2166, 0.0131, -0.5499, 1.5368}),
                     Geometry(1, 1))
          .ok());
  Image grey = MakeImage(256, 256, 3);
  for (int c = 0; c < 3; ++c)
    for (size_t i = 0; i < grey.planes[c].size(); ++i) grey.planes[c][i] = static_cast<uint32_t>(i);
  EXPECT_EQ(RunStage(stage, grey, 3).planes, grey.planes);
}

TEST(IspColorMatrix, MatchesReference) {
  const ColorMatrixConfig configs[] = {
      Matrix({1.6013, -0.4507, -0.1506, -0.2032, 1.4198, -0.2166, 0.0131, -0.5499, 1.5368}),
      Matrix({0.3, 0.59, 0.11, 0.3, 0.59, 0.11, 0.3, 0.59, 0.11}),
      Matrix({16, -16, 0.123456, -3.3, 0.0001, 2.7, 0.5, 0.5, -15.999})};
  for (const ColorMatrixConfig& config : configs) {
    ColorMatrixStage stage;
    ASSERT_TRUE(stage.Configure(config, Geometry(1, 1)).ok());
    const std::vector<double> q = Quantised(stage);
    const Image inputs[] = {RandomImage(37, 13, 3, kMaxQ16, 9), RampImage(64, 16, 3, kMaxQ16)};
    for (const Image& in : inputs) {
      const Image out = RunStage(stage, in, 3);
      EXPECT_LE(MaxAbsError(out, ref::RefColorMatrix(ToRef(in), q.data())), kColorMatrixMaxErr);
      EXPECT_LE(MaxAbsError(out, ref::RefColorMatrix(ToRef(in), config.m)), kColorMatrixConfigMaxErr);
    }
  }
}

// The row loop (vectorised per CPU tier) against the formula in int64 with
// the stage's own coefficients, sample by sample: every row length up to 40
// (each tail after the lanes), the extreme coefficients +-16, and samples at
// 0 and 65535 so that both clamps are reached.
TEST(IspColorMatrix, RowsAreTheFormulaAtEveryWidth) {
  ColorMatrixStage stage;
  ASSERT_TRUE(stage.Configure(Matrix({16, -16, 0.123456, -3.3, 0.0001, 2.7, 0.5, 0.5, -15.999}), Geometry(1, 1)).ok());
  for (int width = 1; width <= 40; ++width) {
    Image in = RandomImage(width, 2, 3, kMaxQ16, 100 + width);
    for (int c = 0; c < 3; ++c)
      for (size_t i = 0; i < in.planes[c].size(); i += 4) in.planes[c][i] = (i / 4 + c) % 2 ? 65535 : 0;
    const Image out = RunStage(stage, in, 3);
    for (int k = 0; k < 3; ++k)
      for (size_t i = 0; i < in.planes[0].size(); ++i) {
        int64_t sum = 0;
        for (int j = 0; j < 3; ++j) sum += int64_t{stage.coefficient(3 * k + j)} * in.planes[j][i];
        const int64_t v = (sum + (int64_t{1} << 23)) >> 24;
        ASSERT_EQ(out.planes[k][i], static_cast<uint32_t>(std::clamp<int64_t>(v, 0, 65535)))
            << "width " << width << " channel " << k << " sample " << i;
      }
  }
}

TEST(IspColorMatrix, Validation) {
  ColorMatrixStage stage;
  const SensorGeometry g = Geometry(4, 4);
  ExpectInvalid(stage.Configure(Matrix({1, 0, 0, 0, kNaN, 0, 0, 0, 1}), g), "color_matrix.m");
  ExpectInvalid(stage.Configure(Matrix({1, 0, 16.5, 0, 1, 0, 0, 0, 1}), g), "color_matrix.m");
  ExpectInvalid(stage.Configure(Matrix({1, 0, 0, 0, 1, 0, 0, 0, -16.01}), g), "color_matrix.m");
  // In range, but the diagonal 16 cannot take the row's rounding remainder:
  // the off-diagonals (2e-8 < 2^-25) round to 0, the row sum to 16 + 2^-24.
  ExpectInvalid(stage.Configure(Matrix({16, 2e-8, 2e-8, 0, 1, 0, 0, 0, 1}), g), "color_matrix.m");
  EXPECT_TRUE(stage.Configure(Matrix({16, -16, 16, 0, 1, 0, 0, 0, 1}), g).ok());
  EXPECT_FALSE(stage.Plan(LineFormat{Domain::kLinear, 1, true}).ok());
}

// ---------------------------------------------------------------------------
// Gamma

GammaStage MakeGamma(GammaConfig config, StageTables& tables) {
  GammaStage stage;
  EXPECT_TRUE(stage.Configure(config, Geometry(1, 1)).ok());
  EXPECT_TRUE(InitStage(stage, tables).ok());
  return stage;
}

TEST(IspGamma, EndpointsAndMonotonic) {
  const GammaConfig configs[] = {{GammaCurve::kSrgb, 2.2},
                                 {GammaCurve::kPower, 2.2},
                                 {GammaCurve::kPower, 0.1},
                                 {GammaCurve::kPower, 10.0},
                                 {GammaCurve::kLinear, 2.2}};
  for (const GammaConfig& config : configs) {
    StageTables tables;
    const GammaStage stage = MakeGamma(config, tables);
    const uint16_t* t = stage.table();
    EXPECT_EQ(t[0], 0);
    EXPECT_EQ(t[65535], 65535);
    for (size_t i = 1; i < GammaStage::kTableSize; ++i) ASSERT_LE(t[i - 1], t[i]) << i;
  }
}

TEST(IspGamma, SrgbAtKnownPoints) {
  // round(65535 * sRGB(i / 65535)); 100 and 205 are on the linear segment.
  StageTables tables;
  const GammaStage stage = MakeGamma({GammaCurve::kSrgb, 2.2}, tables);
  Image in = MakeImage(9, 1, 1);
  in.planes[0] = {0, 1, 100, 205, 206, 1000, 16384, 32768, 65535};
  EXPECT_EQ(RunStage(stage, in, 1).planes[0],
            (std::vector<uint32_t>{0, 13, 1292, 2649, 2661, 8498, 35199, 48192, 65535}));
}

TEST(IspGamma, PowerAtKnownPointsAndAboveFullScale) {
  StageTables tables;
  const GammaStage stage = MakeGamma({GammaCurve::kPower, 2.2}, tables);
  Image in = MakeImage(4, 1, 1);
  in.planes[0] = {1, 256, 32768, 70000};  // 70000 > full scale reads the last entry
  // round(65535 (v / 65535)^(1 / 2.2)): 423.81, 5270.14, 47823.85, and 65535 at full scale.
  EXPECT_EQ(RunStage(stage, in, 1).planes[0], (std::vector<uint32_t>{424, 5270, 47824, 65535}));
}

TEST(IspGamma, MatchesReferenceOnEveryCode) {
  const GammaConfig configs[] = {
      {GammaCurve::kSrgb, 2.2}, {GammaCurve::kPower, 2.2}, {GammaCurve::kPower, 0.45}};
  for (const GammaConfig& config : configs) {
    StageTables tables;
    const GammaStage stage = MakeGamma(config, tables);
    Image all = MakeImage(256, 256, 1);  // every code once
    for (size_t i = 0; i < all.planes[0].size(); ++i) all.planes[0][i] = static_cast<uint32_t>(i);
    EXPECT_LE(MaxAbsError(RunStage(stage, all, 1), ref::RefGamma(ToRef(all), config)), kGammaMaxErr);
    const Image rgb = RandomImage(19, 7, 3, kMaxQ16, 13);
    EXPECT_LE(MaxAbsError(RunStage(stage, rgb, 3), ref::RefGamma(ToRef(rgb), config)), kGammaMaxErr);
  }
}

// Every entry is the header's definition, round(65535 Curve(i / 65535)) with
// Curve's Pow, ties up, clamped, although Init takes PowFast where it cannot
// change the integer: sRGB, the gamma range's ends and gammas in between.
TEST(IspGamma, TableIsTheRoundedCurveAtEveryCode) {
  const GammaConfig configs[] = {{GammaCurve::kSrgb, 2.2},  {GammaCurve::kPower, 0.1},  {GammaCurve::kPower, 0.45},
                                 {GammaCurve::kPower, 1.0}, {GammaCurve::kPower, 1.8},  {GammaCurve::kPower, 2.2},
                                 {GammaCurve::kPower, 2.4}, {GammaCurve::kPower, 3.7}, {GammaCurve::kPower, 10.0}};
  for (const GammaConfig& config : configs) {
    StageTables tables;
    const GammaStage stage = MakeGamma(config, tables);
    for (size_t i = 0; i < GammaStage::kTableSize; ++i) {
      double t = stage.Curve(static_cast<double>(i) / 65535.0) * 65535.0;
      t = std::clamp(t, 0.0, 65535.0);
      ASSERT_EQ(stage.table()[i], static_cast<uint16_t>(t + 0.5)) << "gamma " << config.gamma << " code " << i;
    }
  }
}

// The gathered lookup (sixteen or eight samples a time) against the table read
// one sample at a time, at every row length up to 40 (every tail after the
// lanes), with the last codes and codes above full scale in every lane.
TEST(IspGamma, RowsAreTheTableAtEveryWidth) {
  StageTables tables;
  const GammaStage stage = MakeGamma({GammaCurve::kSrgb, 2.2}, tables);
  const uint16_t* t = stage.table();
  const uint32_t edge[] = {0, 1, 65534, 65535, 65536, 65537, 0x7FFFFFFFu, 0xFFFFFFFFu};
  for (int width = 1; width <= 40; ++width) {
    Image in = RandomImage(width, 3, 3, kMaxQ16, 7 + width);
    for (std::vector<uint32_t>& plane : in.planes)
      for (size_t i = 0; i < plane.size(); i += 3) plane[i] = edge[(i / 3 + plane.size()) % 8];
    const Image out = RunStage(stage, in, 3);
    for (int c = 0; c < 3; ++c)
      for (size_t i = 0; i < in.planes[c].size(); ++i) {
        const uint32_t code = in.planes[c][i] < 65535 ? in.planes[c][i] : 65535;
        ASSERT_EQ(out.planes[c][i], t[code]) << "width " << width << " channel " << c << " sample " << i;
      }
  }
}

TEST(IspGamma, PlanIdentityTablesAndValidation) {
  GammaStage stage;
  ASSERT_TRUE(stage.Configure(GammaConfig{}, Geometry(4, 4)).ok());
  EXPECT_STREQ(stage.IdentityReason(), "gamma curve is linear");
  ASSERT_TRUE(stage.Configure({GammaCurve::kSrgb, 2.2}, Geometry(4, 4)).ok());
  EXPECT_EQ(stage.IdentityReason(), nullptr);
  const Result<LineFormat> f = stage.Plan(LineFormat{Domain::kLinear, 1, true});
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f.value().domain, Domain::kEncoded);
  EXPECT_TRUE(f.value().mosaic);
  EXPECT_FALSE(stage.Plan(LineFormat{Domain::kDigital, 3, false}).ok());

  WorkspaceCounter counter;
  stage.CountTables(counter);
  EXPECT_EQ(counter.raw_bytes(), AlignUp(65537u * sizeof(uint16_t)));  // one spare entry
  std::vector<uint8_t> small(1000);
  Arena arena(Span<uint8_t>{small.data(), small.size()});
  EXPECT_EQ(stage.Init(arena).code(), StatusCode::kResourceExhausted);

  for (double g : {0.0, -1.0, 0.09, 10.1, kNaN})
    ExpectInvalid(stage.Configure({GammaCurve::kPower, g}, Geometry(4, 4)), "gamma.gamma");
  ExpectInvalid(stage.Configure({static_cast<GammaCurve>(9), 2.2}, Geometry(4, 4)), "gamma.curve");
}

// ---------------------------------------------------------------------------
// Every small frame size through the per-pixel stages (demosaic has its own).

TEST(IspSizes, PointStagesMatchReferencesAtEverySmallSize) {
  StageTables tables;
  const GammaStage gamma = MakeGamma({GammaCurve::kSrgb, 2.2}, tables);
  for (int w : kWidths)
    for (int h : kHeights) {
      SCOPED_TRACE(testing::Message() << w << "x" << h);
      const SensorGeometry g = Geometry(w, h, Cfa::kBayerGR);
      const Image dn = RandomImage(w, h, 1, 4095, static_cast<uint32_t>(w + 100 * h));
      BlackLevelStage black;
      ASSERT_TRUE(black.Configure(BlackLevelConfig{}, g, 64.0).ok());
      const Image linear = RunStage(black, dn, 1);
      EXPECT_LE(MaxAbsError(linear, ref::RefBlackLevel(ToRef(dn), 64.0, 12)), kBlackLevelMaxErr);

      const WhiteBalanceConfig wb{{1.9, 1.0, 1.4}};
      WhiteBalanceStage white;
      const double white_level = WhiteLevel(4002.0, 64.0, 12);
      ASSERT_TRUE(white.Configure(wb, g, white_level).ok());
      EXPECT_LE(MaxAbsError(RunStage(white, linear, 1), ref::RefWhiteBalance(ToRef(linear), g.cfa, wb, white_level)),
                kWhiteBalanceMaxErr);

      const Image rgb = RandomImage(w, h, 3, kMaxQ16, static_cast<uint32_t>(w * h));
      ColorMatrixStage ccm;
      ASSERT_TRUE(ccm.Configure(Matrix({1.5, -0.25, -0.25, -0.125, 1.25, -0.125, 0, -0.5, 1.5}), g).ok());
      EXPECT_LE(MaxAbsError(RunStage(ccm, rgb, 3), ref::RefColorMatrix(ToRef(rgb), Quantised(ccm).data())),
                kColorMatrixMaxErr);

      EXPECT_LE(MaxAbsError(RunStage(gamma, rgb, 3), ref::RefGamma(ToRef(rgb), {GammaCurve::kSrgb, 2.2})),
                kGammaMaxErr);
    }
}

}  // namespace
}  // namespace camsim
