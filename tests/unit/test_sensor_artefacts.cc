// Sensor artefacts beyond the EMVA 1288 model: row and column fixed-pattern
// noise and defect pixels (hot, dead, stuck) measure as configured, are fixed
// from frame to frame, and are off by default.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/sensor/emva.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

double StdDev(const std::vector<double>& v) {
  double m = 0, s = 0;
  for (double x : v) m += x;
  m /= v.size();
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / (v.size() - 1));
}

TEST(SensorArtefacts, RowAndColumnFpnMeasureAsConfigured) {
  constexpr int kW = 512, kH = 512;
  PipelineConfig c = test::MonoSensorPath(kW, kH);
  test::NoiseOff(&c.sensor);
  c.sensor.system_gain_dn_per_e = 1.0;
  c.sensor.black_level_dn = 200;
  c.sensor.row_fpn_e = 4.0;
  c.sensor.column_fpn_e = 3.0;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const test::Scene dark = test::FlatScene(kW, kH, 0, 0, 0);
  const auto img = test::RunFrame(*b, dark, 0, 7);
  EXPECT_EQ(test::RunFrame(*b, dark, 5, 64), img);  // fixed, and the same for any strip height
  std::vector<double> row_mean(kH, 0.0), col_mean(kW, 0.0);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      row_mean[y] += img[y * kW + x] / double(kW);
      col_mean[x] += img[y * kW + x] / double(kH);
    }
  // 512 samples: a standard deviation is known to ~3.1 % (1 sigma); 12 % is ~4 sigma.
  EXPECT_NEAR(StdDev(row_mean), 4.0, 0.12 * 4.0);
  EXPECT_NEAR(StdDev(col_mean), 3.0, 0.12 * 3.0);
  // Rows are constant apart from the column pattern: a row minus the column means is flat.
  for (int x = 0; x < kW; ++x) EXPECT_NEAR(img[3 * kW + x] - col_mean[x], row_mean[3] - 200.0, 1.5) << x;
}

// Defect words come from their own stream (emva.h, "Random words"): turning
// defects on leaves the PRNU/DSNU pattern and the temporal noise of every
// other pixel exactly as it was, and changes the defect pixels only.
TEST(SensorArtefacts, DefectsLeaveOtherPixelsUnchanged) {
  constexpr int kW = 256, kH = 128;
  PipelineConfig c = test::MonoSensorPath(kW, kH);
  c.sensor.prnu_percent = 2.0;
  c.sensor.dsnu_e = 3.0;
  auto plain = test::Build(c);
  c.sensor.dead_pixel_fraction = 0.01;
  auto with_defects = test::Build(c);
  ASSERT_TRUE(plain->status.ok()) << plain->status.message();
  ASSERT_TRUE(with_defects->status.ok()) << with_defects->status.message();
  const test::Scene lit = test::FlatScene(kW, kH, 6, 6, 6);  // ~3900 e-: dead pixels stand out
  const auto a = test::RunFrame(*plain, lit, 4, 16);
  const auto b = test::RunFrame(*with_defects, lit, 4, 16);
  ASSERT_EQ(a.size(), b.size());
  int changed = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i] == b[i]) continue;
    ++changed;
    EXPECT_LT(b[i], c.sensor.black_level_dn + 30) << i;  // a changed pixel is a dead one
  }
  // Binomial: N p = 327.68, sd ~ 18; 4 sd.
  const double n = kW * kH * 0.01;
  EXPECT_NEAR(changed, n, 4 * std::sqrt(n));
}

enum PixelClass : char { kNormal, kHot, kDead, kStuck };

// Each pixel's class, told apart from two dark frames and a lit one (6000
// photons, ~3900 e-): stuck reads full scale in all, hot carries >= 400 e-
// of extra dark charge in both dark frames, dead does not respond to light.
// Expects every other pixel to respond normally. Needs hot_pixel_dark_e_per_s
// far above the read noise.
std::vector<PixelClass> ClassifyPixels(const PipelineConfig& c, int w, int h) {
  auto b = test::Build(c);
  EXPECT_TRUE(b->status.ok()) << b->status.message();
  if (!b->status.ok()) return {};
  const double K = c.sensor.system_gain_dn_per_e, black = c.sensor.black_level_dn;
  const auto dark = test::RunFrame(*b, test::FlatScene(w, h, 0, 0, 0), 1, 16);
  const auto dark2 = test::RunFrame(*b, test::FlatScene(w, h, 0, 0, 0), 2, 16);
  const auto lit = test::RunFrame(*b, test::FlatScene(w, h, 6, 6, 6), 3, 16);
  const double lit_dn = black + K * 6000 * c.sensor.quantum_efficiency[kGreen];
  const uint32_t max_dn = (1u << c.geometry.adc_bits) - 1;
  std::vector<PixelClass> classes(dark.size(), kNormal);
  for (size_t i = 0; i < dark.size(); ++i) {
    if (dark[i] == max_dn && lit[i] == max_dn) {
      classes[i] = kStuck;
    } else if (dark[i] > black + K * 400 && dark2[i] > black + K * 400) {
      classes[i] = kHot;
      EXPECT_GT(lit[i], lit_dn);
    } else if (lit[i] < black + K * 30) {
      classes[i] = kDead;
    } else {
      EXPECT_GT(lit[i], lit_dn - K * 400) << i;  // every other pixel responds normally
    }
  }
  return classes;
}

int Count(const std::vector<PixelClass>& classes, PixelClass which) {
  return static_cast<int>(std::count(classes.begin(), classes.end(), which));
}

TEST(SensorArtefacts, DefectPixelsFollowTheirFractions) {
  constexpr int kW = 256, kH = 256;
  PipelineConfig c = test::MonoSensorPath(kW, kH);
  c.sensor.hot_pixel_fraction = 0.005;
  c.sensor.dead_pixel_fraction = 0.004;
  c.sensor.stuck_pixel_fraction = 0.003;
  c.sensor.hot_pixel_dark_e_per_s = 1e5;  // 1000 e- median in 10 ms: far above the 2.4 e- read noise
  const std::vector<PixelClass> classes = ClassifyPixels(c, kW, kH);
  // Binomial counts of 65536 pixels: sd = sqrt(N p) ~ 18 for p = 0.005; 4 sd.
  const double N = kW * kH;
  EXPECT_NEAR(Count(classes, kHot), N * 0.005, 4 * std::sqrt(N * 0.005));
  EXPECT_NEAR(Count(classes, kDead), N * 0.004, 4 * std::sqrt(N * 0.004));
  EXPECT_NEAR(Count(classes, kStuck), N * 0.003, 4 * std::sqrt(N * 0.003));
}

// Each class has its own band of the defect word (emva.h): a user who raises
// the share of hot pixels gets more hot pixels, the old ones among them, and
// the same dead and stuck pixels as before.
TEST(SensorArtefacts, DefectClassesAreIndependent) {
  constexpr int kW = 256, kH = 128;
  PipelineConfig c = test::MonoSensorPath(kW, kH);
  c.sensor.hot_pixel_dark_e_per_s = 1e5;
  c.sensor.hot_pixel_fraction = 0.002;
  c.sensor.dead_pixel_fraction = 0.004;
  c.sensor.stuck_pixel_fraction = 0.003;
  const std::vector<PixelClass> before = ClassifyPixels(c, kW, kH);
  c.sensor.hot_pixel_fraction = 0.008;
  const std::vector<PixelClass> more_hot = ClassifyPixels(c, kW, kH);
  c.sensor.dead_pixel_fraction = 0.0;
  const std::vector<PixelClass> no_dead = ClassifyPixels(c, kW, kH);
  ASSERT_EQ(before.size(), size_t{kW * kH});
  ASSERT_EQ(more_hot.size(), before.size());
  ASSERT_EQ(no_dead.size(), before.size());
  EXPECT_GT(Count(more_hot, kHot), 2 * Count(before, kHot));
  EXPECT_GT(Count(before, kDead), 0);
  EXPECT_GT(Count(before, kStuck), 0);
  for (size_t i = 0; i < before.size(); ++i) {
    if (before[i] == kHot) { EXPECT_EQ(more_hot[i], kHot) << i; }
    if (before[i] == kDead || before[i] == kStuck) { EXPECT_EQ(more_hot[i], before[i]) << i; }
    if (more_hot[i] != kDead) { EXPECT_EQ(no_dead[i], more_hot[i]) << i; }  // only the dead ones go
    if (more_hot[i] == kDead) { EXPECT_EQ(no_dead[i], kNormal) << i; }
  }
}

TEST(SensorArtefacts, HotPixelStrengthsSpreadHalfToOneAndAHalfTimes) {
  constexpr int kW = 256, kH = 256;
  PipelineConfig c = test::MonoSensorPath(kW, kH);
  c.sensor.shot_noise = false;
  c.sensor.dark_noise_e = 0;
  c.sensor.dsnu_e = 0;
  c.sensor.dark_current_e_per_s = 0;
  c.sensor.hot_pixel_fraction = 0.01;
  c.sensor.hot_pixel_dark_e_per_s = 2e5;  // 2000 e- median in 10 ms
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const auto dark = test::RunFrame(*b, test::FlatScene(kW, kH, 0, 0, 0), 0, 16);
  const double K = c.sensor.system_gain_dn_per_e, black = c.sensor.black_level_dn;
  double lo = 1e9, hi = 0, sum = 0;
  int count = 0;
  for (uint32_t v : dark)
    if (v > black + 1) {
      const double e = (v - black) / K;
      lo = std::min(lo, e);
      hi = std::max(hi, e);
      sum += e;
      ++count;
    }
  ASSERT_GT(count, 500);
  EXPECT_GE(lo, 1000.0 - 2 / K);
  EXPECT_LE(hi, 3000.0 + 2 / K);
  EXPECT_NEAR(sum / count, 2000.0, 60.0);  // uniform spread: sd 577 e- / sqrt(~650)
}

// The artefacts beyond the EMVA model are opt-in: every knob defaults to 0
// (each knob's effect when set is measured by the tests above).
TEST(SensorArtefacts, OffByDefault) {
  const SensorConfig s;
  EXPECT_EQ(s.row_fpn_e, 0.0);
  EXPECT_EQ(s.column_fpn_e, 0.0);
  EXPECT_EQ(s.hot_pixel_fraction + s.dead_pixel_fraction + s.stuck_pixel_fraction, 0.0);
}

TEST(SensorArtefacts, OutOfRangeValuesNameTheirKey) {
  PipelineConfig c = test::MonoSensorPath(16, 16);
  c.sensor.stuck_pixel_fraction = 0.5;
  auto b = test::Build(c);
  EXPECT_FALSE(b->status.ok());
  EXPECT_EQ(std::string(b->status.field()), "sensor.stuck_pixel_fraction");
}

}  // namespace
}  // namespace camsim
