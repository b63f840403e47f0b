// CCD smear: the per-frame column pre-pass against its double reference (all
// sensor layouts), the streak it makes (uniform along the column, only where
// light fell), its dependence on exposure time, and the input check.
#include <gtest/gtest.h>

#include <cmath>

#include "core/sensor/smear.h"
#include "core/sensor/smear_ref.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

PipelineConfig SmearPath(int w, int h, Cfa cfa, bool with_cfa_stage) {
  PipelineConfig c;
  c.geometry = {w, h, cfa, 12};
  c.exposure.exposure_time_us = 1000.0;
  c.exposure.f_number = 1.0;
  c.exposure.photons_per_radiance_ms = 1000.0;  // 1000 photons per unit radiance
  int n = 0;
  c.order[n++] = StageId::kExposure;
  if (with_cfa_stage) c.order[n++] = StageId::kCfa;
  c.order[n++] = StageId::kSensor;
  c.order_count = n;
  test::NoiseOff(&c.sensor);
  c.sensor.system_gain_dn_per_e = 1.0;
  c.sensor.black_level_dn = 100;
  c.sensor.smear_row_transfer_us = 10.0;  // 1 % of the 1 ms exposure per row
  c.sensor.smear_leak = 1.0;
  return c;
}

std::vector<double> ToDouble(const std::vector<uint32_t>& q16) {
  std::vector<double> d(q16.size());
  for (size_t i = 0; i < q16.size(); ++i) d[i] = q16[i] / 65536.0;
  return d;
}

void ExpectPrePassMatchesReference(const PipelineConfig& c, const test::Scene& s) {
  std::vector<uint32_t> smear(static_cast<size_t>(SmearEntries(c)));
  ComputeSmear(c, s.View(), Span<uint32_t>{smear.data(), smear.size()});
  const std::vector<double> r[3] = {ToDouble(s.plane[0]), ToDouble(s.plane[1]), ToDouble(s.plane[2])};
  const double* planes[3] = {r[0].data(), r[1].data(), r[2].data()};
  bool three = true;
  for (int i = 0; i < c.order_count; ++i) three &= c.order[i] != StageId::kCfa;
  for (int ch = 0; ch < (three ? 3 : 1); ++ch)
    for (int x = 0; x < c.geometry.width; ++x) {
      const double ref = ref::RefSmear(c, planes, x, ch);
      // Up to three rounded terms of 1/256 e- and Q16 weights: well under 0.05 e-.
      EXPECT_NEAR(smear[static_cast<size_t>(ch) * c.geometry.width + x] / 256.0, ref, 0.05 + 1e-4 * ref)
          << "x " << x << " channel " << ch;
    }
}

TEST(Smear, PrePassMatchesReferenceForEveryLayout) {
  const test::Scene s = test::TexturedScene(40, 30);
  ExpectPrePassMatchesReference(SmearPath(40, 30, Cfa::kBayerRG, true), s);
  ExpectPrePassMatchesReference(SmearPath(40, 30, Cfa::kBayerGB, true), s);
  ExpectPrePassMatchesReference(SmearPath(40, 30, Cfa::kMono, true), s);
  ExpectPrePassMatchesReference(SmearPath(40, 30, Cfa::kBayerRG, false), s);  // one sensor per colour
  // Wider than the pre-pass's blocks of 64 columns, the last one partial.
  const test::Scene wide = test::TexturedScene(150, 12);
  ExpectPrePassMatchesReference(SmearPath(150, 12, Cfa::kBayerGR, true), wide);
  ExpectPrePassMatchesReference(SmearPath(150, 12, Cfa::kBayerGR, false), wide);
}

TEST(Smear, StreakIsUniformAlongLitColumnsOnly) {
  constexpr int kW = 64, kH = 48;
  const PipelineConfig c = SmearPath(kW, kH, Cfa::kBayerRG, true);
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  test::Scene s = test::FlatScene(kW, kH, 0, 0, 0);
  for (int y = 10; y < 15; ++y)
    for (int x = 20; x < 24; ++x)
      for (int ch = 0; ch < 3; ++ch) s.plane[ch][y * kW + x] = Q<16, 16>::FromDouble(2.0).raw;
  std::vector<uint32_t> smear(static_cast<size_t>(SmearEntries(c)));
  FrameInput in = s.View();
  ComputeSmear(c, in, Span<uint32_t>{smear.data(), smear.size()});
  in.smear_e = smear.data();
  ASSERT_TRUE(b->pipeline.CheckInput(in).ok());
  std::vector<uint32_t> out(static_cast<size_t>(kW) * kH);
  Tap tap;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = kW;
  b->pipeline.ProcessFrame(in, 0, 7, &tap, 1, nullptr, nullptr);
  for (int x = 0; x < kW; ++x) {
    const bool lit = x >= 20 && x < 24;
    // 5 rows of 2000 photons (R or G on even columns, G or B on odd), 1 %: ~55..65 e-.
    double expected = 0;
    for (int y = 10; y < 15; ++y) expected += 2000.0 * c.sensor.quantum_efficiency[CfaColour(Cfa::kBayerRG, x, y)];
    expected *= 0.01;
    for (int y = 0; y < kH; ++y) {
      if (y >= 10 && y < 15 && lit) continue;
      const double got = out[y * kW + x] - 100.0;  // K = 1 DN/e-
      if (lit) {
        EXPECT_NEAR(got, expected, 0.51) << x << "," << y;
      } else {
        EXPECT_EQ(got, 0.0) << x << "," << y;
      }
    }
  }
}

TEST(Smear, ShorterExposureForTheSameLightSmearsMore) {
  // Same photons per pixel (photons_per_radiance doubled, time halved): the
  // transfer takes as long, so the smear relative to the signal doubles.
  PipelineConfig a = SmearPath(16, 16, Cfa::kMono, true);
  PipelineConfig b = a;
  b.exposure.exposure_time_us = 500.0;
  b.exposure.photons_per_radiance_ms = 2000.0;
  const test::Scene s = test::FlatScene(16, 16, 1.0, 1.0, 1.0);
  std::vector<uint32_t> sa(static_cast<size_t>(SmearEntries(a))), sb(sa.size());
  ComputeSmear(a, s.View(), Span<uint32_t>{sa.data(), sa.size()});
  ComputeSmear(b, s.View(), Span<uint32_t>{sb.data(), sb.size()});
  EXPECT_GT(sa[3], 0u);
  EXPECT_NEAR(double(sb[3]), 2.0 * sa[3], 4.0);  // three terms rounded to 1/256 e- each
}

// Strong cos4 vignetting (f = 20 px on a 64 x 48 mono sensor: the corners get
// 4 % of the centre's light) on a uniform scene.
PipelineConfig VignettedPath() {
  PipelineConfig c = SmearPath(64, 48, Cfa::kMono, true);
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kVignetting;
  c.order[2] = StageId::kCfa;
  c.order[3] = StageId::kSensor;
  c.order_count = 4;
  c.vignetting.mode = VignettingMode::kCos4;
  c.vignetting.focal_length_px = 20.0;
  return c;
}

TEST(Smear, FollowsTheVignettedColumnSums) {
  PipelineConfig c = VignettedPath();
  const test::Scene s = test::FlatScene(64, 48, 1.0, 1.0, 1.0);
  std::vector<uint32_t> smear(static_cast<size_t>(SmearEntries(c)));
  ComputeSmear(c, s.View(), Span<uint32_t>{smear.data(), smear.size()});
  ExpectPrePassMatchesReference(c, s);
  // The light the sensor sees: the same pipeline without smear, no noise,
  // K = 1 DN/e-: each pixel's DN minus the black level is its charge.
  PipelineConfig plain = c;
  plain.sensor.smear_row_transfer_us = 0;
  auto b = test::Build(plain);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  std::vector<uint32_t> out(64 * 48);
  Tap tap;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = 64;
  b->pipeline.ProcessFrame(s.View(), 0, 7, &tap, 1, nullptr, nullptr);
  const double share = c.sensor.smear_leak * c.sensor.smear_row_transfer_us / c.exposure.exposure_time_us;
  double centre = 0, edge = 0;
  for (int x = 0; x < 64; ++x) {
    double column = 0;
    for (int y = 0; y < 48; ++y) column += out[y * 64 + x] - 100.0;
    // 48 pixels each within 0.5 DN of their charge: the column within 24 e-,
    // its 1 % within 0.24 e-; plus the pre-pass's own rounding.
    EXPECT_NEAR(smear[x] / 256.0, share * column, 0.3) << "column " << x;
    if (x == 32) centre = smear[x] / 256.0;
    if (x == 0) edge = smear[x] / 256.0;
  }
  EXPECT_LT(edge, 0.5 * centre);  // the vignetting is really seen
  // Across the pre-pass's blocks of 64 columns (each pixel's gain by its own column).
  PipelineConfig wide = VignettedPath();
  wide.geometry.width = 100;
  ExpectPrePassMatchesReference(wide, test::FlatScene(100, 48, 1.0, 1.0, 1.0));
}

TEST(Smear, FollowsAVignettingMask) {
  PipelineConfig c = VignettedPath();
  c.vignetting.mode = VignettingMode::kMask;
  test::Scene s = test::FlatScene(64, 48, 1.0, 1.0, 1.0);
  std::vector<uint16_t> mask(64 * 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) mask[y * 64 + x] = static_cast<uint16_t>(x < 32 ? 8192 : 16384 + 64 * y);
  FrameInput in = s.View();
  in.vignetting_mask = MakeImageView<const uint16_t>(mask.data(), 64, 48);
  std::vector<uint32_t> smear(static_cast<size_t>(SmearEntries(c)));
  ComputeSmear(c, in, Span<uint32_t>{smear.data(), smear.size()});
  const std::vector<double> r[3] = {ToDouble(s.plane[0]), ToDouble(s.plane[1]), ToDouble(s.plane[2])};
  const double* planes[3] = {r[0].data(), r[1].data(), r[2].data()};
  for (int x = 0; x < 64; ++x) {
    const double ref = ref::RefSmear(c, planes, x, 0, mask.data());
    EXPECT_NEAR(smear[x] / 256.0, ref, 0.05 + 1e-4 * ref) << "column " << x;
  }
  EXPECT_LT(smear[0], smear[63]);
}

TEST(Smear, MissingPrePassIsAnInputError) {
  const PipelineConfig c = SmearPath(8, 8, Cfa::kMono, true);
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const test::Scene s = test::FlatScene(8, 8, 1, 1, 1);
  const Status st = b->pipeline.CheckInput(s.View());
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(std::string(st.field()), "sensor.smear_row_transfer_us");
}

// Pipeline::RunPrepasses runs what CheckInput asks for, and only that.
TEST(Smear, RunPrepassesAttachesWhatTheConfigurationNeeds) {
  const test::Scene s = test::TexturedScene(16, 12);
  for (bool smear_on : {false, true}) {
    SCOPED_TRACE(smear_on ? "smear on" : "smear off");
    PipelineConfig c = SmearPath(16, 12, Cfa::kBayerRG, true);
    if (!smear_on) c.sensor.smear_row_transfer_us = 0.0;
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    const Pipeline& p = b->pipeline;
    EXPECT_EQ(p.PrepassFlareSources(), 0) << "flare is off";
    ASSERT_EQ(p.PrepassSmearEntries(), smear_on ? SmearEntries(c) : 0);
    std::vector<uint32_t> smear(static_cast<size_t>(p.PrepassSmearEntries()), 0xA5A5A5A5u);
    FlareFrame flare;
    const FrameInput in =
        p.RunPrepasses(s.View(), Span<FlareSource>{}, &flare, Span<uint32_t>{smear.data(), smear.size()});
    EXPECT_EQ(in.flare, nullptr);
    EXPECT_EQ(in.radiance[1].data, s.View().radiance[1].data);
    EXPECT_TRUE(p.CheckInput(in).ok());
    if (!smear_on) {
      EXPECT_EQ(in.smear_e, nullptr);
      continue;
    }
    ASSERT_EQ(in.smear_e, smear.data());
    std::vector<uint32_t> direct(smear.size());
    ComputeSmear(c, s.View(), Span<uint32_t>{direct.data(), direct.size()});
    // The charges (the entries after them are ComputeSmear's column sums).
    const size_t charges = static_cast<size_t>(kMaxChannels) * c.geometry.width;
    EXPECT_EQ(std::vector<uint32_t>(smear.begin(), smear.begin() + charges),
              std::vector<uint32_t>(direct.begin(), direct.begin() + charges));
  }
}

}  // namespace
}  // namespace camsim
