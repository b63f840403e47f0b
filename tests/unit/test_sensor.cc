// The sensor path (exposure, CFA, EMVA 1288 sensor): statistics on flat fields
// follow the model, fixed patterns measure as configured, saturation, Bayer
// phases, and each stage against its double reference.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "core/aperture/exposure.h"
#include "core/base/workspace.h"
#include "core/lens/vignetting.h"
#include "core/pipeline/pipeline.h"
#include "core/sensor/emva.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

// Exposure giving exactly 1000 photons per unit radiance: c = 1000 /ms, 1 ms, f/1.
void ThousandPhotonsPerRadiance(PipelineConfig* c) {
  c->exposure.exposure_time_us = 1000.0;
  c->exposure.f_number = 1.0;
  c->exposure.photons_per_radiance_ms = 1000.0;
}

PipelineConfig SensorOnly(int w, int h, Cfa cfa) {
  PipelineConfig c;
  c.geometry = {w, h, cfa, 12};
  ThousandPhotonsPerRadiance(&c);
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kCfa;
  c.order[2] = StageId::kSensor;
  c.order_count = 3;
  return c;
}

SensorConfig Noiseless() {
  SensorConfig s;
  test::NoiseOff(&s);
  return s;
}

struct Moments {
  double mean = 0, var = 0;
};
Moments Of(const std::vector<double>& v) {
  Moments m;
  for (double x : v) m.mean += x;
  m.mean /= v.size();
  for (double x : v) m.var += (x - m.mean) * (x - m.mean);
  m.var /= (v.size() - 1);
  return m;
}

std::vector<double> AsDouble(const std::vector<uint32_t>& v) { return std::vector<double>(v.begin(), v.end()); }

TEST(Sensor, PhotonTransferFollowsEmva1288) {
  constexpr int kSize = 128;  // 16384 pixels: variance known to ~1.1 % (1 sigma)
  PipelineConfig c = SensorOnly(kSize, kSize, Cfa::kMono);
  c.sensor.dsnu_e = 0;
  c.sensor.prnu_percent = 0;
  c.sensor.dark_current_e_per_s = 0;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const double K = c.sensor.system_gain_dn_per_e, qe = c.sensor.quantum_efficiency[kGreen];
  const double sd = c.sensor.dark_noise_e, bl = c.sensor.black_level_dn;
  for (double radiance : {0.01, 0.5, 2.0, 8.0}) {
    const test::Scene s = test::FlatScene(kSize, kSize, radiance, radiance, radiance);
    const auto a = test::RunFrame(*b, s, 10, 16), bb = test::RunFrame(*b, s, 11, 16);
    std::vector<double> diff(a.size());
    for (size_t i = 0; i < a.size(); ++i) diff[i] = double(a[i]) - double(bb[i]);
    const double mu_e = 1000.0 * radiance * qe;
    const Moments ma = Of(AsDouble(a));
    const double temporal_var = Of(diff).var / 2.0;
    const double expected_var = K * K * (sd * sd + mu_e) + 1.0 / 12.0;
    EXPECT_NEAR(ma.mean - bl, K * mu_e, 0.02 * K * mu_e + 0.05) << "radiance " << radiance;
    // 5 % covers 4 sigma of the variance estimate.
    EXPECT_NEAR(temporal_var, expected_var, 0.05 * expected_var) << "radiance " << radiance;
    RecordProperty("ptc_mu_e_" + std::to_string(mu_e), "mean " + std::to_string(ma.mean - bl) + " (model " +
                                                           std::to_string(K * mu_e) + "), var " +
                                                           std::to_string(temporal_var) + " (model " +
                                                           std::to_string(expected_var) + ")");
  }
}

TEST(Sensor, DsnuAndPrnuMeasureAsConfigured) {
  constexpr int kSize = 96, kFrames = 16;
  PipelineConfig c = SensorOnly(kSize, kSize, Cfa::kMono);
  c.sensor.dsnu_e = 8.0;
  c.sensor.prnu_percent = 2.0;
  c.sensor.dark_noise_e = 2.0;
  c.sensor.dark_current_e_per_s = 0;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const double K = c.sensor.system_gain_dn_per_e, qe = c.sensor.quantum_efficiency[kGreen];
  // EMVA 1288: spatial variance of the frame average minus the temporal share.
  auto spatial_var = [&](double radiance, double* mean) {
    const test::Scene s = test::FlatScene(kSize, kSize, radiance, radiance, radiance);
    std::vector<double> avg(kSize * kSize, 0.0);
    std::vector<uint32_t> f0, f1;
    for (int f = 0; f < kFrames; ++f) {
      const auto img = test::RunFrame(*b, s, static_cast<uint32_t>(f), 32);
      if (f == 0) f0 = img;
      if (f == 1) f1 = img;
      for (size_t i = 0; i < img.size(); ++i) avg[i] += img[i] / double(kFrames);
    }
    std::vector<double> diff(f0.size());
    for (size_t i = 0; i < f0.size(); ++i) diff[i] = double(f0[i]) - double(f1[i]);
    const double temporal = Of(diff).var / 2.0;
    const Moments m = Of(avg);
    *mean = m.mean;
    return m.var - temporal / kFrames;
  };
  double dark_mean = 0, bright_mean = 0;
  const double dsnu_dn = std::sqrt(spatial_var(0.0, &dark_mean));
  EXPECT_NEAR(dsnu_dn / K, 8.0, 0.8);  // 10 %: 9216 pixels
  const double mu_e = 1000.0 * 6.0 * qe;
  const double bright_spatial = spatial_var(6.0, &bright_mean);
  const double prnu = std::sqrt(bright_spatial - dsnu_dn * dsnu_dn) / (bright_mean - dark_mean);
  EXPECT_NEAR(prnu, 0.02, 0.002);
  RecordProperty("dsnu_e_measured", std::to_string(dsnu_dn / K));
  RecordProperty("prnu_measured", std::to_string(prnu));
  EXPECT_NEAR((bright_mean - dark_mean) / K, mu_e, 0.01 * mu_e);
}

TEST(Sensor, FixedPatternsAreTheSameEveryFrame) {
  PipelineConfig c = SensorOnly(32, 32, Cfa::kMono);
  c.sensor = Noiseless();
  c.sensor.dsnu_e = 5.0;
  c.sensor.prnu_percent = 3.0;
  auto b = test::Build(c);
  const test::Scene s = test::FlatScene(32, 32, 2.0, 2.0, 2.0);
  const auto f0 = test::RunFrame(*b, s, 0, 32);
  EXPECT_EQ(test::RunFrame(*b, s, 7, 32), f0);   // no temporal noise: identical
  const Moments m = Of(AsDouble(f0));
  EXPECT_GT(m.var, 1.0);  // but not flat: a pattern exists
  // Keyed by the seed: another seed, another pattern (over 1024 pixels most differ).
  c.seed = 2;
  auto other = test::Build(c);
  const auto g0 = test::RunFrame(*other, s, 0, 32);
  ASSERT_EQ(g0.size(), f0.size());
  size_t differ = 0;
  for (size_t i = 0; i < f0.size(); ++i) differ += f0[i] != g0[i];
  EXPECT_GT(differ, f0.size() / 2);
}

// Dark charge is drawn with the signal (Poisson): in a dark frame its
// temporal variance equals its mean, in electrons. 10 000 e-/s for 10 ms
// is 100 e-; over 64 x 64 pixels the variance is within ~5 % of it (charge
// added after the draw would leave only the quantisation, 1/12 DN^2).
TEST(Sensor, DarkChargeCarriesItsShotNoise) {
  PipelineConfig c = SensorOnly(64, 64, Cfa::kMono);
  c.exposure.exposure_time_us = 10000.0;
  c.sensor = Noiseless();
  c.sensor.shot_noise = true;
  c.sensor.dark_current_e_per_s = 10000.0;
  c.sensor.system_gain_dn_per_e = 1.0;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const test::Scene dark = test::FlatScene(64, 64, 0.0, 0.0, 0.0);
  const Moments m = Of(AsDouble(test::RunFrame(*b, dark, 0, 64)));
  EXPECT_NEAR(m.mean - c.sensor.black_level_dn, 100.0, 1.0);
  EXPECT_NEAR(m.var, 100.0, 15.0);
}

// Each fixed pattern (DSNU, PRNU, row and column FPN, the seeded defect
// map) is the same every frame but another camera's, another seed, has its
// own: a frame of seed 2 differs from seed 1's in most pixels, for each
// pattern on its own.
TEST(Sensor, FixedPatternsFollowTheSeed) {
  const test::Scene s = test::FlatScene(32, 32, 2.0, 2.0, 2.0);
  const auto differing = [&](void (*set)(SensorConfig*)) {
    PipelineConfig c = SensorOnly(32, 32, Cfa::kMono);
    c.sensor = Noiseless();
    set(&c.sensor);
    auto one = test::Build(c);
    c.seed = 2;
    auto two = test::Build(c);
    const auto a = test::RunFrame(*one, s, 0, 32), b = test::RunFrame(*two, s, 0, 32);
    EXPECT_EQ(test::RunFrame(*one, s, 5, 32), a) << "fixed over frames";
    int n = 0;
    for (size_t i = 0; i < a.size(); ++i) n += a[i] != b[i];
    return n;
  };
  EXPECT_GT(differing([](SensorConfig* sc) { sc->dsnu_e = 5.0; }), 32 * 32 / 2) << "DSNU";
  EXPECT_GT(differing([](SensorConfig* sc) { sc->prnu_percent = 3.0; }), 32 * 32 / 2) << "PRNU";
  EXPECT_GT(differing([](SensorConfig* sc) { sc->row_fpn_e = 5.0; }), 32 * 32 / 2) << "row FPN";
  EXPECT_GT(differing([](SensorConfig* sc) { sc->column_fpn_e = 5.0; }), 32 * 32 / 2) << "column FPN";
  // 1 % of the pixels hot in each map (about 10 of 1024), almost none shared:
  // about 20 pixels differ.
  EXPECT_GT(differing([](SensorConfig* sc) { sc->hot_pixel_fraction = 0.01; }), 10) << "hot pixels";
}

// sensor.fixed_pattern_table builds PRNU and DSNU once at Init: the same bytes
// as drawing them every frame (Bayer: one channel; no CFA: three), for odd
// sizes, several strip heights and threads, with noise and defects on; the
// workspace grows by 8 bytes per pixel and channel (plus alignment).
TEST(Sensor, FixedPatternTableGivesTheSameBytes) {
  const int w = 37, h = 23;  // odd: a last pixel pair with one pixel
  const test::Scene s = test::TexturedScene(w, h);
  for (const bool mosaic : {true, false}) {
    PipelineConfig c = SensorOnly(w, h, Cfa::kBayerGR);
    if (!mosaic) {
      c.order[1] = StageId::kSensor;
      c.order_count = 2;
    }
    c.sensor.dsnu_e = 4.0;
    c.sensor.prnu_percent = 2.0;
    c.sensor.hot_pixel_fraction = 0.01;
    c.sensor.stuck_pixel_fraction = 0.01;
    auto drawn = test::Build(c, 2);
    ASSERT_TRUE(drawn->status.ok()) << drawn->status.message();
    c.sensor.fixed_pattern_table = true;
    auto table = test::Build(c, 2);
    ASSERT_TRUE(table->status.ok()) << table->status.message();
    const size_t channels = mosaic ? 1 : 3, grown = table->pipeline.TableBytes() - drawn->pipeline.TableBytes();
    EXPECT_GE(grown, channels * w * h * 8) << "mosaic " << mosaic;
    EXPECT_LT(grown, channels * w * h * 8 + 64) << "at most the workspace's 64-byte alignment more";
    for (const uint32_t frame : {0u, 5u}) {
      const auto want = test::RunFrame(*drawn, s, frame, h);
      EXPECT_EQ(test::RunFrame(*table, s, frame, h), want) << "mosaic " << mosaic << " frame " << frame;
      EXPECT_EQ(test::RunFrame(*table, s, frame, 1), want);
      EXPECT_EQ(test::RunFrameThreads(*table, s, frame, 5, 2), want);
    }
  }
  // Without PRNU and DSNU there is nothing to store.
  PipelineConfig off = SensorOnly(w, h, Cfa::kBayerGR);
  off.sensor.dsnu_e = 0.0;
  off.sensor.prnu_percent = 0.0;
  auto a = test::Build(off);
  off.sensor.fixed_pattern_table = true;
  auto b = test::Build(off);
  EXPECT_EQ(a->pipeline.TableBytes(), b->pipeline.TableBytes());
}

// Which of the sensor's code paths runs the pixels that lanes may take.
enum class SensorPath { kPortable, kAvx2, kWidest };

// The sensor stage run directly on channel planes (channels x h x w of
// photons, Q24.8): output planes, then the electron sums per colour.
std::vector<int64_t> RunSensorDirect(const SensorStage& s, const std::vector<uint32_t>& photons, int w, int h,
                                     int channels, uint32_t frame, const FrameInput* input, SensorPath path) {
  const_cast<SensorStage&>(s).ForcePortablePathForTest(path == SensorPath::kPortable);
  const_cast<SensorStage&>(s).ForceAvx2PathForTest(path == SensorPath::kAvx2);
  std::vector<uint32_t> out(photons.size(), 0xDEADBEEFu);
  StageStats stats;
  for (int y = 0; y < h; ++y) {
    RowIn row;
    RowArgs a;
    for (int c = 0; c < channels; ++c) {
      row.ch[c] = photons.data() + (static_cast<size_t>(c) * h + y) * w;
      a.out[c] = out.data() + (static_cast<size_t>(c) * h + y) * w;
    }
    a.y = y;
    a.width = w;
    a.frame = frame;
    a.rows = &row;
    a.first_row = y;
    a.row_count = 1;
    a.input = input;
    a.stats = &stats;
    s.ProcessRow(a);
  }
  const_cast<SensorStage&>(s).ForcePortablePathForTest(false);
  const_cast<SensorStage&>(s).ForceAvx2PathForTest(false);
  std::vector<int64_t> result(out.begin(), out.end());
  result.insert(result.end(), std::begin(stats.aux_sum), std::end(stats.aux_sum));
  return result;
}

// Passes 1 and 3 in AVX2 lanes (x86-64 with AVX2) give the portable loops'
// bytes and electron sums: photons from 0 to 2^32 - 1 on a log scale (below
// 12 e-, where Poisson is the inverse transform, up to far beyond the full
// well), drawn and tabled fixed patterns with PRNU large enough to clamp the
// gain at 0, row and column FPN, smear, no shot noise, a gain and read noise
// that push the output below 0 and above the ADC range, mosaic and 3-channel
// sensors, widths that leave 1 to 3 pixels after the last group of four or
// end a block on a masked group of four at any of AVX-512's positions (44,
// 60: 12 and 28 pixels), a listed defect (its row goes the portable way),
// and seeded defects (a block's lanes stop before its first defect pixel),
// also with stored patterns, FPN and smear on a 3-channel sensor; DCNU drawn
// and stored, at 100 % (gains clamped at 0 and up to 7.3) with a dark charge
// near the 1e6 e- limit, and with hot and dead pixels. Both SIMD tiers: the
// AVX2 lanes also where the CPU has AVX-512 (ForceAvx2PathForTest).
TEST(Sensor, LanesGiveThePortableBytes) {
  CAMSIM_SKIP_WITHOUT_LANE_KERNELS();
  const int h = 9;
  std::mt19937 rng(5);
  const DefectPixel listed[] = {{3, 4, DefectKind::kHot, -1.0}};
  for (int variant = 0; variant < 12; ++variant)
    for (const int w : {37, 70, 67, 44, 60}) {
      SensorConfig c;
      c.prnu_percent = 2.0;
      c.dsnu_e = 3.0;
      if (variant == 1) c.fixed_pattern_table = true;
      if (variant == 2)
        c.row_fpn_e = 40.0, c.column_fpn_e = 25.0, c.smear_row_transfer_us = 1.0, c.black_level_dn = 14.7;
      if (variant == 3) c.shot_noise = false, c.prnu_percent = 50.0;
      if (variant == 4) c.gain_db = 30.0, c.dark_noise_e = 900.0, c.black_level_dn = 0.0;
      if (variant == 5) c.prnu_percent = 50.0, c.fixed_pattern_table = true, c.full_well_e = 1e6;
      if (variant == 6) c.defects = listed, c.defect_count = 1;
      if (variant == 7) c.hot_pixel_fraction = c.dead_pixel_fraction = c.stuck_pixel_fraction = 0.01;
      if (variant == 8)
        c.hot_pixel_fraction = c.dead_pixel_fraction = c.stuck_pixel_fraction = 0.003, c.fixed_pattern_table = true,
        c.row_fpn_e = 40.0, c.column_fpn_e = 25.0, c.smear_row_transfer_us = 1.0;
      if (variant == 9)  // 1e6 e-/s x 2^(68 / 7) x 1 ms: 8.4e5 e-, near the 1e6 e- limit
        c.dcnu_percent = 100.0, c.dark_current_e_per_s = 1e6, c.temperature_c = c.dark_current_ref_c + 68.0;
      if (variant == 10)
        c.dcnu_percent = 37.0, c.dark_current_e_per_s = 1e6, c.fixed_pattern_table = true,
        c.smear_row_transfer_us = 1.0;
      if (variant == 11)
        c.dcnu_percent = 60.0, c.dark_current_e_per_s = 5e4, c.hot_pixel_fraction = c.dead_pixel_fraction = 0.01,
        c.prnu_percent = 0.0, c.dsnu_e = 0.0;
      const int channels = variant == 5 || variant == 8 || variant == 10 ? 3 : 1;
      SensorStage s;
      ASSERT_TRUE(s.Configure(c, SensorGeometry{w, h, Cfa::kBayerGB, 12}, 1000.0, 99).ok()) << variant;
      s.SetInputChannels(channels);
      WorkspaceCounter counter;
      s.CountTables(counter);
      std::vector<uint8_t> tables(counter.bytes());
      Arena arena(Span<uint8_t>{tables.data(), tables.size()});
      ASSERT_TRUE(s.Init(arena).ok()) << variant;
      std::vector<uint32_t> photons(static_cast<size_t>(channels) * w * h);
      for (uint32_t& p : photons) p = rng() >> (rng() % 33 == 32 ? 0 : rng() % 32);
      for (size_t i = 0; i < photons.size(); i += 13) photons[i] = i % 2 ? 0xFFFFFFFFu : 0u;
      std::vector<uint32_t> smear(static_cast<size_t>(kMaxChannels) * w);
      for (uint32_t& e : smear) e = rng() % 4 == 0 ? 0xFFFFFFFFu : rng() >> (rng() % 32);  // some saturate the charge
      FrameInput input;
      input.smear_e = smear.data();
      for (const uint32_t frame : {0u, 3u}) {
        const auto want = RunSensorDirect(s, photons, w, h, channels, frame, &input, SensorPath::kPortable);
        EXPECT_EQ(RunSensorDirect(s, photons, w, h, channels, frame, &input, SensorPath::kWidest), want)
            << "variant " << variant << " width " << w << " frame " << frame;
        EXPECT_EQ(RunSensorDirect(s, photons, w, h, channels, frame, &input, SensorPath::kAvx2), want)
            << "AVX2 lanes: variant " << variant << " width " << w << " frame " << frame;
      }
    }
}

TEST(Sensor, SaturatesAtFullWellAndAdcMax) {
  PipelineConfig c = SensorOnly(16, 16, Cfa::kBayerRG);
  c.sensor = Noiseless();
  auto b = test::Build(c);
  const test::Scene s = test::FlatScene(16, 16, 1000.0, 1000.0, 1000.0);  // 1e6 photons
  // K * full well = 0.375 * 10500 = 3937.5 -> 3938 (ties up), + black level 64.
  for (uint32_t v : test::RunFrame(*b, s, 0, 16)) ASSERT_EQ(v, 4002u);
  c.sensor.shot_noise = true;  // Poisson of a huge mean is still clipped at the full well
  auto noisy = test::Build(c);
  for (uint32_t v : test::RunFrame(*noisy, s, 0, 16)) ASSERT_EQ(v, 4002u);
  c.sensor.gain_db = 12.0;  // K * 3.98: past the ADC's 4095
  auto gained = test::Build(c);
  for (uint32_t v : test::RunFrame(*gained, s, 0, 16)) ASSERT_EQ(v, 4095u);
}

// SensorSaturationDn (the white balance's highlight clip) is the level a full
// pixel reads, also where K W + black level lies near a tie: the stage rounds
// K to a 32-bit mantissa and W to Q24.8. (A double formula gave 27487 here
// where the stage reads 27486.)
TEST(Sensor, SaturationDnIsWhatAFullPixelReads) {
  struct Case {
    double full_well_e, k, black_dn;
  };
  std::vector<Case> cases = {{337.857, 81.03, 111.0}};
  for (int i = 0; i < 40; ++i)  // more, spread over the ranges
    cases.push_back({100.0 + 997.3 * i + 0.129 * i * i, 0.05 + 0.61 * (i % 13) + 0.0037 * i, 7.25 * (i % 9)});
  const test::Scene s = test::FlatScene(4, 4, 1e4, 1e4, 1e4);  // 1e7 photons: past every well
  for (const Case& k : cases) {
    PipelineConfig c = SensorOnly(4, 4, Cfa::kBayerRG);
    c.geometry.adc_bits = 16;
    c.sensor = Noiseless();
    c.sensor.full_well_e = k.full_well_e;
    c.sensor.system_gain_dn_per_e = k.k;
    c.sensor.black_level_dn = k.black_dn;
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const double want = SensorSaturationDn(c.sensor, c.geometry);
    for (uint32_t v : test::RunFrame(*b, s, 0, 4))
      ASSERT_EQ(v, want) << "W " << k.full_well_e << " K " << k.k << " black " << k.black_dn;
  }
}

TEST(Sensor, BayerPhasePutsEachColourOnItsSites) {
  for (Cfa cfa : {Cfa::kBayerRG, Cfa::kBayerGR, Cfa::kBayerGB, Cfa::kBayerBG}) {
    for (int colour = 0; colour < 3; ++colour) {
      PipelineConfig c = SensorOnly(8, 6, cfa);
      c.sensor = Noiseless();
      c.sensor.black_level_dn = 0;
      auto b = test::Build(c);
      ASSERT_TRUE(b->status.ok());
      const double rgb[3] = {colour == 0 ? 1.0 : 0.0, colour == 1 ? 1.0 : 0.0, colour == 2 ? 1.0 : 0.0};
      const auto out = test::RunFrame(*b, test::FlatScene(8, 6, rgb[0], rgb[1], rgb[2]), 0, 6);
      for (int y = 0; y < 6; ++y)
        for (int x = 0; x < 8; ++x) {
          const uint32_t v = out[y * 8 + x];
          if (CfaColour(cfa, x, y) == colour) {
            EXPECT_GT(v, 100u) << CfaName(cfa) << " " << x << "," << y;
          } else {
            EXPECT_EQ(v, 0u) << CfaName(cfa) << " " << x << "," << y;
          }
        }
    }
  }
  // The names: BayerRG starts R G / G B; BayerBG is the paper's eq. 20-22 (blue at 0,0).
  EXPECT_EQ(CfaColour(Cfa::kBayerRG, 0, 0), kRed);
  EXPECT_EQ(CfaColour(Cfa::kBayerRG, 1, 1), kBlue);
  EXPECT_EQ(CfaColour(Cfa::kBayerBG, 0, 0), kBlue);
  EXPECT_EQ(CfaColour(Cfa::kBayerBG, 1, 1), kRed);
  EXPECT_EQ(CfaColour(Cfa::kBayerGR, 1, 0), kRed);
  EXPECT_EQ(CfaColour(Cfa::kBayerGB, 0, 1), kRed);
}

// Mono weights sum to exactly 1 in Q0.16 however R and B round: here both
// round a half up (32767.5 and 32768.5), which once left G at 2^32 - 1.
TEST(Cfa, MonoWeightsNeverLeaveGreyOrWrapGreen) {
  CfaConfig c;
  c.mono_weights[0] = 65535.0 / 131072.0;
  c.mono_weights[1] = 0.0;
  c.mono_weights[2] = 65537.0 / 131072.0;
  CfaStage s;
  ASSERT_TRUE(s.Configure(c, SensorGeometry{4, 1, Cfa::kMono, 12}).ok());
  const uint32_t grey[4] = {0, 1000, 123456, 0xFFFFFFFFu};
  const uint32_t none[4] = {0, 0, 0, 0};
  uint32_t out[4];
  RowIn in;
  RowArgs a;
  a.width = 4;
  a.rows = &in;
  a.row_count = 1;
  a.out[0] = out;
  in.ch[0] = in.ch[1] = in.ch[2] = grey;
  s.ProcessRow(a);
  for (int x = 0; x < 4; ++x) EXPECT_EQ(out[x], grey[x]) << "grey " << x;
  in.ch[0] = in.ch[2] = none;  // green alone: its weight is 0
  s.ProcessRow(a);
  for (int x = 0; x < 4; ++x) EXPECT_EQ(out[x], 0u) << "green " << x;
  // One colour alone (a weight of exactly 1) passes exactly; the others give 0.
  for (int only = 0; only < 3; ++only) {
    SCOPED_TRACE(only);
    CfaConfig one;
    for (int k = 0; k < 3; ++k) one.mono_weights[k] = k == only ? 1.0 : 0.0;
    ASSERT_TRUE(s.Configure(one, SensorGeometry{4, 1, Cfa::kMono, 12}).ok());
    for (int k = 0; k < 3; ++k) in.ch[k] = k == only ? grey : none;
    s.ProcessRow(a);
    for (int x = 0; x < 4; ++x) EXPECT_EQ(out[x], grey[x]) << "the weighted colour " << x;
    for (int k = 0; k < 3; ++k) in.ch[k] = k == only ? none : grey;
    s.ProcessRow(a);
    for (int x = 0; x < 4; ++x) EXPECT_EQ(out[x], 0u) << "the others " << x;
  }
}

// Bounds of each stage against its double reference (stated, then measured).
constexpr double kExposureMaxErrorPhotons = 0.5 / 256 + 1e-6;  // one Q24.8 rounding (+ factor rounding)
// The sensor's: one final rounding, plus K times the charge's errors: QE in
// Q1.16 (at most 2^-17 of the photons) and three Q.8 roundings (photons, mean,
// dark charge; 2^-9 e- each).
double SensorMaxErrorDn(const SensorConfig& s, double photons) {
  const double k = s.system_gain_dn_per_e * std::pow(10.0, s.gain_db / 20.0);
  return 0.5 + k * (photons * 0x1p-17 + 3 * 0x1p-9) + 1e-9;
}

TEST(Sensor, ExposureMatchesReference) {
  ExposureConfig e;
  e.exposure_time_us = 12345.0;
  e.f_number = 4.0;
  ExposureStage st;
  ASSERT_TRUE(st.Configure(e).ok());
  double worst = 0;
  for (double r : {0.0, 1e-4, 0.01, 0.18, 1.0, 3.14159, 400.0}) {
    const uint32_t in = Q<16, 16>::FromDouble(r).raw;
    const double fixed = st.factor().Apply(in) / 256.0;
    const double ref = ReferenceExposure(e, in / 65536.0);
    worst = std::max(worst, std::abs(fixed - ref));
    EXPECT_NEAR(fixed, ref, kExposureMaxErrorPhotons + ref * 1e-9) << r;
  }
  RecordProperty("exposure_max_error_photons", std::to_string(worst));
  // The reference is the stage's own model function: check it against eq. 7
  // written out (photons = radiance c t / N^2, t in ms).
  EXPECT_DOUBLE_EQ(ReferenceExposure(e, 0.5), 0.5 * 8000.0 * 12.345 / 16.0);
}

// A fractional black level is part of the one rounding (round(K v + BL)), not
// rounded on its own: that would bias every mean by round(BL) - BL.
TEST(Sensor, NoiselessSensorMatchesReference) {
  double worst = 0;
  for (const double black : {64.0, 14.7, 3.5, 0.25}) {
    PipelineConfig c = SensorOnly(64, 1, Cfa::kBayerGB);
    c.sensor = Noiseless();
    c.sensor.dark_current_e_per_s = 50.0;
    c.sensor.temperature_c = c.sensor.dark_current_ref_c + 2 * c.sensor.dark_current_doubling_c;  // x4
    c.sensor.gain_db = 6.0;
    c.sensor.black_level_dn = black;
    c.exposure.exposure_time_us = 100000.0;  // dark charge 50 e-/s x 4 x 0.1 s = 20 e-
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok());
    // Signals from 0 to past the ADC's clip (most pixels below it), so the
    // gain, the dark charge and the black level all show in the means.
    const double photons_per_radiance = ReferenceExposure(c.exposure, 1.0);
    test::Scene s = test::FlatScene(64, 1, 0, 0, 0);
    for (int x = 0; x < 64; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        const double electrons = (x + 0.3 * ch) * 90.0;  // 0 .. ~5700 e-
        const double photons = electrons / c.sensor.quantum_efficiency[ch];
        s.plane[ch][x] = static_cast<uint32_t>(std::lround(photons / photons_per_radiance * 65536.0));
      }
    const auto out = test::RunFrame(*b, s, 0, 1);
    int unclipped = 0;
    for (int x = 0; x < 64; ++x) {
      const Colour col = CfaColour(c.geometry.cfa, x, 0);
      const double photons = ReferenceExposure(c.exposure, s.plane[col][x] / 65536.0);
      const double ref = ReferenceSensorMeanDn(c.sensor, c.geometry, c.exposure.exposure_time_us, col, photons);
      // The reference's model written out here with libm: the gain in dB,
      // the dark current doubling with temperature, the well, the ADC.
      const double k = c.sensor.system_gain_dn_per_e * std::pow(10.0, 6.0 / 20.0);
      const double dark = 50.0 * 0.1 * std::exp2(2.0);
      const double e = std::min(c.sensor.full_well_e, photons * c.sensor.quantum_efficiency[col] + dark);
      const double model = std::clamp(k * e + black, 0.0, 4095.0);
      ASSERT_NEAR(ref, model, 1e-9 * std::max(1.0, model)) << "x " << x << ": the reference's model";
      unclipped += model < 4095.0 ? 1 : 0;
      worst = std::max(worst, std::abs(out[x] - ref));
      EXPECT_NEAR(out[x], ref, SensorMaxErrorDn(c.sensor, photons)) << "x " << x << ", black level " << black;
    }
    EXPECT_GE(unclipped, 48) << "the test's signals should mostly stay below the clip";
  }
  RecordProperty("sensor_max_error_dn", std::to_string(worst));
}

TEST(Sensor, VignettingMatchesReference) {
  for (VignettingMode mode : {VignettingMode::kCos4, VignettingMode::kTable}) {
    PipelineConfig c;
    c.geometry = {97, 61, Cfa::kBayerRG, 12};
    c.vignetting.mode = mode;
    c.vignetting.focal_length_px = 60.0;  // strong fall-off: corner gain ~0.4
    const double table[5] = {1.0, 0.95, 0.8, 0.6, 0.3};
    for (int i = 0; i < 5; ++i) c.vignetting.table[i] = table[i];
    c.vignetting.table_count = 5;
    ThousandPhotonsPerRadiance(&c);
    c.order[0] = StageId::kExposure;
    c.order[1] = StageId::kVignetting;
    c.order_count = 2;
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const test::Scene s = test::FlatScene(97, 61, 10.0, 10.0, 10.0);  // 10 000 photons
    const auto out = test::RunFrame(*b, s, 0, 61);
    double worst = 0;
    for (int y = 0; y < 61; ++y)
      for (int x = 0; x < 97; ++x) {
        const double ref = 10000.0 * ReferenceVignettingGain(c.vignetting, c.geometry, x, y);
        const double got = out[(y * 97 + x) * 3] / 256.0;
        worst = std::max(worst, std::abs(got - ref));
      }
    // Gain quantised to Q2.14 and the 257-point curve: relative 1e-4 of 10 000 photons.
    EXPECT_LT(worst, 1.0) << int(mode);
    RecordProperty(mode == VignettingMode::kCos4 ? "vignetting_cos4_max_error_photons" : "vignetting_table_max_error_photons",
                   std::to_string(worst));
    // Corners are exactly the curve's end point, the centre exactly 1.
    EXPECT_NEAR(out[0] / 256.0, 10000.0 * ReferenceVignettingGain(c.vignetting, c.geometry, 0, 0), 1.0);
    EXPECT_EQ(out[(30 * 97 + 48) * 3], 10000u * 256u);
  }
  // The reference shares the stage's model functions: check it against the
  // models written out. Cos4: cos^4 of the field angle atan(r / f), r the
  // pixel's distance from the centre (48, 30). Table: linear in rho between
  // the 5 given gains, rho the squared radius over the corner's (48^2 + 30^2).
  VignettingConfig v;
  v.mode = VignettingMode::kCos4;
  v.focal_length_px = 60.0;
  const SensorGeometry g{97, 61, Cfa::kBayerRG, 12};
  for (const auto& [x, y] : {std::pair{0, 0}, {48, 30}, {96, 60}, {10, 45}, {70, 3}}) {
    const double r = std::hypot(x - 48.0, y - 30.0);
    EXPECT_NEAR(ReferenceVignettingGain(v, g, x, y), std::pow(std::cos(std::atan(r / 60.0)), 4), 1e-12) << x << "," << y;
  }
  v.mode = VignettingMode::kTable;
  const double table[5] = {1.0, 0.95, 0.8, 0.6, 0.3};
  for (int i = 0; i < 5; ++i) v.table[i] = table[i];
  v.table_count = 5;
  for (const auto& [x, y] : {std::pair{0, 0}, {48, 30}, {10, 45}, {70, 3}}) {
    const double rho = ((x - 48.0) * (x - 48.0) + (y - 30.0) * (y - 30.0)) / (48.0 * 48.0 + 30.0 * 30.0);
    const int i = std::min(static_cast<int>(rho * 4), 3);
    const double want = table[i] + (table[i + 1] - table[i]) * (rho * 4 - i);
    EXPECT_NEAR(ReferenceVignettingGain(v, g, x, y), want, 1e-12) << x << "," << y;
  }
}

TEST(Sensor, VignettingMaskMultipliesEachPixel) {
  PipelineConfig c;
  c.geometry = {8, 4, Cfa::kBayerRG, 12};
  c.vignetting.mode = VignettingMode::kMask;
  ThousandPhotonsPerRadiance(&c);
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kVignetting;
  c.order_count = 2;
  Pipeline p;
  ASSERT_FALSE(p.Configure(c, 1, false).ok());  // mask mode without a mask
  ASSERT_TRUE(p.Configure(c, 1, true).ok());
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  ASSERT_TRUE(p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok());
  test::Scene s = test::FlatScene(8, 4, 1.0, 1.0, 1.0);  // 1000 photons = 256000 in Q24.8
  std::vector<uint16_t> mask(32);
  for (int i = 0; i < 32; ++i) mask[i] = static_cast<uint16_t>(i * 512);  // Q2.14: i / 32
  FrameInput in = s.View();
  in.vignetting_mask = MakeImageView<const uint16_t>(mask.data(), 8, 4);
  ASSERT_TRUE(p.CheckInput(in).ok());
  std::vector<uint32_t> out(32 * 3);
  Tap t;
  t.format = TapFormat::kU32;
  t.data = out.data();
  t.stride = 8 * 3;
  p.ProcessFrame(in, 0, 4, &t, 1, nullptr, nullptr);
  for (int i = 0; i < 32; ++i) EXPECT_EQ(out[i * 3 + 1], 256000u * i / 32) << i;  // exact: i/32 is dyadic
}

}  // namespace
}  // namespace camsim
