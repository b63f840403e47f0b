// Dark current non-uniformity (SensorConfig::dcnu_percent, core/sensor/emva.h):
// each pixel's dark current is the mean times max(0, 1 + dcnu z4), z4 a
// fixed-pattern normal of its own stream. Its spatial spread in a dark frame,
// its growth with exposure time and temperature, that it is fixed and
// follows the seed, the stored table's bytes, the reference's moments, and
// the configuration's range check.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/pipeline/pipeline.h"
#include "core/sensor/emva.h"
#include "host_tools/config.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

constexpr int kSide = 256;  // 65 536 pixels per statistic

// A mono kSide x kSide dark frame's path: every random term off except DCNU
// (no shot noise: a single frame is the fixed pattern itself), K = 0.5 DN/e-,
// black level 64 DN, 2e5 e-/s of dark current: 2000 e- in 10 ms.
PipelineConfig DarkPath(double dcnu_percent, double exposure_us) {
  PipelineConfig c = test::MonoSensorPath(kSide, kSide);
  test::NoiseOff(&c.sensor);
  c.sensor.system_gain_dn_per_e = 0.5;
  c.sensor.dark_current_e_per_s = 2e5;
  c.sensor.dcnu_percent = dcnu_percent;
  c.exposure.exposure_time_us = exposure_us;
  c.seed = 3;
  return c;
}

std::vector<uint32_t> DarkFrame(const PipelineConfig& c, uint32_t frame = 0) {
  auto b = test::Build(c);
  EXPECT_TRUE(b->status.ok()) << b->status.message();
  if (!b->status.ok()) return {};
  return test::RunFrame(*b, test::FlatScene(c.geometry.width, c.geometry.height, 0, 0, 0), frame,
                        c.geometry.height);
}

struct Spatial {
  double mean = 0, sd = 0;
};
// Mean and standard deviation of (DN - black level) / K, electrons.
Spatial Electrons(const std::vector<uint32_t>& dn, const SensorConfig& s) {
  Spatial r;
  for (uint32_t v : dn) r.mean += (v - s.black_level_dn) / s.system_gain_dn_per_e;
  r.mean /= static_cast<double>(dn.size());
  double ss = 0;
  for (uint32_t v : dn) {
    const double d = (v - s.black_level_dn) / s.system_gain_dn_per_e - r.mean;
    ss += d * d;
  }
  r.sd = std::sqrt(ss / static_cast<double>(dn.size() - 1));
  return r;
}

// Pearson correlation of two frames.
double Correlation(const std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
  double ma = 0, mb = 0;
  for (size_t i = 0; i < a.size(); ++i) ma += a[i], mb += b[i];
  ma /= static_cast<double>(a.size());
  mb /= static_cast<double>(b.size());
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

// The dark signal's spatial spread is dark_e * dcnu, and doubles with the
// exposure time (2000 e- in 10 ms, 4000 e- in 20 ms; 5 % DCNU: 100 and 200 e-).
// Tolerance: the sample standard deviation of N = 65 536 normals has a
// relative standard error of 1 / sqrt(2 (N - 1)) = 0.28 %; 4 of those is
// 1.1 %. The other errors are far below that: the Gaussian table's 2.5e-5
// in z, dcnu 0.05 as Q.16 (3277 / 65536: +6e-5 relative), the gain's and the
// charge's roundings (< 1 e- on 100 e-, uncorrelated with z), and the ADC's
// quantisation (1/12 DN^2 = 0.33 e-^2 against 1e4 e-^2). At 5 % no gain is
// clamped (that starts at 15.7 %), so the spread is exactly dark_e * dcnu.
// Without DCNU (the old model) the frame is flat: sd 0.
// The ratio of the two spreads, and every pixel's charge, are those of the
// exposure times: the same z4 scales (pixel by pixel within 3 e-: half a DN
// of rounding in each frame, 1 e- at K = 0.5, doubled for the short one).
TEST(SensorDcnu, DarkSpreadIsDarkChargeTimesDcnuAndGrowsWithExposure) {
  const PipelineConfig short_c = DarkPath(5.0, 10000.0), long_c = DarkPath(5.0, 20000.0);
  const auto short_f = DarkFrame(short_c), long_f = DarkFrame(long_c);
  ASSERT_EQ(short_f.size(), static_cast<size_t>(kSide) * kSide);
  ASSERT_EQ(long_f.size(), short_f.size());
  const Spatial s = Electrons(short_f, short_c.sensor), l = Electrons(long_f, long_c.sensor);
  EXPECT_NEAR(s.mean, 2000.0, 2000.0 * 0.05 * 4 / kSide) << "mean: 4 standard errors of it";
  EXPECT_NEAR(l.mean, 4000.0, 4000.0 * 0.05 * 4 / kSide);
  EXPECT_NEAR(s.sd, 100.0, 1.1) << "dark_e * dcnu at 10 ms";
  EXPECT_NEAR(l.sd, 200.0, 2.2) << "dark_e * dcnu at 20 ms";
  EXPECT_NEAR(l.sd / s.sd, 2.0, 1e-3) << "linear in the exposure time";
  int off = 0;
  for (size_t i = 0; i < short_f.size(); ++i) {
    const double e_short = (short_f[i] - 64.0) / 0.5, e_long = (long_f[i] - 64.0) / 0.5;
    off += std::abs(e_long - 2.0 * e_short) > 3.1;
  }
  EXPECT_EQ(off, 0) << "each pixel's dark charge doubles with the exposure time";
  RecordProperty("dcnu_sd_10ms_e", std::to_string(s.sd));
  RecordProperty("dcnu_sd_20ms_e", std::to_string(l.sd));
}

// The pattern scales with the temperature as the mean dark current does:
// one doubling temperature warmer at 10 ms is the same frame, byte for byte,
// as 20 ms at the reference temperature (the same dark charge, the same z4).
TEST(SensorDcnu, WarmerIsLikeLongerExposure) {
  PipelineConfig warm = DarkPath(5.0, 10000.0);
  warm.sensor.temperature_c = warm.sensor.dark_current_ref_c + warm.sensor.dark_current_doubling_c;
  const auto w = DarkFrame(warm), l = DarkFrame(DarkPath(5.0, 20000.0));
  ASSERT_FALSE(w.empty());
  EXPECT_EQ(w, l);
  EXPECT_GT(Electrons(w, warm.sensor).sd, 150.0) << "not flat";
}

// At large DCNU the gain clamps at 0 (z4 < -1 / dcnu): the mean over the
// pixels rises and the spread falls below dark_e * dcnu, as the double
// reference's moments of max(0, 1 + s z) say (80 %: mean 1.0405 dark_e, rms
// 0.7282 dark_e, against 1 and 0.8 unclamped). Sampling: the factor's sd
// 0.73 over 65 536 pixels gives the mean a standard error of 0.29 % of
// dark_e and the sd (of a skewed, clipped variable: kurtosis below 4) about
// 0.35 %; tolerance 1.5 % of dark_e for both, the unclamped values 4 % and
// 7 % away. (The ADC clips above 8062 e-, z > 3.8: about 5 pixels.)
TEST(SensorDcnu, ClampedPatternMatchesTheReferenceMoments) {
  const PipelineConfig c = DarkPath(80.0, 10000.0);
  const auto f = DarkFrame(c);
  ASSERT_FALSE(f.empty());
  const Spatial e = Electrons(f, c.sensor);
  const double mean = ReferenceDarkChargeMean(c.sensor, c.exposure.exposure_time_us);
  const double rms = ReferenceDarkChargeRms(c.sensor, c.exposure.exposure_time_us);
  EXPECT_NEAR(mean, 2080.939, 0.01);  // Python's math.erfc
  EXPECT_NEAR(rms, 1456.402, 0.01);
  EXPECT_NEAR(e.mean, mean, 0.015 * 2000.0);
  EXPECT_NEAR(e.sd, rms, 0.015 * 2000.0);
  int zero = 0;  // clamped pixels read the black level: Phi(-1.25) = 10.6 %
  for (uint32_t v : f) zero += v == 64u;
  EXPECT_NEAR(zero / static_cast<double>(f.size()), 0.1056, 0.006);
  // The reference mean DN of a dark pixel uses the clamped mean.
  const double dn = ReferenceSensorMeanDn(c.sensor, c.geometry, c.exposure.exposure_time_us, kGreen, 0.0);
  EXPECT_NEAR(dn, 64.0 + 0.5 * mean, 1e-9);
  // Off: the reference is the plain dark charge, and the spread 0.
  SensorConfig off = c.sensor;
  off.dcnu_percent = 0.0;
  EXPECT_DOUBLE_EQ(ReferenceDarkChargeMean(off, 10000.0), 2000.0);
  EXPECT_EQ(ReferenceDarkChargeRms(off, 10000.0), 0.0);
}

// The pattern is fixed: the same every frame (no temporal term is on, so any
// frame-keyed draw would show), another seed's differs in most pixels, and it
// is its own draw: uncorrelated with the DSNU pattern of the same seed (the
// fixed-pattern stream's words) and with the defect stream's map (hot pixels
// add to the DCNU charge without changing the other pixels).
TEST(SensorDcnu, PatternIsFixedAndFollowsTheSeed) {
  PipelineConfig c = DarkPath(5.0, 10000.0);
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const test::Scene dark = test::FlatScene(kSide, kSide, 0, 0, 0);
  const auto f0 = test::RunFrame(*b, dark, 0, kSide);
  EXPECT_EQ(test::RunFrame(*b, dark, 1, kSide), f0);
  EXPECT_EQ(test::RunFrame(*b, dark, 1000003, 17), f0);
  EXPECT_GT(Electrons(f0, c.sensor).sd, 90.0) << "a pattern exists";

  PipelineConfig other = c;
  other.seed = 4;
  const auto f1 = DarkFrame(other);
  ASSERT_EQ(f1.size(), f0.size());
  size_t differing = 0;
  for (size_t i = 0; i < f0.size(); ++i) differing += f0[i] != f1[i];
  EXPECT_GT(differing, f0.size() * 9 / 10) << "another seed, another pattern";
  // Uncorrelated patterns: r's standard error is 1 / 256 over 65 536 pixels; 5 of it.
  EXPECT_LT(std::abs(Correlation(f0, f1)), 0.02);
  PipelineConfig dsnu = c;
  dsnu.sensor.dcnu_percent = 0.0;
  dsnu.sensor.dsnu_e = 100.0;
  EXPECT_LT(std::abs(Correlation(f0, DarkFrame(dsnu))), 0.02) << "DSNU's draw, not DCNU's";

  // Hot pixels (1 %) add their charge to their DCNU charge; every other
  // pixel keeps its DCNU charge, byte for byte.
  PipelineConfig hot = c;
  hot.sensor.hot_pixel_fraction = 0.01;
  hot.sensor.hot_pixel_dark_e_per_s = 1e6;  // 1e4 e- median, 0.5x .. 1.5x
  hot.sensor.full_well_e = 1e6;
  const auto fh = DarkFrame(hot);
  ASSERT_EQ(fh.size(), f0.size());
  size_t raised = 0, same = 0;
  for (size_t i = 0; i < f0.size(); ++i) {
    raised += fh[i] > f0[i] + 1000;  // at least 5000 e- more
    same += fh[i] == f0[i];
  }
  EXPECT_EQ(raised + same, f0.size());
  EXPECT_NEAR(raised / static_cast<double>(f0.size()), 0.01, 0.002);
}

// sensor.fixed_pattern_table stores the DCNU gains at Init: the same bytes as
// drawing them every frame, with shot and read noise, PRNU, DSNU and defects
// on or off, mosaic and 3-channel, at several strip heights and 2 threads;
// the tables grow by 4 bytes per pixel and channel for DCNU alone (8 more
// with PRNU or DSNU), and not at all when nothing is on.
TEST(SensorDcnu, TableGivesTheDrawnBytes) {
  const int w = 37, h = 23;  // odd: a last pixel pair with one pixel
  const test::Scene s = test::TexturedScene(w, h);
  for (const bool mosaic : {true, false})
    for (const bool others : {false, true}) {
      PipelineConfig c;
      c.geometry = {w, h, Cfa::kBayerGR, 12};
      c.exposure.exposure_time_us = 1000.0;
      c.order[0] = StageId::kExposure;
      c.order[1] = mosaic ? StageId::kCfa : StageId::kSensor;
      c.order[2] = StageId::kSensor;
      c.order_count = mosaic ? 3 : 2;
      c.sensor.dark_current_e_per_s = 3e5;  // 300 e-
      c.sensor.dcnu_percent = 40.0;
      c.sensor.dsnu_e = others ? 4.0 : 0.0;
      c.sensor.prnu_percent = others ? 2.0 : 0.0;
      c.sensor.hot_pixel_fraction = others ? 0.01 : 0.0;
      c.sensor.dead_pixel_fraction = others ? 0.01 : 0.0;
      auto drawn = test::Build(c, 2);
      ASSERT_TRUE(drawn->status.ok()) << drawn->status.message();
      c.sensor.fixed_pattern_table = true;
      auto table = test::Build(c, 2);
      ASSERT_TRUE(table->status.ok()) << table->status.message();
      const size_t channels = mosaic ? 1 : 3, per_pixel = others ? 12 : 4;
      const size_t grown = table->pipeline.TableBytes() - drawn->pipeline.TableBytes();
      EXPECT_GE(grown, channels * w * h * per_pixel) << "mosaic " << mosaic << " others " << others;
      EXPECT_LT(grown, channels * w * h * per_pixel + 128) << "at most two tables' 64-byte alignment more";
      for (const uint32_t frame : {0u, 5u}) {
        const auto want = test::RunFrame(*drawn, s, frame, h);
        EXPECT_EQ(test::RunFrame(*drawn, s, frame, 1), want);
        EXPECT_EQ(test::RunFrame(*table, s, frame, h), want) << "mosaic " << mosaic << " frame " << frame;
        EXPECT_EQ(test::RunFrame(*table, s, frame, 1), want);
        EXPECT_EQ(test::RunFrame(*table, s, frame, 7), want);
        EXPECT_EQ(test::RunFrameThreads(*table, s, frame, 5, 2), want);
        EXPECT_EQ(test::RunFrameThreads(*drawn, s, frame, 3, 2), want);
      }
      // DCNU changes the output (the cases above are not vacuous).
      c.sensor.dcnu_percent = 0.0;
      auto without = test::Build(c, 2);
      ASSERT_TRUE(without->status.ok());
      EXPECT_NE(test::RunFrame(*without, s, 0, h), test::RunFrame(*drawn, s, 0, h));
    }
}

// Configure refuses a DCNU outside [0, 100] % and NaN, naming the key; the
// host's configuration does too, with the file and line.
TEST(SensorDcnu, ConfigureRefusesOutOfRange) {
  const SensorGeometry g{16, 16, Cfa::kMono, 12};
  for (const double bad : {-0.001, 100.001, 1e9, std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::infinity()}) {
    SensorConfig c;
    c.dcnu_percent = bad;
    SensorStage s;
    const Status st = s.Configure(c, g, 1000.0, 1);
    ASSERT_FALSE(st.ok()) << bad;
    EXPECT_STREQ(st.field(), "sensor.dcnu_percent") << bad;
    EXPECT_NE(std::string(st.message()).find("[0, 100]"), std::string::npos) << st.message();
  }
  for (const double good : {0.0, 0.5, 100.0}) {
    SensorConfig c;
    c.dcnu_percent = good;
    SensorStage s;
    EXPECT_TRUE(s.Configure(c, g, 1000.0, 1).ok()) << good;
  }

  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  ASSERT_TRUE(host::ParseConfig("[sensor]\n\ndcnu_percent = 150.0\n", "d.toml", &rc, &origins, &error)) << error;
  EXPECT_EQ(rc.core.sensor.dcnu_percent, 150.0);
  EXPECT_FALSE(host::FinishConfig(&rc, 64, 48, origins, 1, &error));
  EXPECT_NE(error.find("d.toml:3: sensor.dcnu_percent must be in [0, 100] %"), std::string::npos) << error;
  host::RunConfig nan;
  error.clear();
  const bool parsed = host::ParseConfig("[sensor]\ndcnu_percent = nan\n", "n.toml", &nan, &origins, &error) &&
                      host::FinishConfig(&nan, 64, 48, origins, 1, &error);
  EXPECT_FALSE(parsed);
  EXPECT_NE(error.find("dcnu_percent"), std::string::npos) << error;
  // The key is in the annotated default configuration, at its default 0.
  EXPECT_NE(host::DefaultConfigToml().find("\ndcnu_percent = 0.0\n"), std::string::npos);
}

}  // namespace
}  // namespace camsim
