// Sensor artefacts beyond the EMVA 1288 model: row and column fixed-pattern
// noise and defect pixels (hot, dead, stuck) measure as configured, are fixed
// from frame to frame, and are off by default.
#include <gtest/gtest.h>

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

struct DefectCounts {
  int hot = 0, dead = 0, stuck = 0;
};

TEST(SensorArtefacts, DefectPixelsFollowTheirFractions) {
  constexpr int kW = 256, kH = 256;
  PipelineConfig c = test::MonoSensorPath(kW, kH);
  c.sensor.hot_pixel_fraction = 0.005;
  c.sensor.dead_pixel_fraction = 0.004;
  c.sensor.stuck_pixel_fraction = 0.003;
  c.sensor.hot_pixel_dark_e_per_s = 1e5;  // 1000 e- median in 10 ms: far above the 2.4 e- read noise
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  const double K = c.sensor.system_gain_dn_per_e, black = c.sensor.black_level_dn;
  const auto dark = test::RunFrame(*b, test::FlatScene(kW, kH, 0, 0, 0), 1, 16);
  const auto dark2 = test::RunFrame(*b, test::FlatScene(kW, kH, 0, 0, 0), 2, 16);
  const auto lit = test::RunFrame(*b, test::FlatScene(kW, kH, 6, 6, 6), 3, 16);  // 6000 photons, ~3900 e-
  const double lit_dn = black + K * 6000 * c.sensor.quantum_efficiency[kGreen];
  const int max_dn = 4095;
  DefectCounts n;
  for (size_t i = 0; i < dark.size(); ++i) {
    if (dark[i] == uint32_t(max_dn) && lit[i] == uint32_t(max_dn)) {
      ++n.stuck;
    } else if (dark[i] > black + K * 400 && dark2[i] > black + K * 400) {
      ++n.hot;  // >= 500 e- of extra dark charge every frame
      EXPECT_GT(lit[i], lit_dn);
    } else if (lit[i] < black + K * 30) {
      ++n.dead;  // no response to ~3900 e- of light
    } else {
      EXPECT_GT(lit[i], lit_dn - K * 400) << i;  // every other pixel responds normally
    }
  }
  // Binomial counts of 65536 pixels: sd = sqrt(N p) ~ 18 for p = 0.005; 4 sd.
  const double N = kW * kH;
  EXPECT_NEAR(n.hot, N * 0.005, 4 * std::sqrt(N * 0.005));
  EXPECT_NEAR(n.dead, N * 0.004, 4 * std::sqrt(N * 0.004));
  EXPECT_NEAR(n.stuck, N * 0.003, 4 * std::sqrt(N * 0.003));
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
