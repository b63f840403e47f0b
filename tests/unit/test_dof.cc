// Depth of field and structural blur (core/lens/dof.h) against the double
// references (dof_ref.h): CoC, the fixed-point line solver on stiff and
// ragged coefficients, the column window, both methods, strip invariance.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "core/lens/dof.h"
#include "core/lens/dof_ref.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

DofConfig LensConfig() {
  DofConfig c;
  c.focal_length_mm = 28.0;
  c.pixel_pitch_um = 5.0;
  c.focus_distance_m = 3.0;
  c.max_coc_px = 64.0;
  c.min_coc_px = 0.5;
  return c;
}

// A pipeline of only the depth-of-field stages, radiance in and out.
PipelineConfig DofPipeline(int w, int h, DofMethod method) {
  PipelineConfig p;
  p.geometry.width = w;
  p.geometry.height = h;
  p.dof = LensConfig();
  p.dof.method = method;
  p.exposure.f_number = 2.8;
  p.order[0] = StageId::kDofGather;
  p.order[1] = StageId::kDofRows;
  p.order[2] = StageId::kDofColumns;
  p.order_count = 3;
  return p;
}

std::vector<uint32_t> RunDof(const PipelineConfig& p, const test::Scene& s, int strip, WorkerStats* stats = nullptr) {
  auto b = test::Build(p);
  EXPECT_TRUE(b->status.ok()) << b->status.message();
  EXPECT_TRUE(b->pipeline.CheckInput(s.View()).ok());
  return test::RunFrame(*b, s, 0, strip, stats);
}

// The scene's depth plane from a function of (x, y) in metres.
template <typename F>
void SetDepth(test::Scene* s, F depth) {
  s->inverse_depth.resize(static_cast<size_t>(s->width) * s->height);
  for (int y = 0; y < s->height; ++y)
    for (int x = 0; x < s->width; ++x)
      s->inverse_depth[static_cast<size_t>(y) * s->width + x] = InverseDepthFromMetres(depth(x, y));
}

// ---------------------------------------------------------------- CoC

TEST(DofCoc, MatchesThinLensFormula) {
  const DofConfig c = LensConfig();
  CocModel m;
  ASSERT_TRUE(m.Configure(c, 2.8).ok());
  // Tolerance: the output LSB (1/256), the inverse-depth rounding (K * 2^-21,
  // K = f^2 z_f / (N (z_f - f)) / pitch px m) and 2^-31 relative for the scale.
  const double f = 0.028, K = f * f * 3.0 / (2.8 * (3.0 - f)) / 5e-6;
  for (double z : {0.2, 0.5, 1.0, 2.0, 2.9, 2.99, 3.0, 3.01, 3.2, 5.0, 10.0, 100.0, 1e4, 1e10}) {
    const double ref = ReferenceCocPixels(c, 2.8, z);
    const double got = m.Coc(InverseDepthFromMetres(z)) / 256.0;
    EXPECT_NEAR(got, ref, 1.0 / 256 + K * std::ldexp(1.0, -21) + 1e-9 * ref) << "z = " << z;
  }
  EXPECT_EQ(m.Coc(InverseDepthFromMetres(3.0)), 0u) << "the focus distance is sharp";
}

TEST(DofCoc, SpecialDepths) {
  const DofConfig c = LensConfig();
  CocModel m;
  ASSERT_TRUE(m.Configure(c, 2.8).ok());
  const double inf_coc = 0.028 * 0.028 / (2.8 * (3.0 - 0.028)) / 5e-6;  // 18.8 px
  // 1e10 m (the bundled sky), +inf and NaN: the CoC of infinity.
  for (double z : {1e10, double(INFINITY), double(NAN)}) {
    EXPECT_EQ(InverseDepthFromMetres(z), 0u) << z;
    EXPECT_NEAR(m.Coc(InverseDepthFromMetres(z)) / 256.0, inf_coc, 1.0 / 256) << z;
    EXPECT_NEAR(ReferenceCocPixels(c, 2.8, z), inf_coc, 1e-6) << z;
  }
  // 0: the nearest depth, blur capped at max_coc.
  EXPECT_EQ(InverseDepthFromMetres(0.0), kMaxInverseDepth);
  EXPECT_EQ(m.Coc(InverseDepthFromMetres(0.0)), 64u * 256);
  EXPECT_EQ(ReferenceCocPixels(c, 2.8, 0.0), 64.0);
  // Negative and -inf: no depth, left sharp.
  for (double z : {-1.0, -1e-30, -double(INFINITY)}) {
    EXPECT_EQ(InverseDepthFromMetres(z), kInvalidInverseDepth) << z;
    EXPECT_EQ(m.Coc(InverseDepthFromMetres(z)), 0u) << z;
    EXPECT_EQ(ReferenceCocPixels(c, 2.8, z), 0.0) << z;
  }
}

TEST(DofCoc, LargerFNumberLessBlur) {
  const DofConfig c = LensConfig();
  CocModel m2, m8;
  ASSERT_TRUE(m2.Configure(c, 2.0).ok());
  ASSERT_TRUE(m8.Configure(c, 8.0).ok());
  for (double z : {0.5, 1.0, 10.0, 1e10}) {
    const uint32_t a = m2.Coc(InverseDepthFromMetres(z)), b = m8.Coc(InverseDepthFromMetres(z));
    EXPECT_GT(a, b) << z;
    if (a < 64u * 256) {
      EXPECT_NEAR(a / 4.0, b, 2.0) << "CoC goes as 1/N, z = " << z;
    }
  }
}

TEST(DofCoc, ConfigErrorsNameTheKey) {
  DofConfig c = LensConfig();
  CocModel m;
  c.focus_distance_m = 0.01;  // inside the focal length
  EXPECT_EQ(std::string(m.Configure(c, 2.8).field()), "dof.focus_distance_m");
  c = LensConfig();
  c.pixel_pitch_um = 0.0;
  EXPECT_EQ(std::string(m.Configure(c, 2.8).field()), "sensor.pixel_pitch_um");
  c = LensConfig();
  c.max_coc_px = 5000;
  EXPECT_EQ(std::string(m.Configure(c, 2.8).field()), "dof.max_coc_px");
}

// ---------------------------------------------------------------- line solver

struct LineCase {
  const char* name;
  std::vector<double> beta;  // [0 .. n], ends ignored
};

uint32_t BetaRaw(double b) {
  const double r = std::floor(b * 4096.0 + 0.5);
  return r >= 4294967295.0 ? dof::kMaxBeta : static_cast<uint32_t>(r);
}

std::vector<LineCase> LineCases(int n) {
  std::vector<LineCase> cases;
  auto constant = [n](double b) { return std::vector<double>(static_cast<size_t>(n + 1), b); };
  for (double b : {0.0, 1e-2, 1.0, 100.0, 1e4, 1e6}) {
    static char names[6][32];
    static int k = 0;
    std::snprintf(names[k % 6], sizeof names[0], "constant %g", b);
    cases.push_back({names[k++ % 6], constant(b)});
  }
  std::vector<double> step = constant(1e-2);
  for (int i = n / 2; i <= n; ++i) step[static_cast<size_t>(i)] = 1e6;
  cases.push_back({"step 1e-2 | 1e6", step});
  std::vector<double> alt = constant(1e-2);
  for (int i = 0; i <= n; i += 2) alt[static_cast<size_t>(i)] = 1e6;
  cases.push_back({"alternating 1e-2 / 1e6 (ratio 1e8)", alt});
  std::mt19937 rng(7);
  std::vector<double> rnd(static_cast<size_t>(n + 1));
  for (double& b : rnd) {
    const double e = std::uniform_real_distribution<double>(-2.0, 6.0)(rng);
    b = (rng() % 10 == 0) ? 0.0 : std::pow(10.0, e);  // log-uniform 1e-2 .. 1e6, 10 % zero links
  }
  cases.push_back({"random log-uniform 1e-2 .. 1e6 with zeros", rnd});
  return cases;
}

// Solves a line in fixed point and in double; returns the max error in LSB.
struct LineResult {
  double max_err = 0, mass_err = 0;
  bool in_range = true;
};
LineResult SolveBoth(const std::vector<double>& beta_d, const std::vector<uint32_t>& x, int n) {
  std::vector<uint32_t> beta(static_cast<size_t>(n + 1));
  std::vector<double> bq(static_cast<size_t>(n + 1)), xd(x.begin(), x.end()), yd(static_cast<size_t>(n));
  for (int i = 0; i <= n; ++i) {
    beta[static_cast<size_t>(i)] = BetaRaw(beta_d[static_cast<size_t>(i)]);
    bq[static_cast<size_t>(i)] = beta[static_cast<size_t>(i)] / 4096.0;  // the reference solves the same b
  }
  std::vector<uint32_t> line = x;
  std::vector<uint8_t> work(dof::LineWorkBytes(n) + 64);
  uint8_t* aligned = work.data() + (64 - reinterpret_cast<uintptr_t>(work.data()) % 64) % 64;
  uint32_t* lines[1] = {line.data()};
  dof::SolveLine(lines, 1, beta.data(), n, aligned);
  ReferenceSolveLine(xd.data(), bq.data(), n, yd.data());
  LineResult r;
  const uint32_t lo = *std::min_element(x.begin(), x.end()), hi = *std::max_element(x.begin(), x.end());
  double sx = 0, sy = 0;
  for (int i = 0; i < n; ++i) {
    r.max_err = std::max(r.max_err, std::fabs(line[static_cast<size_t>(i)] - yd[static_cast<size_t>(i)]));
    r.in_range = r.in_range && line[static_cast<size_t>(i)] >= lo && line[static_cast<size_t>(i)] <= hi;
    sx += x[static_cast<size_t>(i)];
    sy += line[static_cast<size_t>(i)];
  }
  r.mass_err = std::fabs(sy - sx);
  return r;
}

// Stated bounds (measured maxima are printed): error vs the double solve
// <= 1 LSB + 2^-24 of the line's range (0.5 from the final rounding; the
// weights r, e are Q.30, absolute error 2^-31, and at b = 1e6 the response
// spans ~1000 samples, so their error is relative to the range, not to the
// LSB: 0.5 LSB at radiance 16, ~235 LSB measured for a 2^32 range); line
// sum within n (1/2 + 2^-24 range) LSB; output within [min, max] exactly.
double LineBound(double range) { return 1.0 + std::ldexp(range, -24); }
constexpr double kMaxLineErrLsb = 2.0;  // per pass, for radiance up to 64 (range < 2^22)

TEST(DofSolver, StiffAndRaggedLinesMatchDoubleThomas) {
  const int n = 1024;
  std::mt19937 rng(3);
  for (const LineCase& lc : LineCases(n)) {
    for (uint32_t amplitude : {1u << 20, 0xFFFFFFFFu}) {  // radiance 16, and the full Q16.16 range
      std::vector<uint32_t> x(static_cast<size_t>(n));
      for (int i = 0; i < n; ++i) {
        // Edges, a ramp and noise: content the diffusion actually moves.
        const double v = ((i / 37) % 2 ? 0.8 : 0.1) + 0.1 * std::sin(i * 0.05) + 0.05 * (rng() % 1000) / 1000.0;
        x[static_cast<size_t>(i)] = static_cast<uint32_t>(v * amplitude);
      }
      const LineResult r = SolveBoth(lc.beta, x, n);
      std::printf("  %-45s amplitude %10u: max err %.3f LSB, |sum err| %.1f LSB\n", lc.name, amplitude, r.max_err,
                  r.mass_err);
      EXPECT_LE(r.max_err, LineBound(amplitude)) << lc.name;
      EXPECT_LE(r.mass_err, n * (0.5 + std::ldexp(amplitude, -24))) << lc.name;
      if (amplitude < (1u << 22)) {
        EXPECT_LE(r.max_err, kMaxLineErrLsb) << lc.name;
      }
      EXPECT_TRUE(r.in_range) << lc.name;
    }
  }
}

TEST(DofSolver, WideAndSplitProductsAgree) {
  // The 128-bit product (x86-64, aarch64) and the split one (armhf) must give
  // the same bits, including the extremes of both operands.
  std::mt19937_64 rng(11);
  const int64_t kD = (int64_t{1} << 49) - 1;
  for (int i = 0; i < 2000000; ++i) {
    int64_t d = static_cast<int64_t>(rng() % (2 * static_cast<uint64_t>(kD) + 1)) - kD;
    uint32_t w = static_cast<uint32_t>(rng() % ((1u << 30) + 1));
    if (i < 64) {  // the extremes
      d = (i & 1) ? kD : -kD;
      w = (i & 2) ? (1u << 30) : static_cast<uint32_t>(i >> 2);
    }
    ASSERT_EQ(dof::MulQ30(d, w), dof::MulQ30Split(d, w)) << d << " * " << w;
  }
  // Ties round up: 2^29 / 2^30 = 0.5 -> 1; -0.5 -> 0.
  EXPECT_EQ(dof::MulQ30Split(1, 1u << 29), 1);
  EXPECT_EQ(dof::MulQ30Split(-1, 1u << 29), 0);
}

TEST(DofSolver, RowUpdatesInLanesMatchScalar) {
  CAMSIM_SKIP_WITHOUT_LANE_KERNELS();
  // PullRow and BackRow (AVX-512 or AVX2 lanes on x86-64) against MulQ30 and OutOf one
  // by one, over the whole contract: |difference| < 2^49, weights 0 .. 2^30,
  // y on both sides of the output range (saturation), every tail length.
  std::mt19937_64 rng(17);
  const int64_t kD = (int64_t{1} << 49) - 1;
  const int n = 4099;
  std::vector<int64_t> u(n), us(n), y(n);
  std::vector<uint32_t> in(n), w(n), out(n + 1);
  for (int round = 0; round < 40; ++round) {
    for (int x = 0; x < n; ++x) {
      in[x] = static_cast<uint32_t>(rng());
      w[x] = static_cast<uint32_t>(rng() % ((1u << 30) + 1));
      if (x % 61 == 0) w[x] = (x & 64) ? (1u << 30) : 0u;
      u[x] = static_cast<int64_t>(rng() % (uint64_t{1} << 48));  // sweep state: a radiance Q16.32
      y[x] = static_cast<int64_t>(rng() % (2 * static_cast<uint64_t>(kD) + 1)) - kD / 2;
      us[x] = std::clamp<int64_t>(y[x] + static_cast<int64_t>(rng() % (2 * static_cast<uint64_t>(kD) + 1)) - kD,
                                  y[x] - kD, y[x] + kD);
    }
    const int count = n - round % 8;  // each tail length (n = 4099: 3 .. 7 and 0 .. 2 mod 8)
    std::vector<int64_t> u_want = u, y_want = y;
    std::vector<uint32_t> out_want(n + 1, 0xDEADBEEFu);
    for (int x = 0; x < count; ++x) {
      u_want[x] += dof::MulQ30((int64_t{in[x]} << dof::kGuardBits) - u_want[x], w[x]);
      if (round % 2 == 0) y_want[x] += dof::MulQ30(us[x] - y_want[x], w[x]);
      out_want[x] = SatU32(RoundShift(y_want[x], dof::kGuardBits));
    }
    std::fill(out.begin(), out.end(), 0xDEADBEEFu);
    dof::PullRow(u.data(), in.data(), w.data(), count);
    dof::BackRow(y.data(), us.data(), round % 2 == 0 ? w.data() : nullptr, out.data(), count);
    for (int x = 0; x < n; ++x) {
      ASSERT_EQ(u[x], u_want[x]) << "PullRow, round " << round << " x " << x;
      ASSERT_EQ(y[x], y_want[x]) << "BackRow, round " << round << " x " << x;
      ASSERT_EQ(out[x], out_want[x]) << "BackRow out, round " << round << " x " << x;
    }
  }
}

TEST(DofSolver, LinesTogetherMatchOneByOne) {
  // SolveLines (eight lines in AVX-512 lanes where the CPU has them) against
  // SolveLine one line at a time: every line count, lengths around the
  // transposes' blocks of 8, links with zero runs and lone samples, samples
  // up to 2^32 - 1, and non-zero ignored end links.
  std::mt19937 rng(23);
  for (int n : {1, 2, 7, 8, 9, 16, 333, 1027}) {
    std::vector<LineCase> cases = LineCases(n);
    std::vector<double> sparse(static_cast<size_t>(n + 1));  // mostly unlinked: lone samples and short runs
    for (double& b : sparse) b = rng() % 3 == 0 ? std::pow(10.0, static_cast<double>(rng() % 7) - 1.0) : 0.0;
    cases.push_back({"sparse", sparse});
    for (int count = 1; count <= dof::kLaneLines; ++count) {
      std::vector<std::vector<uint32_t>> in(static_cast<size_t>(count)), out(in.size()), want(in.size());
      std::vector<std::vector<uint32_t>> beta(in.size());
      std::vector<dof::LineIo> lines(in.size());
      std::vector<int32_t> want_solved(in.size()), solved(in.size(), -1);
      std::vector<uint8_t> work(std::max(dof::LinesWorkBytes(n), dof::LineWorkBytes(n)) + 64);
      uint8_t* aligned = work.data() + (64 - reinterpret_cast<uintptr_t>(work.data()) % 64) % 64;
      for (int j = 0; j < count; ++j) {
        const LineCase& lc = cases[static_cast<size_t>(j + count) % cases.size()];
        std::vector<uint32_t>& b = beta[static_cast<size_t>(j)];
        b.resize(static_cast<size_t>(n + 1));
        for (int i = 0; i <= n; ++i) b[static_cast<size_t>(i)] = BetaRaw(lc.beta[static_cast<size_t>(i)]);
        b[0] = b[static_cast<size_t>(n)] = 4096;  // ignored
        in[static_cast<size_t>(j)].resize(3 * static_cast<size_t>(n));
        for (uint32_t& v : in[static_cast<size_t>(j)]) v = rng() % 4 == 0 ? 0xFFFFFFFFu - rng() % 3 : rng();
        want[static_cast<size_t>(j)] = in[static_cast<size_t>(j)];
        uint32_t* w3[3];
        for (int c = 0; c < 3; ++c) w3[c] = want[static_cast<size_t>(j)].data() + static_cast<size_t>(c) * n;
        want_solved[static_cast<size_t>(j)] = dof::SolveLine(w3, 3, b.data(), n, aligned);
        out[static_cast<size_t>(j)].assign(3 * static_cast<size_t>(n), 0xDEADBEEFu);
        for (int c = 0; c < 3; ++c) {
          lines[static_cast<size_t>(j)].in[c] = in[static_cast<size_t>(j)].data() + static_cast<size_t>(c) * n;
          lines[static_cast<size_t>(j)].out[c] = out[static_cast<size_t>(j)].data() + static_cast<size_t>(c) * n;
        }
        lines[static_cast<size_t>(j)].beta = b.data();
      }
      // Skipping off (Stage::set_skip_idle) steps and sweeps the unlinked
      // samples too: the same bytes and counts.
      for (const bool skip : {true, false}) {
        for (std::vector<uint32_t>& o : out) std::fill(o.begin(), o.end(), 0xDEADBEEFu);
        dof::SolveLines(lines.data(), count, n, aligned, solved.data(), skip);
        for (int j = 0; j < count; ++j) {
          ASSERT_EQ(solved[static_cast<size_t>(j)], want_solved[static_cast<size_t>(j)]) << "n " << n << " line " << j;
          for (int i = 0; i < 3 * n; ++i)
            ASSERT_EQ(out[static_cast<size_t>(j)][static_cast<size_t>(i)], want[static_cast<size_t>(j)][static_cast<size_t>(i)])
                << "n " << n << " lines " << count << " line " << j << " channel " << i / n << " x " << i % n
                << " skip " << skip;
        }
        if (skip) continue;
        for (int j = 0; j < count; ++j) {  // and one by one
          std::vector<uint32_t> one = in[static_cast<size_t>(j)];
          uint32_t* o3[3];
          for (int c = 0; c < 3; ++c) o3[c] = one.data() + static_cast<size_t>(c) * n;
          ASSERT_EQ(dof::SolveLine(o3, 3, beta[static_cast<size_t>(j)].data(), n, aligned, false),
                    want_solved[static_cast<size_t>(j)]);
          ASSERT_EQ(one, want[static_cast<size_t>(j)]) << "n " << n << " line " << j << " solved one by one, skip off";
        }
      }
    }
  }
}

TEST(DofSolver, ConstantLineStaysExactlyConstant) {
  const int n = 333;
  for (const LineCase& lc : LineCases(n)) {
    for (uint32_t v : {0u, 1u, 65536u, 0xFFFFFFFFu}) {
      std::vector<uint32_t> line(static_cast<size_t>(n), v), beta(static_cast<size_t>(n + 1));
      for (int i = 0; i <= n; ++i) beta[static_cast<size_t>(i)] = BetaRaw(lc.beta[static_cast<size_t>(i)]);
      std::vector<uint8_t> work(dof::LineWorkBytes(n) + 64);
      uint8_t* aligned = work.data() + (64 - reinterpret_cast<uintptr_t>(work.data()) % 64) % 64;
      uint32_t* lines[1] = {line.data()};
      dof::SolveLine(lines, 1, beta.data(), n, aligned);
      for (uint32_t y : line) ASSERT_EQ(y, v) << lc.name;
    }
  }
}

TEST(DofSolver, ImpulseSpreadsSymmetricallyAndConservesMass) {
  const int n = 401;
  std::vector<uint32_t> line(static_cast<size_t>(n), 0), beta(static_cast<size_t>(n + 1), BetaRaw(25.0));
  line[200] = 1u << 30;
  std::vector<uint8_t> work(dof::LineWorkBytes(n) + 64);
  uint8_t* aligned = work.data() + (64 - reinterpret_cast<uintptr_t>(work.data()) % 64) % 64;
  uint32_t* lines[1] = {line.data()};
  dof::SolveLine(lines, 1, beta.data(), n, aligned);
  int64_t sum = 0;
  for (uint32_t v : line) sum += v;
  EXPECT_LE(std::llabs(sum - (int64_t{1} << 30)), n / 2 + 1);
  for (int d = 1; d < 150; ++d) EXPECT_LE(std::abs(int64_t{line[200 - d]} - int64_t{line[200 + d]}), 1) << d;
  EXPECT_GT(line[200], line[201]);
  EXPECT_GT(line[201], line[205]);
}

TEST(DofCoc, Cc2RowInLanesMatchesDiffusionCoc) {
  // DiffusionCc2Row (AVX2 or AVX-512 lanes on x86-64) against DiffusionCoc
  // squared, for lenses from barely any blur to the cap everywhere, at the
  // special depths, both sides of the focus and of min_coc, and every tail
  // length after groups of eight.
  struct Lens { double f_number, focus_m, max_coc, min_coc, scale; };
  const Lens lenses[] = {{2.0, 3.0, 64.0, 0.5, 0.17677669529663687}, {1.4, 1.0, 1023.0, 0.0, 1.0},
                         {16.0, 100.0, 0.25, 0.25, 0.01}, {0.5, 0.05, 1023.0, 1.0, 0.5}};
  std::mt19937_64 rng(23);
  for (const Lens& lens : lenses) {
    DofConfig c = LensConfig();
    c.focus_distance_m = lens.focus_m;
    c.max_coc_px = lens.max_coc;
    c.min_coc_px = lens.min_coc;
    c.diffusion_scale = lens.scale;
    CocModel m;
    ASSERT_TRUE(m.Configure(c, lens.f_number).ok());
    const uint32_t f = m.focus();
    std::vector<uint32_t> iz = {0u, 1u, kInvalidInverseDepth, kInvalidInverseDepth - 1, kMaxInverseDepth, f};
    for (const uint32_t d : {m.min_diff() - 1, m.min_diff(), m.min_diff() + 1})  // min_coc's edge, both sides
      if (d <= f) iz.insert(iz.end(), {f + d, f - d});
    for (uint32_t step = 1; step < (1u << 31); step *= 3)
      for (int sgn : {-1, 1}) iz.push_back(f + static_cast<uint32_t>(sgn) * step);
    while (iz.size() < 4003) iz.push_back(static_cast<uint32_t>(rng()) >> (rng() % 32));
    const int n = static_cast<int>(iz.size());
    for (int count = n - 7; count <= n; ++count) {
      std::vector<uint64_t> cc2(static_cast<size_t>(n), 0xDEADBEEFull);
      m.DiffusionCc2Row(iz.data(), count, cc2.data());
      for (int x = 0; x < n; ++x) {
        const uint64_t coc = m.DiffusionCoc(iz[static_cast<size_t>(x)]);
        ASSERT_EQ(cc2[static_cast<size_t>(x)], x < count ? coc * coc : 0xDEADBEEFull)
            << "f/" << lens.f_number << " iz " << iz[static_cast<size_t>(x)] << " at " << x << " of " << count;
      }
    }
  }
}

// ---------------------------------------------------------------- 2-D diffusion

// The stage's own squared diffusion CoC per pixel, as the reference's input.
std::vector<double> StageCc2(const test::Scene& s, const PipelineConfig& p) {
  CocModel m;
  EXPECT_TRUE(m.Configure(p.dof, p.exposure.f_number).ok());
  std::vector<double> cc2(s.inverse_depth.size());
  for (size_t i = 0; i < cc2.size(); ++i) {
    const uint64_t c = m.DiffusionCoc(s.inverse_depth[i]);
    cc2[i] = dof::BetaOf(c * c, c * c) / 4096.0;  // min then round == round then min
  }
  return cc2;
}

struct Err2 {
  double max = 0, rms = 0;
};
Err2 Compare(const std::vector<uint32_t>& got, const std::vector<double>& ref, int channel) {
  Err2 e;
  double s2 = 0;
  for (size_t i = 0; i < ref.size(); ++i) {
    const double d = std::fabs(got[3 * i + static_cast<size_t>(channel)] - ref[i]);
    e.max = std::max(e.max, d);
    s2 += d * d;
  }
  e.rms = std::sqrt(s2 / ref.size());
  return e;
}

std::vector<double> PlaneD(const test::Scene& s, int c) { return std::vector<double>(s.plane[c].begin(), s.plane[c].end()); }

TEST(DofDiffusion, ColumnWindowSweepErrorFalls) {
  const int w = 64, h = 200;
  test::Scene s = test::TexturedScene(w, h);
  SetDepth(&s, [](int x, int) { return 1.0 + 0.002 * x; });  // CoC ~ 38 .. 34 px diameter
  for (double scale : {0.17677669529663687, 1.0}) {  // b ~ 44 (default) and ~1400 (a ~37-row response)
    PipelineConfig p = DofPipeline(w, h, DofMethod::kDiffusion);
    p.dof.diffusion_scale = scale;
    const std::vector<double> cc2 = StageCc2(s, p);
    const std::vector<double> full = ReferenceDiffusion(PlaneD(s, 1), cc2, w, h, -1);
    const double peak = *std::max_element(full.begin(), full.end());
    double prev = 1e300;
    std::printf("  diffusion_scale %.3f (peak %.0f LSB):\n", scale, peak);
    for (int window : {2, 4, 8, 16, 32, 64, 128, 256}) {
      p.dof.column_window = window;
      const std::vector<uint32_t> out = RunDof(p, s, 32);
      const Err2 e = Compare(out, full, 1);
      const Err2 ew = Compare(out, ReferenceDiffusion(PlaneD(s, 1), cc2, w, h, window, DofColumnStage::kBlock), 1);
      std::printf("    window %3d: vs whole columns max %10.2f rms %10.3f LSB; vs windowed reference max %.2f LSB\n",
                  window, e.max, e.rms, ew.max);
      EXPECT_LE(ew.max, 2 * kMaxLineErrLsb) << "fixed point vs the same windowed system, window " << window;
      if (prev > 2.0) {
        EXPECT_LT(e.max, prev) << "the error falls as the window grows, window " << window;
      }
      prev = e.max;
    }
    // The largest window reaches the fixed-point floor (the frame is 200 rows).
    EXPECT_LE(prev, 2 * kMaxLineErrLsb);
  }
}

TEST(DofDiffusion, StiffDepthEdgesStayInRangeAndAccurate) {
  const int w = 80, h = 60;
  test::Scene s = test::TexturedScene(w, h);
  // Depth jumps between near (huge CoC, capped) and focus: b from 0 to ~1e6.
  SetDepth(&s, [](int x, int y) { return ((x / 7 + y / 5) % 3 == 0) ? 3.0 : ((x + y) % 2 ? 0.05 : 1e10); });
  PipelineConfig p = DofPipeline(w, h, DofMethod::kDiffusion);
  p.dof.max_coc_px = 1023;
  p.dof.diffusion_scale = 1.0;
  p.dof.column_window = 64;
  const std::vector<double> cc2 = StageCc2(s, p);
  const std::vector<uint32_t> out = RunDof(p, s, 16);
  for (int c = 0; c < 3; ++c) {
    const Err2 e = Compare(out, ReferenceDiffusion(PlaneD(s, c), cc2, w, h, 64, DofColumnStage::kBlock), c);
    std::printf("  channel %d: max %.2f LSB vs the windowed double solve\n", c, e.max);
    EXPECT_LE(e.max, 2 * kMaxLineErrLsb);  // two passes
    const uint32_t lo = *std::min_element(s.plane[c].begin(), s.plane[c].end());
    const uint32_t hi = *std::max_element(s.plane[c].begin(), s.plane[c].end());
    for (size_t i = 0; i < s.plane[c].size(); ++i) {
      ASSERT_GE(out[3 * i + static_cast<size_t>(c)], lo);
      ASSERT_LE(out[3 * i + static_cast<size_t>(c)], hi);
    }
  }
}

TEST(DofDiffusion, BitExactForEveryStripHeightAndThreads) {
  const int w = 57, h = 73;
  test::Scene s = test::TexturedScene(w, h);
  SetDepth(&s, [](int x, int y) { return 0.5 + 0.05 * x + 0.02 * y; });
  for (DofMethod m : {DofMethod::kDiffusion, DofMethod::kGather}) {
    PipelineConfig p = DofPipeline(w, h, m);
    p.dof.column_window = 9;
    p.dof.max_radius_px = 7;
    const std::vector<uint32_t> ref = RunDof(p, s, h);
    // Strips that start and end inside a column block (kBlock = 32) too.
    for (int strip : {1, 2, 5, 7, 16, 40, 64}) EXPECT_EQ(RunDof(p, s, strip), ref) << "strip " << strip;
    for (int threads = 1; threads <= 4; ++threads) {
      auto b = test::Build(p, threads);
      ASSERT_TRUE(b->status.ok());
      for (int strip : {1, 7, 64}) EXPECT_EQ(test::RunFrameThreads(*b, s, 0, strip, threads), ref) << threads << " " << strip;
    }
    // Every sample written, and the depth ramp blurred most of them: equal
    // outputs of a stage that did nothing would prove nothing.
    size_t changed = 0;
    for (size_t i = 0; i < ref.size(); ++i) {
      ASSERT_NE(ref[i], test::kUnwritten) << "sample " << i << " never written";
      changed += ref[i] != s.plane[i % 3][i / 3];
    }
    EXPECT_GT(changed, ref.size() / 2) << "method " << static_cast<int>(m);
    RecordProperty(m == DofMethod::kDiffusion ? "diffusion_changed" : "gather_changed", std::to_string(changed));
  }
}

// dof_columns keeps a solved block between rows (strip state): a block solved
// for one frame must never be read for the next one, whose rows differ.
TEST(DofDiffusion, SolvedBlockNotReusedAcrossFrames) {
  const int w = 40, h = 70;
  test::Scene a = test::TexturedScene(w, h);
  SetDepth(&a, [](int x, int y) { return 0.5 + 0.05 * x + 0.02 * y; });
  test::Scene c = a;
  for (int k = 0; k < 3; ++k)
    for (uint32_t& v : c.plane[k]) v = v / 2 + (3u << 16);
  PipelineConfig p = DofPipeline(w, h, DofMethod::kDiffusion);
  p.dof.column_window = 9;
  const std::vector<uint32_t> fresh = RunDof(p, c, 7);
  auto b = test::Build(p);
  ASSERT_TRUE(b->status.ok());
  const std::vector<uint32_t> first = test::RunFrame(*b, a, 0, 7);
  EXPECT_NE(first, fresh);
  // Strips of 7 and 64 rows both end inside a block of frame a.
  EXPECT_EQ(test::RunFrame(*b, c, 1, 7), fresh);
  EXPECT_EQ(test::RunFrame(*b, a, 2, 64), first);
  EXPECT_EQ(test::RunFrame(*b, c, 3, 64), fresh);
}

// A bright point on a dark background.
test::Scene PointScene(int w, int h) {
  test::Scene s = test::FlatScene(w, h, 0.1, 0.1, 0.1);
  for (int c = 0; c < 3; ++c) s.plane[c][static_cast<size_t>(h / 2) * w + w / 2] = 100u << 16;
  return s;
}

TEST(DofBoth, PointAtFocusStaysSharp) {
  const int w = 41, h = 41;
  test::Scene s = PointScene(w, h);
  // The point at the focus distance; everything else far out of focus.
  SetDepth(&s, [](int x, int y) { return x == w / 2 && y == h / 2 ? 3.0 : 0.5; });
  PipelineConfig p = DofPipeline(w, h, DofMethod::kDiffusion);
  const size_t centre = static_cast<size_t>(h / 2) * w + w / 2;
  const std::vector<uint32_t> out = RunDof(p, s, 8);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(out[3 * centre + static_cast<size_t>(c)], 100u << 16);
  // Gather: with the whole frame in focus, the output is the input.
  SetDepth(&s, [](int, int) { return 3.0; });
  p.dof.method = DofMethod::kGather;
  const std::vector<uint32_t> g = RunDof(p, s, 8);
  ASSERT_EQ(g.size(), static_cast<size_t>(w) * h * 3);
  for (size_t i = 0; i < g.size(); ++i) ASSERT_EQ(g[i], s.plane[i % 3][i / 3]) << "sample " << i;
}

// Per-axis variance (px^2) of a point's spread, background removed.
double SpreadVariance(const std::vector<uint32_t>& out, int w, int h, double background) {
  double m = 0, vx = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double v = out[3 * (static_cast<size_t>(y) * w + x) + 1] - background;
      const double dx = x - w / 2, dy = y - h / 2;
      m += v;
      vx += v * (dx * dx + dy * dy) / 2;
    }
  return vx / m;
}

TEST(DofBoth, LargerFNumberLessBlurAndMethodsAgree) {
  const int w = 81, h = 81;
  test::Scene s = PointScene(w, h);
  SetDepth(&s, [](int, int) { return 1.5; });  // uniformly out of focus
  const double bg = 0.1 * 65536;
  double var[2][2];
  int k = 0;
  for (double n : {2.8, 8.0}) {
    int j = 0;
    for (DofMethod m : {DofMethod::kDiffusion, DofMethod::kGather}) {
      PipelineConfig p = DofPipeline(w, h, m);
      p.exposure.f_number = n;
      p.dof.column_window = 40;
      p.dof.max_radius_px = 20;
      var[k][j++] = SpreadVariance(RunDof(p, s, 16), w, h, bg);
    }
    ++k;
  }
  // The CoC at 1.5 m: ~7.5 px at f/2.8, ~2.6 px at f/8; a disc of diameter c has variance c^2 / 16.
  const DofConfig c = LensConfig();
  for (int i = 0; i < 2; ++i) {
    const double coc = ReferenceCocPixels(c, i == 0 ? 2.8 : 8.0, 1.5);
    std::printf("  f/%s: CoC %.2f px, disc variance %.2f; diffusion %.2f, gather %.2f px^2\n", i ? "8" : "2.8", coc,
                coc * coc / 16, var[i][0], var[i][1]);
  }
  EXPECT_GT(var[0][0], 2 * var[1][0]) << "diffusion: f/8 blurs less than f/2.8";
  EXPECT_GT(var[0][1], 2 * var[1][1]) << "gather: f/8 blurs less than f/2.8";
  // Cross-check: the default diffusion_scale matches the disc's variance.
  EXPECT_NEAR(var[0][0] / var[0][1], 1.0, 0.25);
}

TEST(DofGather, MatchesDoubleReference) {
  const int w = 48, h = 40;
  test::Scene s = test::TexturedScene(w, h);
  SetDepth(&s, [](int x, int y) { return 0.6 + 0.1 * x + 0.05 * y; });
  PipelineConfig p = DofPipeline(w, h, DofMethod::kGather);
  p.dof.max_radius_px = 12;
  CocModel m;
  ASSERT_TRUE(m.Configure(p.dof, p.exposure.f_number).ok());
  std::vector<double> radius(s.inverse_depth.size());
  for (size_t i = 0; i < radius.size(); ++i)
    radius[i] = std::min<uint32_t>((m.Coc(s.inverse_depth[i]) + 64) >> 7, 4 * 12) / 4.0;
  const std::vector<uint32_t> out = RunDof(p, s, 7);
  for (int c = 0; c < 3; ++c) {
    const std::vector<double> ref = ReferenceGather(PlaneD(s, c), radius, w, h);
    double max_rel = 0;
    for (size_t i = 0; i < ref.size(); ++i)
      max_rel = std::max(max_rel, std::fabs(out[3 * i + static_cast<size_t>(c)] - ref[i]) / (1 + ref[i]));
    std::printf("  channel %d: max relative error %.2e\n", c, max_rel);
    EXPECT_LE(max_rel, 3e-4);  // weights round(2^26 / A): relative error 0.5 A / 2^26 each (< 6e-6 for A <= 797)
  }
}

// Structural blur's squared diameters follow the double reference up to the
// CoC cap (s d = 1023 px); they used to saturate a 32-bit table at s d = 256.
TEST(DofStructural, LargeDiametersAreNotCapped) {
  const int w = 64, h = 48;
  DofConfig c;
  c.method = DofMethod::kOff;
  c.structural_only = true;
  c.structural_poly[2] = 600.0;  // 600 px diameter at the corners
  c.diffusion_scale = 0.5;       // s d = 300 px
  c.max_coc_px = 1023;
  const SensorGeometry g{w, h, Cfa::kBayerRG, 12};
  DofRowStage stage;
  ASSERT_TRUE(stage.Configure(c, g, 2.8).ok());
  WorkspaceCounter count;
  stage.CountTables(count);
  std::vector<uint8_t> memory(count.bytes());
  Arena tables(Span<uint8_t>{memory.data(), memory.size()});
  ASSERT_TRUE(stage.Init(tables).ok());
  const std::vector<double> ref = ReferenceCc2(c, 2.8, nullptr, w, h, false);  // px^2
  std::vector<uint64_t> row(w);
  for (int y : {0, h / 2, h - 1}) {
    stage.RowCc2(FrameInput{}, y, 0, w, row.data());
    for (int x = 0; x < w; ++x) {
      const double got = static_cast<double>(row[static_cast<size_t>(x)]) / 4294967296.0;
      const double want = ref[static_cast<size_t>(y) * w + x];
      ASSERT_NEAR(got, want, 1e-3 * want + 1.0) << "x " << x << " y " << y;
    }
  }
}

TEST(DofStructural, SharpCentreSoftCornersWithoutDepth) {
  const int w = 96, h = 64;
  test::Scene s = test::TexturedScene(w, h);  // no depth plane
  PipelineConfig p = DofPipeline(w, h, DofMethod::kOff);
  p.dof.structural_only = true;
  p.dof.structural_poly[2] = 12.0;  // 12 px diameter at the corners, 0 at the centre
  p.dof.diffusion_scale = 1.0;
  auto b = test::Build(p);
  ASSERT_TRUE(b->status.ok()) << b->status.message();
  ASSERT_TRUE(b->pipeline.CheckInput(s.View()).ok()) << "structural blur needs no depth";
  const std::vector<uint32_t> out = test::RunFrame(*b, s, 0, 5);
  auto diff = [&](int x0, int y0) {
    double d = 0;
    for (int y = y0; y < y0 + 8; ++y)
      for (int x = x0; x < x0 + 8; ++x) {
        const size_t i = static_cast<size_t>(y) * w + x;
        d += std::fabs(double(out[3 * i + 1]) - s.plane[1][i]);
      }
    return d;
  };
  EXPECT_LT(diff(w / 2 - 4, h / 2 - 4) * 20, diff(0, 0)) << "centre nearly untouched, corner blurred";
  EXPECT_GT(diff(0, 0), 0);
}

TEST(DofSkipping, CountsSolvedPixels) {
  const int w = 64, h = 32;
  test::Scene s = test::TexturedScene(w, h);
  SetDepth(&s, [](int x, int) { return x < 40 ? 3.0 : 1.0; });  // left 40 columns in focus
  PipelineConfig p = DofPipeline(w, h, DofMethod::kDiffusion);
  WorkerStats st;
  const std::vector<uint32_t> out = RunDof(p, s, 8, &st);
  // Linked pixels: columns 40 .. 63 (column 40's link to 39 is min(0, .) = 0).
  const int64_t expected = int64_t{24} * h;
  EXPECT_EQ(st.stage[0].skipped_px, int64_t{w} * h - expected) << "rows";
  EXPECT_EQ(st.stage[1].skipped_px, int64_t{w} * h - expected) << "columns";
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < 40; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      ASSERT_EQ(out[3 * i], s.plane[0][i]) << "skipped pixels are copied";
    }
}

// A pixel is solved when it links to a neighbour on either side, also across
// a column block's edge: row 31 ends block 0, has no link above (row 30 is in
// focus) and links to row 32 below.
TEST(DofSkipping, BlockEdgeRowLinkedBelowIsSolved) {
  const int w = 8, h = 2 * DofColumnStage::kBlock;
  test::Scene s = test::TexturedScene(w, h);
  SetDepth(&s, [](int, int y) { return y < DofColumnStage::kBlock - 1 ? 3.0 : 1.0; });
  PipelineConfig p = DofPipeline(w, h, DofMethod::kDiffusion);
  for (const int strip : {16, h}) {
    WorkerStats st;
    RunDof(p, s, strip, &st);
    EXPECT_EQ(st.stage[1].skipped_px, int64_t{w} * (DofColumnStage::kBlock - 1)) << "strip " << strip;
  }
}

// A column tile (DofColumnStage::kTile columns) whose window has no link is
// copied, not swept: the outer tiles are in focus, the middle one is not.
TEST(DofSkipping, InFocusColumnTilesAreCopied) {
  constexpr int kTile = DofColumnStage::kTile;
  const int w = 3 * kTile, h = 2 * DofColumnStage::kBlock + 5;
  test::Scene s = test::TexturedScene(w, h);
  SetDepth(&s, [](int x, int) { return x >= kTile && x < 2 * kTile ? 1.0 : 3.0; });
  PipelineConfig p = DofPipeline(w, h, DofMethod::kDiffusion);
  WorkerStats st;
  const std::vector<uint32_t> out = RunDof(p, s, 16, &st);
  EXPECT_EQ(st.stage[1].skipped_px, int64_t{2} * kTile * h) << "columns";
  int changed = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      for (int c = 0; c < 3; ++c) {
        if (x >= kTile && x < 2 * kTile)
          changed += out[3 * i + c] != s.plane[c][i];
        else
          ASSERT_EQ(out[3 * i + c], s.plane[c][i]) << "in-focus tiles are copied; x " << x << " y " << y;
      }
    }
  EXPECT_GT(changed, kTile * h) << "the middle tile is blurred";
}

// Skipping off (PipelineConfig::skip_idle, what `camsim run
// --measure-savings` times against) runs the work on the pixels that need
// none and changes no byte, for both methods; the counts stay the same.
TEST(DofSkipping, SkippingOffChangesNoByte) {
  const int w = 3 * DofColumnStage::kTile + 7, h = 2 * DofColumnStage::kBlock + 9;
  test::Scene s = test::TexturedScene(w, h);
  // In focus at 3 m on the left (the whole first column tile, which the
  // column pass copies) and at the top (a block the row pass copies); out of
  // focus elsewhere.
  static_assert(DofColumnStage::kTile <= 66 && DofRowStage::kBlock <= 10);
  SetDepth(&s, [](int x, int y) { return x < 66 || y < 10 ? 3.0 : 0.7 + 0.01 * ((x * 7 + y * 3) % 50); });
  for (const DofMethod method : {DofMethod::kDiffusion, DofMethod::kGather}) {
    PipelineConfig p = DofPipeline(w, h, method);
    p.dof.max_radius_px = 6;
    WorkerStats on, off;
    const std::vector<uint32_t> skipped = RunDof(p, s, 16, &on);
    p.skip_idle = false;
    EXPECT_EQ(RunDof(p, s, 16, &off), skipped) << (method == DofMethod::kGather ? "gather" : "diffusion");
    for (int k = 0; k < (method == DofMethod::kGather ? 1 : 2); ++k) {
      EXPECT_GE(on.stage[k].skipped_px, int64_t{w} * 4) << "stage " << k << ": the case skips";
      EXPECT_LT(on.stage[k].skipped_px, int64_t{w} * h / 2) << "stage " << k << ": and works";
      EXPECT_EQ(off.stage[k].skipped_px, on.stage[k].skipped_px) << "stage " << k;
    }
  }
  // A frame one row high: the column window holds no link at all (and the
  // count must not read a link row the window does not have).
  test::Scene row = test::TexturedScene(w, 1);
  SetDepth(&row, [](int x, int) { return x < 40 ? 3.0 : 0.7; });
  PipelineConfig p = DofPipeline(w, 1, DofMethod::kDiffusion);
  WorkerStats on, off;
  const std::vector<uint32_t> skipped = RunDof(p, row, 1, &on);
  p.skip_idle = false;
  EXPECT_EQ(RunDof(p, row, 1, &off), skipped);
  EXPECT_EQ(on.stage[1].skipped_px, w) << "columns: no neighbour above or below";
  EXPECT_EQ(off.stage[1].skipped_px, w);
}

TEST(DofSkipping, GatherCopiesRowsWithoutBlur) {
  const int w = 40, h = 60;
  test::Scene s = test::TexturedScene(w, h);
  // Rows 0 .. 29 at focus, rows 30 .. 59 far out of focus; radius cap 5.
  SetDepth(&s, [](int, int y) { return y < 30 ? 3.0 : 0.5; });
  PipelineConfig p = DofPipeline(w, h, DofMethod::kGather);
  p.dof.max_radius_px = 5;
  WorkerStats st;
  const std::vector<uint32_t> out = RunDof(p, s, 8, &st);
  EXPECT_EQ(st.stage[0].skipped_px, int64_t{w} * 25) << "rows 0 .. 24 see no blurred row within 5";
  for (size_t i = 0; i < static_cast<size_t>(w) * 25 * 3; ++i) ASSERT_EQ(out[i], s.plane[i % 3][i / 3]);
  int changed = 0;
  for (size_t i = static_cast<size_t>(w) * 30 * 3; i < out.size(); ++i) changed += out[i] != s.plane[i % 3][i / 3];
  EXPECT_GT(changed, w * 30) << "the out-of-focus half is blurred";
}

TEST(DofPipelineTest, MissingDepthIsAnErrorNamingTheKey) {
  const test::Scene s = test::TexturedScene(16, 16);
  auto b = test::Build(DofPipeline(16, 16, DofMethod::kDiffusion));
  ASSERT_TRUE(b->status.ok());
  const Status st = b->pipeline.CheckInput(s.View());
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(std::string(st.field()), "dof.method");
}

// fuzz_core found an order with dof_columns but not dof_rows: the column pass
// then read coefficient tables nobody had built. It is a configuration error.
// The column pass's window is kBlock + 2 column_window rows: the largest
// accepted window fits on a tall frame, and the next is refused by its key
// (it used to pass the key's check and fail in the ring sizing, unnamed).
TEST(DofPipelineTest, ColumnWindowRangeFitsTheRowWindow) {
  PipelineConfig p = DofPipeline(32, 1100, DofMethod::kDiffusion);
  p.dof.column_window = kMaxColumnWindow;
  auto fits = test::Build(p);
  EXPECT_TRUE(fits->status.ok()) << fits->status.message();
  p.dof.column_window = kMaxColumnWindow + 1;
  auto refused = test::Build(p);
  ASSERT_FALSE(refused->status.ok());
  EXPECT_EQ(std::string(refused->status.field()), "dof.column_window") << refused->status.message();
}

TEST(DofPipelineTest, ColumnsWithoutRowsIsAnErrorNamingTheKey) {
  for (const bool rows_after : {false, true}) {
    PipelineConfig p = DofPipeline(16, 16, DofMethod::kDiffusion);
    if (rows_after) {  // both run, but in the wrong order
      p.order[0] = StageId::kDofColumns;
      p.order[1] = StageId::kDofRows;
      p.order_count = 2;
    } else {
      p.order[0] = StageId::kDofColumns;
      p.order_count = 1;
    }
    auto b = test::Build(p);
    ASSERT_FALSE(b->status.ok()) << (rows_after ? "columns before rows" : "columns alone");
    EXPECT_EQ(std::string(b->status.field()), "pipeline.stages");
    EXPECT_NE(std::string(b->status.message()).find("dof_columns needs dof_rows"), std::string::npos)
        << b->status.message();
  }
  // The same stages in the right order configure.
  EXPECT_TRUE(test::Build(DofPipeline(16, 16, DofMethod::kDiffusion))->status.ok());
}

}  // namespace
}  // namespace camsim
