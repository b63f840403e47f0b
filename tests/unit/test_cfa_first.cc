// A Bayer CFA runs ahead of exposure and vignetting (pipeline.cc,
// MoveCfaAhead): they then process one mosaic plane instead of three. The
// planner must move it exactly then, and the bytes must be those of the
// configured order (exposure and vignetting on RGB, then the CFA), for every
// Bayer phase, row parity and width (blocks of 16 columns and every tail
// length), with saturation reached. Also: vignetting's curve gains (AVX2
// lanes where the CPU has them) against the scalar VignettingCurveGain.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "core/aperture/exposure.h"
#include "core/lens/vignetting.h"
#include "core/pipeline/pipeline.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

using test::Find;
using test::InitStage;
using test::StageTables;

constexpr Cfa kBayerPhases[] = {Cfa::kBayerRG, Cfa::kBayerGR, Cfa::kBayerGB, Cfa::kBayerBG};

// Runs a pointwise stage over `in` (1 or 3 planes) row by row; output rows
// are pre-filled with a marker so that an unwritten sample shows.
std::vector<std::vector<uint32_t>> RunRows(const Stage& stage, const std::vector<std::vector<uint32_t>>& in, int w,
                                           int h, const FrameInput* input) {
  const size_t channels = in.size();
  std::vector<std::vector<uint32_t>> out(channels, std::vector<uint32_t>(static_cast<size_t>(w) * h));
  for (int y = 0; y < h; ++y) {
    std::vector<uint32_t> rows_out[3];
    RowIn row;
    RowArgs a;
    for (size_t c = 0; c < channels; ++c) {
      rows_out[c].assign(static_cast<size_t>(w), 0xDEADBEEFu);
      row.ch[c] = in[c].data() + static_cast<size_t>(y) * w;
      a.out[c] = rows_out[c].data();
    }
    a.y = y;
    a.width = w;
    a.rows = &row;
    a.row_count = 1;
    a.first_row = y;
    a.input = input;
    stage.ProcessRow(a);
    for (size_t c = 0; c < channels; ++c)
      std::memcpy(out[c].data() + static_cast<size_t>(y) * w, rows_out[c].data(), sizeof(uint32_t) * w);
  }
  return out;
}


// The planner moves a Bayer CFA ahead of the exposure and vignetting entries
// right before it, says so in the plan, and leaves a mono CFA (a weighted
// sum, rounded after the scaling) and every other order alone. A Bayer CFA
// right after distortion (moved there or configured so) is left out: the
// distortion writes the mosaic itself.
TEST(CfaFirst, PlannerMovesABayerCfaAheadOfPointwiseStages) {
  struct Case {
    Cfa cfa;
    std::vector<StageId> order, want;
    bool cfa_runs;
  };
  using S = StageId;
  const Case cases[] = {
      {Cfa::kBayerGR, {S::kExposure, S::kVignetting, S::kCfa, S::kSensor},
       {S::kCfa, S::kExposure, S::kVignetting, S::kSensor}, true},
      {Cfa::kBayerBG, {S::kDistortion, S::kExposure, S::kCfa, S::kVignetting},
       {S::kDistortion, S::kCfa, S::kExposure, S::kVignetting}, false},
      {Cfa::kMono, {S::kExposure, S::kVignetting, S::kCfa, S::kSensor},
       {S::kExposure, S::kVignetting, S::kCfa, S::kSensor}, true},
      {Cfa::kMono, {S::kDistortion, S::kCfa}, {S::kDistortion, S::kCfa}, true},
      {Cfa::kBayerRG, {S::kExposure, S::kDistortion, S::kCfa}, {S::kExposure, S::kDistortion, S::kCfa}, false},
      {Cfa::kBayerRG, {S::kDistortion, S::kExposure}, {S::kDistortion, S::kExposure}, true},  // no CFA: RGB
  };
  for (const Case& k : cases) {
    PipelineConfig c;
    c.geometry.width = 32;
    c.geometry.height = 16;
    c.geometry.cfa = k.cfa;
    c.vignetting.mode = VignettingMode::kCos4;
    c.vignetting.focal_length_px = 30.0;
    c.distortion.lens.model = DistortionModel::kBrown;
    c.distortion.lens.fx = c.distortion.lens.fy = 40.0;
    c.distortion.lens.cx = 15.5;
    c.distortion.lens.cy = 7.5;
    c.distortion.lens.k[0] = -0.1;
    c.order_count = static_cast<int>(k.order.size());
    for (int i = 0; i < c.order_count; ++i) c.order[i] = k.order[i];
    Pipeline p;
    const Status s = p.Configure(c, 1, false);
    ASSERT_TRUE(s.ok()) << s.message();
    const Plan& plan = p.plan();
    ASSERT_EQ(plan.count, c.order_count);
    const bool moved = k.want != k.order;
    for (int i = 0; i < plan.count; ++i) {
      const PlanEntry& e = plan.entries[i];
      const bool is_cfa = e.id == StageId::kCfa;
      EXPECT_EQ(e.id, k.want[i]) << CfaName(k.cfa) << " entry " << i;
      EXPECT_EQ(e.runs, !is_cfa || k.cfa_runs) << CfaName(k.cfa) << " entry " << i;
      EXPECT_EQ(std::strlen(e.note) > 0, is_cfa && moved && k.cfa_runs) << CfaName(k.cfa) << " entry " << i;
      if (is_cfa && !k.cfa_runs) {
        EXPECT_STREQ(e.reason, "distortion before it computes only each Bayer site's colour and writes the mosaic "
                               "itself");
      }
      // Distortion writes the mosaic when, and only when, it leaves the CFA out.
      if (e.id == StageId::kDistortion) {
        EXPECT_EQ(e.out.channels, k.cfa_runs ? 3 : 1) << CfaName(k.cfa);
        EXPECT_EQ(e.out.mosaic, !k.cfa_runs) << CfaName(k.cfa);
      }
    }
    if (!moved || !k.cfa_runs) continue;
    // Formats: the CFA keeps the radiance domain, exposure turns the mosaic into photons.
    const PlanEntry* cfa = Find(plan, StageId::kCfa);
    const PlanEntry* exposure = Find(plan, StageId::kExposure);
    EXPECT_EQ(cfa->out.domain, Domain::kRadiance);
    EXPECT_EQ(cfa->out.channels, 1);
    EXPECT_TRUE(cfa->out.mosaic);
    EXPECT_EQ(exposure->out.domain, Domain::kPhotons);
    EXPECT_EQ(exposure->out.channels, 1);
    EXPECT_TRUE(exposure->out.mosaic);
  }
}

// The moved order gives the bytes of the configured one: the pipeline
// exposure -> vignetting -> CFA (run as CFA -> exposure -> vignetting)
// against exposure -> vignetting on RGB with each pixel's site colour picked.
TEST(CfaFirst, SameBytesAsTheConfiguredOrder) {
  struct Setting {
    double exposure_time_us, f_number, photons_per_radiance_ms;
    VignettingMode mode;
  };
  const Setting settings[] = {
      {10000.0, 2.8, 8000.0, VignettingMode::kCos4},   // ordinary, strong fall-off
      {192000.0, 0.5, 1e9, VignettingMode::kTable},    // factor >= 2^31 (UScale shift 0): saturates
      {1.0, 128.0, 1e-6, VignettingMode::kCos4},       // factor < 2^-32 (shift > 63): all zero
      {100000.0, 1.0, 3e4, VignettingMode::kTable},    // table gain 3.9: saturation by the gain
  };
  for (const Setting& s : settings)
    for (Cfa cfa : kBayerPhases)
      for (int w : {1, 2, 7, 16, 17, 37, 64}) {
        SCOPED_TRACE(testing::Message() << CfaName(cfa) << " width " << w << " exposure " << s.exposure_time_us);
        PipelineConfig c;
        c.geometry.width = w;
        c.geometry.height = 5;
        c.geometry.cfa = cfa;
        c.exposure.exposure_time_us = s.exposure_time_us;
        c.exposure.f_number = s.f_number;
        c.exposure.photons_per_radiance_ms = s.photons_per_radiance_ms;
        c.vignetting.mode = s.mode;
        c.vignetting.focal_length_px = 3.0;
        c.vignetting.table_count = 3;
        c.vignetting.table[0] = 3.9;
        c.vignetting.table[1] = 1.0;
        c.vignetting.table[2] = 0.25;
        c.order[0] = StageId::kExposure;
        c.order[1] = StageId::kVignetting;
        c.order[2] = StageId::kCfa;
        c.order_count = 3;
        const test::Scene scene = test::TexturedScene(w, c.geometry.height);
        auto moved = test::Build(c);
        ASSERT_TRUE(moved->status.ok()) << moved->status.message();
        ASSERT_EQ(moved->pipeline.plan().entries[0].id, StageId::kCfa);
        c.order_count = 2;
        auto rgb = test::Build(c);
        ASSERT_TRUE(rgb->status.ok()) << rgb->status.message();
        const std::vector<uint32_t> got = test::RunFrame(*moved, scene, 0, 2);
        const std::vector<uint32_t> all = test::RunFrame(*rgb, scene, 0, 2);
        ASSERT_EQ(got.size() * 3, all.size());
        for (int y = 0; y < c.geometry.height; ++y)
          for (int x = 0; x < w; ++x) {
            const size_t i = static_cast<size_t>(y) * w + x;
            ASSERT_EQ(got[i], all[3 * i + CfaColour(cfa, x, y)]) << "at " << x << "," << y;
          }
      }
}

// Every output sample of a curve mode is SatU32(round(in * g / 2^14)) with
// g = VignettingCurveGain of the pixel's squared radius, on the lanes and on
// the portable loop, for three channels and a mosaic's one; widths give the
// lanes none, some and a tail in both halves (1920: full 256-column blocks).
TEST(Vignetting, CurveGainsAreTheScalarOnes) {
  for (int mode = 0; mode < 3; ++mode)
    for (int w : {1, 2, 7, 16, 17, 37, 515, 1920})
      for (const size_t channels : {size_t{3}, size_t{1}})
        for (const bool portable : {false, true}) {
          SCOPED_TRACE(testing::Message() << "mode " << mode << " width " << w << " channels " << channels
                                          << " portable " << portable);
          VignettingConfig v;
          v.mode = mode == 2 ? VignettingMode::kTable : VignettingMode::kCos4;
          v.focal_length_px = mode == 0 ? 3.0 : 700.0;
          v.table_count = 3;
          v.table[0] = 3.9;  // past 1: saturation of bright samples
          v.table[1] = 1.0;
          v.table[2] = 0.25;
          SensorGeometry g;
          g.width = w;
          g.height = 5;
          g.cfa = Cfa::kBayerGB;
          VignettingStage stage;
          StageTables tables;
          ASSERT_TRUE(stage.Configure(v, g, false).ok());
          stage.ForcePortablePathForTest(portable);
          ASSERT_TRUE(InitStage(stage, tables).ok());
          // Mostly moderate values, some near the top of the range.
          std::mt19937 rng(static_cast<uint32_t>(w + mode));
          std::vector<std::vector<uint32_t>> in(channels, std::vector<uint32_t>(static_cast<size_t>(w) * g.height));
          for (std::vector<uint32_t>& plane : in)
            for (size_t i = 0; i < plane.size(); ++i) plane[i] = i % 5 == 0 ? rng() : rng() >> 8;
          const auto out = RunRows(stage, in, w, g.height, nullptr);
          uint16_t curve[VignettingStage::kCurvePoints + 1];
          UScale scale;
          ASSERT_TRUE(BuildVignettingCurve(v, g, curve, &scale).ok());
          for (int y = 0; y < g.height; ++y)
            for (int x = 0; x < w; ++x) {
              const int64_t dx = 2 * x - (w - 1), dy = 2 * y - (g.height - 1);
              const uint32_t gain = VignettingCurveGain(curve, scale, static_cast<uint32_t>(dx * dx + dy * dy));
              for (size_t c = 0; c < channels; ++c) {
                const size_t i = static_cast<size_t>(y) * w + x;
                const uint32_t want = SatU32(RoundShiftU(uint64_t{in[c][i]} * gain, 14));
                ASSERT_EQ(out[c][i], want) << "channel " << c << " at " << x << "," << y;
              }
            }
        }
}

}  // namespace
}  // namespace camsim
