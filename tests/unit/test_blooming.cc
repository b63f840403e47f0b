// Blooming: charge above the full well spills along the column to where the
// model says, charge is conserved (except what leaves the frame), the
// streaming window matches the whole-column reference, and the stage is left
// out when off.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "core/sensor/blooming.h"
#include "core/pipeline/pipeline_ref.h"
#include "core/sensor/blooming_ref.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

// Exposure (1000 photons per unit radiance), CFA, and optionally blooming: photons out.
PipelineConfig PhotonPath(int w, int h, Cfa cfa, bool blooming) {
  PipelineConfig c;
  c.geometry = {w, h, cfa, 12};
  c.exposure.exposure_time_us = 1000.0;
  c.exposure.f_number = 1.0;
  c.exposure.photons_per_radiance_ms = 1000.0;
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kCfa;
  c.order[2] = StageId::kBlooming;
  c.order_count = blooming ? 3 : 2;
  c.blooming.enabled = blooming;
  c.sensor.full_well_e = 1000.0;
  c.sensor.quantum_efficiency[0] = 0.4;
  c.sensor.quantum_efficiency[1] = 0.5;
  c.sensor.quantum_efficiency[2] = 0.625;
  return c;
}

// One call of the stage for row y of `planes` (1 or 3, w x h), as the
// driver makes it: the window's rows y - r .. y + r, clamped to the frame
// (the stage reads those inside it).
void BloomRow(const BloomingStage& stage, const std::vector<const uint32_t*>& planes, int w, int h, int r, int y,
              const std::vector<uint32_t*>& out, std::vector<uint8_t>* state, std::vector<uint64_t>* scratch) {
  std::vector<RowIn> rows(static_cast<size_t>(2 * r + 1));
  for (int k = 0; k < 2 * r + 1; ++k)
    for (size_t c = 0; c < planes.size(); ++c) rows[k].ch[c] = planes[c] + std::clamp(y - r + k, 0, h - 1) * w;
  RowArgs args;
  args.y = y;
  args.width = w;
  args.rows = rows.data();
  args.first_row = y - r;
  args.row_count = 2 * r + 1;
  for (size_t c = 0; c < out.size(); ++c) args.out[c] = out[c];
  args.state = state->data();
  args.scratch = reinterpret_cast<uint8_t*>(scratch->data());
  stage.ProcessRow(args);
}

TEST(Blooming, SpillGoesWhereTheModelSays) {
  constexpr int kW = 4, kH = 64;
  auto b = test::Build(PhotonPath(kW, kH, Cfa::kMono, true));
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  // Background 1000 photons = 500 e- (QE 0.5): every pixel has 500 e- of room.
  test::Scene s = test::FlatScene(kW, kH, 1.0, 1.0, 1.0);
  // Row 30: 5000 photons = 2500 e-: 1500 e- above the well, 750 e- each way.
  for (int c = 0; c < 3; ++c)
    for (int x = 0; x < kW; ++x) s.plane[c][30 * kW + x] = Q<16, 16>::FromDouble(5.0).raw;
  const auto out = test::RunFrame(*b, s, 0, 5);
  for (int y = 0; y < kH; ++y) {
    double e = 500;
    if (y == 30 || y == 31 || y == 29) e = 1000;  // full
    if (y == 32 || y == 28) e = 750;              // the last 250 e- each way
    for (int x = 0; x < kW; ++x) {
      if (e == 1000) {
        EXPECT_EQ(out[y * kW + x], kFullWellPhotons) << "a full well reads saturated; y " << y << " x " << x;
        continue;
      }
      EXPECT_NEAR(out[y * kW + x] / 256.0 * 0.5, e, 0.01) << "y " << y << " x " << x;
    }
  }
}

// Through the sensor, with its PRNU, shot and dark noise: a pixel whose
// well blooming left full reads saturated, as it does without blooming (its
// photons are kFullWellPhotons, not W / QE, on which PRNU below 1 and the
// shot noise would put about half of them below the well).
TEST(Blooming, FullWellsReadSaturatedThroughTheNoisySensor) {
  constexpr int kW = 64, kH = 60;
  test::Scene s = test::FlatScene(kW, kH, 0.5, 0.5, 0.5);  // 500 photons = 250 e- (QE 0.5)
  for (int c = 0; c < 3; ++c)
    for (int i = 20 * kW; i < 40 * kW; ++i) s.plane[c][i] = Q<16, 16>::FromDouble(10.0).raw;  // 5000 e-
  std::vector<uint32_t> dn[2];
  for (const bool blooming : {false, true}) {
    PipelineConfig c = PhotonPath(kW, kH, Cfa::kMono, blooming);
    c.order[c.order_count++] = StageId::kSensor;
    c.sensor.prnu_percent = 2.0;
    auto b = test::Build(c);
    ASSERT_TRUE(b->status.ok()) << b->status.message();
    dn[blooming] = test::RunFrame(*b, s, 3, 16);
  }
  // Rows 20 .. 39 are over the well either way; with blooming, the spill
  // (4000 e- of excess a pixel, half each way, 750 e- of room a pixel, within
  // the stage's window of R = 16 rows) fills at least rows 14 .. 19 and 40 .. 45.
  const auto stats = [&](const std::vector<uint32_t>& v, int y0, int y1) {
    double sum = 0, sum2 = 0;
    for (int y = y0; y <= y1; ++y)
      for (int x = 0; x < kW; ++x) {
        sum += v[y * kW + x];
        sum2 += double(v[y * kW + x]) * v[y * kW + x];
      }
    const double n = double(y1 - y0 + 1) * kW, mean = sum / n;
    return std::pair{mean, std::sqrt(sum2 / n - mean * mean)};
  };
  const auto [mean_off, sd_off] = stats(dn[0], 20, 39);
  EXPECT_LT(sd_off, 2.0) << "saturated: only the read noise after the clip";
  for (const auto& [y0, y1] : {std::pair{20, 39}, {14, 19}, {40, 45}}) {
    const auto [mean, sd] = stats(dn[1], y0, y1);
    EXPECT_NEAR(mean, mean_off, 0.5) << "rows " << y0 << ".." << y1;
    EXPECT_LT(sd, 2.0) << "rows " << y0 << ".." << y1;
  }
}

// A Bayer scene of saturating blobs: the streamed stage against the
// whole-column reference, charge conservation, and strip-height independence.
TEST(Blooming, MatchesWholeColumnReferenceAndConservesCharge) {
  constexpr int kW = 45, kH = 96;  // 45: lanes of 16 (and 8) columns and a tail
  const PipelineConfig with = PhotonPath(kW, kH, Cfa::kBayerRG, true);
  auto bloom = test::Build(with);
  auto plain = test::Build(PhotonPath(kW, kH, Cfa::kBayerRG, false));
  ASSERT_TRUE(bloom->status.ok() && plain->status.ok());
  // Background 0.8 (320..500 e-, so 500..680 e- of room), blobs of 1..2 rows
  // of up to 3750 e- (5500 e- of excess: spills of <= 6 rows each way, well
  // inside the R = 16 window), a different pattern per column; column 0's
  // first blob touches the top row (charge leaves the frame).
  test::Scene s = test::FlatScene(kW, kH, 0.8, 0.8, 0.8);
  for (int x = 0; x < kW; ++x)
    for (int blob = 0; blob < 3; ++blob) {
      const int y0 = (x * 7 + blob * 37) % (kH - 3);
      const int h = 1 + (x + blob) % 2;
      const double r = 2.0 + (x * 13 + blob * 5) % 5;  // radiance 2..6: up to 6000 photons
      for (int y = y0; y < y0 + h; ++y)
        for (int c = 0; c < 3; ++c) s.plane[c][y * kW + x] = Q<16, 16>::FromDouble(r).raw;
    }
  const auto in = test::RunFrame(*plain, s, 0, 16);
  const auto out = test::RunFrame(*bloom, s, 0, 16);
  EXPECT_EQ(test::RunFrame(*bloom, s, 0, 1), out);
  EXPECT_EQ(test::RunFrame(*bloom, s, 0, 37), out);
  const double W = with.sensor.full_well_e;
  double total_ref = 0, total_out = 0, max_err = 0;
  int changed = 0;
  for (int x = 0; x < kW; ++x) {
    std::vector<double> charge(kH);
    std::vector<double> qe(kH);
    for (int y = 0; y < kH; ++y) {
      // The core's QE (Q0.16) and charge: photons (Q24.8) times QE, rounded to Q.8.
      const double qe_q16 = std::round(with.sensor.quantum_efficiency[CfaColour(Cfa::kBayerRG, x, y)] * 65536);
      qe[y] = qe_q16 / 65536.0;
      charge[y] = std::floor(in[y * kW + x] * qe_q16 / 65536.0 + 0.5) / 256.0;
    }
    const std::vector<double> ref = ref::RefBloomColumn(charge, W);
    for (int y = 0; y < kH; ++y) {
      // A full well's marker (kFullWellPhotons) holds exactly W.
      const double got = out[y * kW + x] == kFullWellPhotons && in[y * kW + x] != kFullWellPhotons
                             ? W
                             : out[y * kW + x] / 256.0 * qe[y];
      max_err = std::max(max_err, std::abs(got - ref[y]));
      total_ref += ref[y];
      total_out += got;
      changed += out[y * kW + x] != in[y * kW + x];
      EXPECT_LE(got, W + 0.01);
    }
  }
  EXPECT_GT(changed, kW * 4);  // blooming happened
  // Back to photons rounds to 1/256 photon: < 0.01 e- per pixel.
  EXPECT_LT(max_err, 0.01);
  // The pipeline's reference (camsim tradeoff's) agrees, full wells included.
  ref::RefImage photons{kW, kH, {std::vector<double>(in.size())}};
  for (size_t i = 0; i < in.size(); ++i) photons.planes[0][i] = in[i] / 256.0;
  const ref::RefImage r = ref::RunStageReference(bloom->pipeline, 2, photons, s.View());
  int full = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    ASSERT_NEAR(r.planes[0][i], out[i] / 256.0, 0.05) << i;  // 0.01 e- / QE 0.4, and Q0.16 QE
    full += out[i] == kFullWellPhotons;
  }
  EXPECT_GT(full, kW) << "full wells marked";
  EXPECT_NEAR(total_out, total_ref, 0.01 * kW * kH);
  RecordProperty("max_abs_error_e", std::to_string(max_err));
}

// The stage keeps, per strip, the last row over the well of each column,
// and a following row scans only the row entering its window. A strip that
// starts where another frame's strip ended must scan its whole window again
// (BeginStrip): here frame A has nothing over the well, frame B a row of it
// inside the first window, and B's rows come out as from a strip of its own.
TEST(Blooming, AStripStartsAfreshWhereAnotherFramesStripEnded) {
  constexpr int kW = 24, kH = 40, kR = 4;
  BloomingConfig config;
  config.enabled = true;
  config.rows = kR;
  SensorConfig sensor;
  sensor.full_well_e = 1000.0;
  BloomingStage stage;
  ASSERT_TRUE(stage.Configure(config, sensor, SensorGeometry{kW, kH, Cfa::kMono, 12}).ok());
  // Photons, Q24.8: 100 everywhere; frame B has 5000 (3250 e- at QE 0.65) in row 21.
  std::vector<uint32_t> a(kW * kH, 256u * 100), b = a;
  for (int x = 0; x < kW; ++x) b[21 * kW + x] = 256u * 5000;
  std::vector<uint8_t> state(stage.StateBytes(kW), 0);
  std::vector<uint64_t> scratch(stage.ScratchBytes(kW) / sizeof(uint64_t) + 1);
  const auto row_of = [&](const std::vector<uint32_t>& image, int y) {
    std::vector<uint32_t> out(kW);
    BloomRow(stage, {image.data()}, kW, kH, kR, y, {out.data()}, &state, &scratch);
    return out;
  };
  std::vector<std::vector<uint32_t>> want;  // B's rows 20..29 from a strip that starts at row 12
  stage.BeginStrip(state.data());
  for (int y = 12; y < 30; ++y) {
    const auto out = row_of(b, y);
    if (y >= 20) want.push_back(out);
  }
  EXPECT_NE(want[1], std::vector<uint32_t>(b.begin() + 21 * kW, b.begin() + 22 * kW)) << "no blooming";
  stage.BeginStrip(state.data());
  for (int y = 10; y < 20; ++y) row_of(a, y);  // frame A's strip ends at row 19
  stage.BeginStrip(state.data());
  for (int y = 20; y < 30; ++y) EXPECT_EQ(row_of(b, y), want[y - 20]) << "row " << y;
}

// The model of blooming.h for one pixel, written column by column in the
// stage's integers: charge Q.8 = photons * QE rounded, the down pass and the
// up pass over the window clipped to the frame, back to photons rounded.
uint32_t ModelPixel(const std::vector<uint32_t>& plane, int w, int h, int x, int y, int r,
                    const std::function<uint32_t(int row)>& qe_of_row, uint64_t well) {
  const int first = std::max(0, y - r), last = std::min(h - 1, y + r);
  std::vector<uint64_t> level, excess;
  for (int row = first; row <= last; ++row) {
    const uint64_t m = (uint64_t{plane[row * w + x]} * qe_of_row(row) + (1u << 15)) >> 16;
    level.push_back(std::min(m, well));
    excess.push_back(m - level.back());
  }
  const size_t self = static_cast<size_t>(y - first);
  const uint64_t m_self = level[self] + excess[self];
  uint64_t carry = 0;
  for (size_t k = 0; k < level.size(); ++k) {
    const uint64_t take = std::min(well - level[k], carry);
    level[k] += take;
    carry = carry - take + excess[k] / 2;
  }
  carry = 0;
  for (size_t k = level.size(); k-- > 0;) {
    const uint64_t take = std::min(well - level[k], carry);
    level[k] += take;
    carry = carry - take + (excess[k] - excess[k] / 2);
  }
  const uint64_t q = qe_of_row(y);
  if (q == 0 || level[self] == m_self) return plane[y * w + x];
  if (level[self] == well) return kFullWellPhotons;  // a full well reads saturated
  return static_cast<uint32_t>(std::min<uint64_t>(((level[self] << 16) + q / 2) / q, 0xFFFFFFFFu));
}

// The stage runs columns in groups of 16 lanes. Against the column-by-column
// model, byte for byte: a width of two whole groups and a partial one,
// spills in a single column of a group, in a group's first and last columns
// and in the partial group, at the frame's top and bottom, a colour with QE
// 0 (it keeps its input), input pixels at 2^32 - 1, for a Bayer mosaic and
// for three channels.
TEST(Blooming, GroupsOfColumnsGiveTheColumnModelsBytes) {
  constexpr int kW = 37, kH = 30, kR = 5;
  for (const int channels : {1, 3}) {
    SCOPED_TRACE(channels);
    BloomingConfig config;
    config.enabled = true;
    config.rows = kR;
    SensorConfig sensor;
    sensor.full_well_e = 1000.0;
    sensor.quantum_efficiency[0] = 0.0;  // red: no charge
    sensor.quantum_efficiency[1] = 0.55;
    sensor.quantum_efficiency[2] = 0.7;
    const Cfa cfa = channels == 1 ? Cfa::kBayerGR : Cfa::kMono;
    BloomingStage stage;
    ASSERT_TRUE(stage.Configure(config, sensor, SensorGeometry{kW, kH, cfa, 12}).ok());
    const auto qe_q16 = [&](int colour) {
      return static_cast<uint32_t>(std::lround(sensor.quantum_efficiency[colour] * 65536));
    };
    // Photons, Q24.8: a textured background of 200..1000 photons, then blobs.
    std::vector<std::vector<uint32_t>> planes(channels, std::vector<uint32_t>(kW * kH));
    for (int c = 0; c < channels; ++c)
      for (int i = 0; i < kW * kH; ++i) planes[c][i] = 256u * (200 + static_cast<uint32_t>((i * 7919 + c * 31) % 800));
    const struct Blob {
      int x, y, rows;
      uint32_t photons;
    } blobs[] = {{3, 12, 2, 6000},      {16, 0, 2, 9000},  {31, 28, 2, 5000}, {15, 20, 1, 4000},
                 {34, 7, 3, 20000},     {36, 15, 1, 7000}, {22, 25, 1, 0xFFFFFFFFu / 256}};
    for (const Blob& b : blobs)
      for (int c = 0; c < channels; ++c)
        for (int y = b.y; y < b.y + b.rows; ++y) planes[c][y * kW + b.x] = b.photons == 0xFFFFFFFFu / 256 ? 0xFFFFFFFFu : 256u * b.photons;
    std::vector<uint8_t> state(stage.StateBytes(kW), 0);
    std::vector<uint64_t> scratch(stage.ScratchBytes(kW) / sizeof(uint64_t) + 1);
    stage.BeginStrip(state.data());
    std::vector<std::vector<uint32_t>> out(channels, std::vector<uint32_t>(kW * kH));
    for (int y = 0; y < kH; ++y) {
      std::vector<const uint32_t*> in;
      std::vector<uint32_t*> row_out;
      for (int c = 0; c < channels; ++c) {
        in.push_back(planes[c].data());
        row_out.push_back(out[c].data() + y * kW);
      }
      BloomRow(stage, in, kW, kH, kR, y, row_out, &state, &scratch);
    }
    int changed = 0;
    for (int c = 0; c < channels; ++c)
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
          const auto qe_of_row = [&](int row) { return qe_q16(channels == 3 ? c : CfaColour(cfa, x, row)); };
          const uint32_t want = ModelPixel(planes[c], kW, kH, x, y, kR, qe_of_row, 1000u * 256);
          ASSERT_EQ(out[c][y * kW + x], want) << "channel " << c << " x " << x << " y " << y;
          changed += want != planes[c][y * kW + x];
        }
    EXPECT_GT(changed, 40) << "blooming happened";
    if (channels == 1) {  // column 3 of BayerGR: red (QE 0) on even rows, green on odd ones
      EXPECT_EQ(out[0][14 * kW + 3], planes[0][14 * kW + 3]) << "a QE-0 pixel the spill passes keeps its input";
      EXPECT_NE(out[0][15 * kW + 3], planes[0][15 * kW + 3]) << "the spill passes it";
    }
  }
}

TEST(Blooming, ChargeIsConservedAwayFromTheBorders) {
  // One column, one blob in the middle: nothing reaches the frame's ends.
  std::vector<double> col(200, 300.0);
  col[100] = 9000.0;
  col[101] = 4000.0;
  const std::vector<double> out = ref::RefBloomColumn(col, 1000.0);
  double in_sum = 0, out_sum = 0;
  for (size_t i = 0; i < col.size(); ++i) {
    in_sum += col[i];
    out_sum += out[i];
    EXPECT_LE(out[i], 1000.0);
  }
  EXPECT_DOUBLE_EQ(out_sum, in_sum);
  // 11000 e- of excess, 5500 e- each way, 700 e- of room per pixel: seven
  // pixels filled and 600 e- into the eighth on each side.
  for (int k = 1; k <= 7; ++k) {
    EXPECT_EQ(out[100 - k], 1000.0) << k;
    EXPECT_EQ(out[101 + k], 1000.0) << k;
  }
  EXPECT_EQ(out[92], 900.0);
  EXPECT_EQ(out[109], 900.0);
  EXPECT_EQ(out[91], 300.0);
  EXPECT_EQ(out[110], 300.0);
}

TEST(Blooming, LeftOutWhenOff) {
  PipelineConfig c = PhotonPath(8, 8, Cfa::kMono, false);
  c.order_count = 3;
  auto b = test::Build(c);
  ASSERT_TRUE(b->status.ok());
  const Plan& p = b->pipeline.plan();
  bool found = false;
  for (int i = 0; i < p.count; ++i)
    if (p.entries[i].id == StageId::kBlooming) {
      found = true;
      EXPECT_FALSE(p.entries[i].runs);
      EXPECT_NE(std::string(p.entries[i].reason).find("blooming"), std::string::npos);
    }
  EXPECT_TRUE(found);
}

TEST(Blooming, RowsOutOfRangeNameTheKey) {
  PipelineConfig c = PhotonPath(8, 8, Cfa::kMono, true);
  c.blooming.rows = 65;
  auto b = test::Build(c);
  EXPECT_FALSE(b->status.ok());
  EXPECT_EQ(std::string(b->status.field()), "blooming.rows");
}

}  // namespace
}  // namespace camsim
