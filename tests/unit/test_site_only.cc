// Exposure and vignetting in CFA-site-only mode (exposure.h, vignetting.h):
// on site-only lines (one colour per pixel, 0 in the two others, as the
// site-only distortion writes them) the site-only code path must give the
// same bytes as the all-channel path, on every channel, for every Bayer
// phase, row parity and width (blocks of 8 columns and every tail length),
// and the planner must switch it on exactly where distortion runs site-only.
// Also: vignetting's curve gains (AVX2 lanes where the CPU has them) against
// the scalar VignettingCurveGain, pixel by pixel.
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

constexpr Cfa kBayerPhases[] = {Cfa::kBayerRG, Cfa::kBayerGR, Cfa::kBayerGB, Cfa::kBayerBG};
// Block-only, tail-only and mixed widths; odd ones put vignetting's mirrored
// half at an odd first column.
constexpr int kWidths[] = {1, 2, 3, 7, 8, 9, 16, 23, 37, 64, 515};
constexpr int kHeight = 4;  // both row parities, twice

// A site-only frame: channel c of pixel (x, y) is a random sample (the full
// 32-bit range, so saturation is reached) where c is the site's colour, else 0.
std::vector<std::vector<uint32_t>> SiteOnlyFrame(int w, int h, Cfa cfa, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<std::vector<uint32_t>> planes(3, std::vector<uint32_t>(static_cast<size_t>(w) * h, 0));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // Mostly moderate values, some near the top of the range.
      const uint32_t v = (x % 5 == 0) ? rng() : rng() >> 8;
      planes[CfaColour(cfa, x, y)][static_cast<size_t>(y) * w + x] = v;
    }
  return planes;
}

// Runs a pointwise 3-channel stage over the frame row by row; output
// channel rows are pre-filled with a marker so that an unwritten sample shows.
std::vector<std::vector<uint32_t>> RunRows(const Stage& stage, const std::vector<std::vector<uint32_t>>& in, int w,
                                       int h, const FrameInput* input) {
  std::vector<std::vector<uint32_t>> out(3, std::vector<uint32_t>(static_cast<size_t>(w) * h));
  for (int y = 0; y < h; ++y) {
    std::vector<uint32_t> rows_out[3];
    RowIn row;
    for (int c = 0; c < 3; ++c) {
      rows_out[c].assign(static_cast<size_t>(w), 0xDEADBEEFu);
      row.ch[c] = in[c].data() + static_cast<size_t>(y) * w;
    }
    RowArgs a;
    a.y = y;
    a.width = w;
    a.rows = &row;
    a.row_count = 1;
    a.first_row = y;
    a.input = input;
    for (int c = 0; c < 3; ++c) a.out[c] = rows_out[c].data();
    stage.ProcessRow(a);
    for (int c = 0; c < 3; ++c)
      std::memcpy(out[c].data() + static_cast<size_t>(y) * w, rows_out[c].data(), sizeof(uint32_t) * w);
  }
  return out;
}

void ExpectSameBytes(const std::vector<std::vector<uint32_t>>& got, const std::vector<std::vector<uint32_t>>& want,
                     int w) {
  for (int c = 0; c < 3; ++c)
    for (size_t i = 0; i < got[c].size(); ++i)
      ASSERT_EQ(got[c][i], want[c][i]) << "channel " << c << " at " << i % w << "," << i / w;
}

TEST(SiteOnly, ExposureEqualsAllChannels) {
  ExposureConfig factors[3];  // an ordinary factor and both of UScale::Apply's special cases
  factors[1].exposure_time_us = 192000.0;  // factor 1e9 * 192 / 0.5^2 / 256 = 3e9 >= 2^31: shift 0
  factors[1].f_number = 0.5;
  factors[1].photons_per_radiance_ms = 1e9;
  factors[2].exposure_time_us = 1.0;  // factor < 2^-32: shift > 63
  factors[2].f_number = 128.0;
  factors[2].photons_per_radiance_ms = 1e-6;
  const int want_shift[3][2] = {{1, 63}, {0, 0}, {64, 95}};  // the range each case is meant to reach
  for (int i = 0; i < 3; ++i) {
    const ExposureConfig& e = factors[i];
    ExposureStage all, site;
    ASSERT_TRUE(all.Configure(e).ok()) << i;
    ASSERT_TRUE(site.Configure(e).ok());
    EXPECT_GE(all.factor().shift, want_shift[i][0]);
    EXPECT_LE(all.factor().shift, want_shift[i][1]);
    for (Cfa cfa : kBayerPhases)
      for (int w : kWidths) {
        SCOPED_TRACE(testing::Message() << CfaName(cfa) << " width " << w << " shift " << all.factor().shift);
        site.SetSiteOnly(cfa);
        const auto in = SiteOnlyFrame(w, kHeight, cfa, static_cast<uint32_t>(w));
        ExpectSameBytes(RunRows(site, in, w, kHeight, nullptr), RunRows(all, in, w, kHeight, nullptr), w);
      }
  }
}

using test::InitStage;
using test::StageTables;

TEST(SiteOnly, VignettingEqualsAllChannels) {
  for (VignettingMode mode : {VignettingMode::kCos4, VignettingMode::kMask})
    for (Cfa cfa : kBayerPhases)
      for (int w : kWidths) {
        SCOPED_TRACE(testing::Message() << "mode " << static_cast<int>(mode) << " " << CfaName(cfa) << " width "
                                        << w);
        VignettingConfig v;
        v.mode = mode;
        v.focal_length_px = 3.0;  // strong fall-off across even a small frame
        SensorGeometry g;
        g.width = w;
        g.height = kHeight;
        g.cfa = cfa;
        // Mask gains: Q2.14 up to 3.99994, so saturation is reached too.
        std::vector<uint16_t> mask(static_cast<size_t>(w) * kHeight);
        std::mt19937 rng(static_cast<uint32_t>(7 * w));
        for (uint16_t& m : mask) m = static_cast<uint16_t>(rng() & 0xFFFF);
        FrameInput input;
        input.vignetting_mask = ImageView<const uint16_t>{mask.data(), w, kHeight, 1, w};
        VignettingStage all, site;
        StageTables ta, ts;
        ASSERT_TRUE(all.Configure(v, g, true).ok());
        ASSERT_TRUE(site.Configure(v, g, true).ok());
        ASSERT_TRUE(InitStage(all, ta).ok());
        ASSERT_TRUE(InitStage(site, ts).ok());
        site.SetSiteOnly(cfa);
        const auto in = SiteOnlyFrame(w, kHeight, cfa, static_cast<uint32_t>(1000 + w));
        ExpectSameBytes(RunRows(site, in, w, kHeight, &input), RunRows(all, in, w, kHeight, &input), w);
      }
}

// Every output sample of a curve mode is SatU32(round(in * g / 2^14)) with
// g = VignettingCurveGain of the pixel's squared radius, on the lanes and on
// the portable loop, for all channels and site only; widths give the lanes
// none, some and a tail in both halves (1920: full 256-column blocks).
TEST(Vignetting, CurveGainsAreTheScalarOnes) {
  for (int mode = 0; mode < 3; ++mode)
    for (int w : {1, 2, 7, 16, 17, 37, 515, 1920})
      for (const bool site_only : {false, true})
        for (const bool portable : {false, true}) {
          SCOPED_TRACE(testing::Message() << "mode " << mode << " width " << w << " site " << site_only
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
          if (site_only) stage.SetSiteOnly(g.cfa);
          auto in = SiteOnlyFrame(w, g.height, g.cfa, static_cast<uint32_t>(w + mode));
          if (!site_only) in[0] = in[1] = in[2] = SiteOnlyFrame(w, g.height, Cfa::kMono, 3u)[kGreen];  // mono: all green
          const auto out = RunRows(stage, in, w, g.height, nullptr);
          uint16_t curve[VignettingStage::kCurvePoints + 1];
          UScale scale;
          ASSERT_TRUE(BuildVignettingCurve(v, g, curve, &scale).ok());
          for (int y = 0; y < g.height; ++y)
            for (int x = 0; x < w; ++x) {
              const int64_t dx = 2 * x - (w - 1), dy = 2 * y - (g.height - 1);
              const uint32_t gain = VignettingCurveGain(curve, scale, static_cast<uint32_t>(dx * dx + dy * dy));
              for (int c = 0; c < 3; ++c) {
                const size_t i = static_cast<size_t>(y) * w + x;
                const uint32_t want = SatU32(RoundShiftU(uint64_t{in[c][i]} * gain, 14));
                ASSERT_EQ(out[c][i], want) << "channel " << c << " at " << x << "," << y;
              }
            }
        }
}

// The planner: site-only exactly for the pointwise stages between a
// site-only distortion and a Bayer CFA; Configure resets it.
TEST(SiteOnly, PlannerSetsItBetweenDistortionAndCfa) {
  PipelineConfig c;
  c.geometry.width = 64;
  c.geometry.height = 48;
  c.distortion.lens.model = DistortionModel::kBrown;
  c.distortion.lens.fx = c.distortion.lens.fy = 50.0;
  c.distortion.lens.cx = 31.5;
  c.distortion.lens.cy = 23.5;
  c.distortion.lens.k[0] = -0.2;
  c.vignetting.mode = VignettingMode::kCos4;
  c.vignetting.focal_length_px = 60.0;
  c.order[0] = StageId::kDistortion;
  c.order[1] = StageId::kExposure;
  c.order[2] = StageId::kVignetting;
  c.order[3] = StageId::kCfa;
  c.order_count = 4;
  struct Case {
    Cfa cfa;
    int order_count;
    bool want;
  };
  for (const Case& k : {Case{Cfa::kBayerGR, 4, true}, Case{Cfa::kMono, 4, false}, Case{Cfa::kBayerGR, 3, false}}) {
    SCOPED_TRACE(testing::Message() << CfaName(k.cfa) << ", " << k.order_count << " stages");
    c.geometry.cfa = k.cfa;
    c.order_count = k.order_count;
    Pipeline p;
    ASSERT_TRUE(p.Configure(c, 1, false).ok());
    int seen = 0;
    for (int i = 0; i < p.plan().running; ++i) {
      const Stage& s = p.running_stage(i);
      if (std::strcmp(s.name(), "exposure") == 0) {
        EXPECT_EQ(static_cast<const ExposureStage&>(s).site_only(), k.want ? k.cfa : Cfa::kMono);
        ++seen;
      }
      if (std::strcmp(s.name(), "vignetting") == 0) {
        EXPECT_EQ(static_cast<const VignettingStage&>(s).site_only(), k.want ? k.cfa : Cfa::kMono);
        ++seen;
      }
    }
    EXPECT_EQ(seen, 2);
  }
}

}  // namespace
}  // namespace camsim
