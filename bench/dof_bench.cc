// Depth of field at 1920x1080 (aisle1080_0001.exr with its depth): time per
// frame and error per precision setting, one thread, strips of 16 rows.
//
//   ./build/release/bench/camsim_bench --benchmark_filter=Dof
//
// BM_DofDiffusion/window: dof_rows + dof_columns with dof.column_window =
//   window; error against the double solve with whole columns.
// BM_DofGather/radius: dof_gather with dof.max_radius_px = radius; error
//   against the double gather with the radius uncapped (255).
// BM_DofFloatThomas: a plain float Thomas solve, rows then whole columns, 3
//   channels, each line factored once (bench-only: a frame-sized float buffer).
// Counters: err_rms / err_max relative to the frame's mean radiance (so 1e-3
// is 0.1 % of the mean), workspace_bytes (tables + one worker's rings and scratch).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <random>
#include <cmath>
#include <map>
#include <vector>

#include "bench/bench_common.h"
#include "core/base/simd.h"
#include "core/lens/dof_ref.h"

#ifdef CAMSIM_X86_AVX2
#include <immintrin.h>
#endif

namespace camsim {
namespace {

constexpr int kW = 1920, kH = 1080;

// Strong blur so the work is real: 28 mm at f/1.4 focused at 1 m on a 36 mm
// wide sensor (18.75 um pixels): CoC ~ 10 .. 31 px over the scene.
PipelineConfig DofConfigFor(DofMethod method) {
  PipelineConfig p;
  p.geometry.width = kW;
  p.geometry.height = kH;
  p.exposure.f_number = 1.4;
  p.dof.method = method;
  p.dof.focal_length_mm = 28.0;
  p.dof.pixel_pitch_um = 36000.0 / kW;
  p.dof.focus_distance_m = 1.0;
  p.dof.max_coc_px = 64.0;
  p.order[0] = StageId::kDofGather;
  p.order[1] = StageId::kDofRows;
  p.order[2] = StageId::kDofColumns;
  p.order_count = 3;
  return p;
}

std::vector<double> Plane(const host::CoreInput& in, int c) {
  std::vector<double> v(in.radiance[c].size());
  for (size_t i = 0; i < v.size(); ++i) v[i] = in.radiance[c][i] / 65536.0;
  return v;
}

// Reference planes per method, computed once.
const std::vector<std::vector<double>>& Reference(DofMethod method) {
  static std::map<DofMethod, std::vector<std::vector<double>>> cache;
  auto it = cache.find(method);
  if (it != cache.end()) return it->second;
  const host::CoreInput& in = bench::Scene(kW);
  PipelineConfig p = DofConfigFor(method);
  std::vector<std::vector<double>> planes(3);
  if (method == DofMethod::kDiffusion) {
    const std::vector<double> cc2 = ReferenceCc2(p.dof, 1.4, in.inverse_depth.data(), kW, kH, true);
    for (int c = 0; c < 3; ++c) planes[c] = ReferenceDiffusion(Plane(in, c), cc2, kW, kH, -1);
  } else {
    p.dof.max_radius_px = 255;
    const std::vector<double> r = ReferenceGatherRadius(p.dof, 1.4, in.inverse_depth.data(), kW, kH);
    for (int c = 0; c < 3; ++c) planes[c] = ReferenceGather(Plane(in, c), r, kW, kH);
  }
  return cache[method] = planes;
}

void SetError(benchmark::State& state, const std::vector<uint32_t>& out, const std::vector<std::vector<double>>& ref) {
  double s2 = 0, mx = 0, mean = 0;
  for (int c = 0; c < 3; ++c)
    for (size_t i = 0; i < ref[c].size(); ++i) {
      const double d = std::fabs(out[3 * i + c] / 65536.0 - ref[c][i]);
      s2 += d * d;
      mx = std::max(mx, d);
      mean += ref[c][i];
    }
  const double n = 3.0 * ref[0].size();
  mean /= n;
  state.counters["err_rms"] = std::sqrt(s2 / n) / mean;
  state.counters["err_max"] = mx / mean;
}

void RunDof(benchmark::State& state, const PipelineConfig& config, int strip_rows = 16) {
  Pipeline p;
  if (!p.Configure(config, 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  const FrameInput in = bench::Scene(kW).View();
  if (!p.CheckInput(in).ok()) std::abort();
  std::vector<uint32_t> out(static_cast<size_t>(kW) * kH * 3);
  Tap tap;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = kW * 3;
  WorkerStats stats;
  for (auto _ : state) {
    stats = WorkerStats();
    p.ProcessFrame(in, 0, strip_rows, &tap, 1, &stats, nullptr);
    benchmark::DoNotOptimize(out.data());
  }
  SetError(state, out, Reference(config.dof.method));
  int64_t skipped = 0;
  for (int i = 0; i < p.plan().running; ++i) skipped += stats.stage[i].skipped_px;
  state.counters["skipped_frac"] = static_cast<double>(skipped) / (double(kW) * kH * p.plan().running);
  state.counters["workspace_bytes"] = static_cast<double>(p.WorkspaceBytes());
}

void BM_DofDiffusion(benchmark::State& state) {
  PipelineConfig p = DofConfigFor(DofMethod::kDiffusion);
  p.dof.column_window = static_cast<int>(state.range(0));
  RunDof(state, p);
}
BENCHMARK(BM_DofDiffusion)->Arg(8)->Arg(16)->Arg(32)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond)->MinTime(0.5);

// BM_DofDiffusionStrips/window/strip_rows: the same with taller strips. Each
// strip starts with empty rings, so a strip of S rows runs the row pass (and
// the CoC) on its S + 2W + (up to) 15 window rows: 5x the frame at S = 16, W = 32.
void BM_DofDiffusionStrips(benchmark::State& state) {
  PipelineConfig p = DofConfigFor(DofMethod::kDiffusion);
  p.dof.column_window = static_cast<int>(state.range(0));
  RunDof(state, p, static_cast<int>(state.range(1)));
}
BENCHMARK(BM_DofDiffusionStrips)
    ->Args({32, 16})
    ->Args({32, 64})
    ->Args({32, 128})
    ->Args({32, 272})
    ->Args({32, 1080})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(0.5);

void BM_DofGather(benchmark::State& state) {
  PipelineConfig p = DofConfigFor(DofMethod::kGather);
  p.dof.max_radius_px = static_cast<int>(state.range(0));
  RunDof(state, p);
}
BENCHMARK(BM_DofGather)->Arg(4)->Arg(8)->Arg(16)->Unit(benchmark::kMillisecond)->MinTime(0.5);

// Plain float Thomas: rows then whole columns; coefficients factored once per
// line (c' and 1/denominator), applied to 3 channels.
void BM_DofFloatThomas(benchmark::State& state) {
  const host::CoreInput& in = bench::Scene(kW);
  const PipelineConfig p = DofConfigFor(DofMethod::kDiffusion);
  const std::vector<double> cc2d = ReferenceCc2(p.dof, 1.4, in.inverse_depth.data(), kW, kH, true);
  const std::vector<float> cc2(cc2d.begin(), cc2d.end());
  std::vector<float> img[3];
  std::vector<float> cp(kH > kW ? kH : kW), inv(cp.size()), b(cp.size() + 1), dp(cp.size());
  std::vector<std::vector<double>> outd(3, std::vector<double>(static_cast<size_t>(kW) * kH));
  for (auto _ : state) {
    for (int c = 0; c < 3; ++c) {
      img[c].resize(in.radiance[c].size());
      for (size_t i = 0; i < img[c].size(); ++i) img[c][i] = in.radiance[c][i] / 65536.0f;
    }
    // One line: factor (c', 1/den) once, then forward + back substitution per channel.
    auto solve = [&](size_t base, ptrdiff_t step, int n, auto beta_at) {
      for (int i = 0; i < n; ++i) b[static_cast<size_t>(i)] = i > 0 ? beta_at(i) : 0.0f;
      for (int i = 0; i < n; ++i) {
        const float lo = b[static_cast<size_t>(i)], up = i + 1 < n ? beta_at(i + 1) : 0.0f;
        const float den = 1.0f + lo + up + (i > 0 ? lo * cp[static_cast<size_t>(i - 1)] : 0.0f);
        inv[static_cast<size_t>(i)] = 1.0f / den;
        cp[static_cast<size_t>(i)] = -up * inv[static_cast<size_t>(i)];
      }
      for (int c = 0; c < 3; ++c) {
        float* v = img[c].data() + base;
        dp[0] = v[0] * inv[0];
        for (int i = 1; i < n; ++i)
          dp[static_cast<size_t>(i)] = (v[i * step] + b[static_cast<size_t>(i)] * dp[static_cast<size_t>(i - 1)]) * inv[static_cast<size_t>(i)];
        v[(n - 1) * step] = dp[static_cast<size_t>(n - 1)];
        for (int i = n - 2; i >= 0; --i) v[i * step] = dp[static_cast<size_t>(i)] - cp[static_cast<size_t>(i)] * v[(i + 1) * step];
      }
    };
    for (int y = 0; y < kH; ++y) {
      const size_t row = static_cast<size_t>(y) * kW;
      solve(row, 1, kW, [&](int i) { return std::min(cc2[row + i - 1], cc2[row + i]); });
    }
    for (int x = 0; x < kW; ++x)
      solve(static_cast<size_t>(x), kW, kH, [&](int i) {
        return std::min(cc2[static_cast<size_t>(i - 1) * kW + x], cc2[static_cast<size_t>(i) * kW + x]);
      });
    benchmark::DoNotOptimize(img[0].data());
  }
  const std::vector<std::vector<double>>& ref = Reference(DofMethod::kDiffusion);
  std::vector<uint32_t> out(static_cast<size_t>(kW) * kH * 3);
  for (int c = 0; c < 3; ++c)
    for (size_t i = 0; i < img[c].size(); ++i) out[3 * i + c] = static_cast<uint32_t>(std::lround(img[c][i] * 65536.0));
  SetError(state, out, ref);
  state.counters["workspace_bytes"] = 3.0 * kW * kH * 4;  // the float frame it needs
}
BENCHMARK(BM_DofFloatThomas)->Unit(benchmark::kMillisecond)->MinTime(0.5);

// Division-free reciprocal against the hardware divide (issue 7, tried and
// not adopted): the solver's rounded Q.30 quotient n / d (0 <= n <= d, the
// DivQ30 of core/lens/dof.cc, repeated here) three ways, on the solver's
// operand ranges (D in [2^30, 2^50], b << 18 added).
//   /0 hardware 64-bit divide (the core's way);
//   /1 the same exact quotient from a 256-entry reciprocal table, two Newton
//      steps and a remainder correction (identical bits);
//   /2 table + two Newton steps without correction (within 2 Q.30 ulp);
//   /3 the exact quotient of /1 in four 64-bit AVX2 lanes (x86-64 only):
//      the bit width by five shifts, a 512-entry table of 2^41 / (i + 1)
//      (an underestimate, so both Newton steps stay below 2^63 / m), an
//      estimate within [q - 2, q + 1] and three remainder corrections.
// Arg 0..2 as above; second arg 0: independent quotients (throughput), 1:
// each denominator depends on the previous quotient (latency, as the row
// pass's chain r_i -> D_{i+1} -> r_{i+1}).
namespace divide {
inline uint32_t Hardware(uint64_t n, uint64_t d) {
  const int bits = static_cast<int>(std::bit_width(d));
  const int k = bits > 34 ? bits - 34 : 0;
  n >>= k;
  d >>= k;
  return static_cast<uint32_t>(((n << 30) + (d >> 1)) / d);
}
struct Table {
  uint32_t y[256];  // ~ 2^63 / m for m = 2^31 (1 + (i + 1/2) / 256)
  Table() {
    for (int i = 0; i < 256; ++i) y[i] = static_cast<uint32_t>(4294967296.0 / (1.0 + (i + 0.5) / 256.0) + 0.5);
  }
};
const Table kTable;
// ~ 2^63 / m, m in [2^31, 2^32) the top 32 bits of the normalised divisor.
inline uint64_t Reciprocal(uint32_t m) {
  uint64_t y = kTable.y[(m >> 23) & 0xFF];
  for (int k = 0; k < 2; ++k) {
    const uint64_t e = (uint64_t{1} << 63) - uint64_t{m} * y;  // signed error, small
    y += static_cast<uint64_t>((static_cast<int64_t>(e) >> 31) * static_cast<int64_t>(y) >> 32);
  }
  return y;
}
inline uint32_t Exact(uint64_t n, uint64_t d) {
  const int bits = static_cast<int>(std::bit_width(d));
  const int k = bits > 34 ? bits - 34 : 0;
  n >>= k;
  d >>= k;
  const uint64_t num = (n << 30) + (d >> 1);
  const int z = std::countl_zero(d);
  const uint64_t y = Reciprocal(static_cast<uint32_t>((d << z) >> 32));
  __extension__ typedef unsigned __int128 U128;
  uint64_t q = static_cast<uint64_t>((static_cast<U128>(num) * y) >> (95 - z));
  int64_t rem = static_cast<int64_t>(num - q * d);
  while (rem < 0) { --q; rem += static_cast<int64_t>(d); }
  while (static_cast<uint64_t>(rem) >= d) { ++q; rem -= static_cast<int64_t>(d); }
  return static_cast<uint32_t>(q);
}
inline uint32_t Approx(uint64_t n, uint64_t d) {
  const int z = std::countl_zero(d);
  const uint64_t y = Reciprocal(static_cast<uint32_t>((d << z) >> 32));
  __extension__ typedef unsigned __int128 U128;
  return static_cast<uint32_t>((static_cast<U128>(n) * y) >> (65 - z));
}
#ifdef CAMSIM_X86_AVX2
struct LanesTable {
  uint32_t y[512];  // floor(2^41 / (i + 1)), i = 512 .. 1023 the top 10 bits of m: <= 2^63 / m
  LanesTable() {
    for (uint64_t i = 512; i < 1024; ++i) y[i - 512] = static_cast<uint32_t>((uint64_t{1} << 41) / (i + 1));
  }
};
const LanesTable kLanesTable;
// Hardware's quotient of four lanes (d in [2^30, 2^63)).
CAMSIM_AVX2_TARGET __m256i Lanes(__m256i n, __m256i d) {
  const __m256i zero = _mm256_setzero_si256();
  __m256i t = _mm256_srli_epi64(d, 34), k = zero;  // k = bit_width(d >> 34)
  for (int s : {16, 8, 4, 2, 1}) {
    const __m256i step = _mm256_and_si256(_mm256_cmpgt_epi64(t, _mm256_set1_epi64x((int64_t{1} << s) - 1)),
                                          _mm256_set1_epi64x(s));
    k = _mm256_add_epi64(k, step);
    t = _mm256_srlv_epi64(t, step);
  }
  k = _mm256_add_epi64(k, t);
  const __m256i dk = _mm256_srlv_epi64(d, k);  // [2^30, 2^34)
  const __m256i num = _mm256_add_epi64(_mm256_slli_epi64(_mm256_srlv_epi64(n, k), 30), _mm256_srli_epi64(dk, 1));
  __m256i e = _mm256_and_si256(_mm256_cmpgt_epi64(_mm256_set1_epi64x(int64_t{1} << 32), dk), _mm256_set1_epi64x(2));
  __m256i dn = _mm256_sllv_epi64(dk, e);
  const __m256i e1 = _mm256_and_si256(_mm256_cmpgt_epi64(_mm256_set1_epi64x(int64_t{1} << 33), dn), _mm256_set1_epi64x(1));
  dn = _mm256_sllv_epi64(dn, e1);  // d << e in [2^33, 2^34)
  e = _mm256_add_epi64(e, e1);
  const __m256i m = _mm256_srli_epi64(dn, 2);  // top 32 bits
  const __m256i cell = _mm256_sub_epi64(_mm256_srli_epi64(dn, 24), _mm256_set1_epi64x(512));
  __m256i y = _mm256_cvtepu32_epi64(_mm256_i64gather_epi32(reinterpret_cast<const int*>(kLanesTable.y), cell, 4));
  for (int step = 0; step < 2; ++step) {  // y += y (2^63 - m y) / 2^63, truncated
    const __m256i err = _mm256_sub_epi64(_mm256_set1_epi64x(INT64_MIN), _mm256_mul_epu32(m, y));
    y = _mm256_add_epi64(y, _mm256_srli_epi64(_mm256_mul_epu32(y, _mm256_srli_epi64(err, 31)), 32));
  }
  const __m256i top = _mm256_srlv_epi64(num, _mm256_sub_epi64(_mm256_set1_epi64x(33), e));  // < 2^32
  __m256i q = _mm256_srli_epi64(_mm256_mul_epu32(top, y), 32);
  const __m256i qd = _mm256_add_epi64(_mm256_mul_epu32(q, dk),
                                      _mm256_slli_epi64(_mm256_mul_epu32(q, _mm256_srli_epi64(dk, 32)), 32));
  __m256i rem = _mm256_sub_epi64(num, qd);  // exact, in [-d, 3d)
  const __m256i over = _mm256_cmpgt_epi64(zero, rem);
  q = _mm256_add_epi64(q, over);
  rem = _mm256_add_epi64(rem, _mm256_and_si256(over, dk));
  for (int step = 0; step < 2; ++step) {
    const __m256i under = _mm256_cmpgt_epi64(rem, _mm256_sub_epi64(dk, _mm256_set1_epi64x(1)));
    q = _mm256_sub_epi64(q, under);
    rem = _mm256_sub_epi64(rem, _mm256_and_si256(under, dk));
  }
  return q;
}
// Quotients i .. i + 3; chain: each group's denominators add the previous
// group's first quotient's low bit (as /0-/2 per quotient).
CAMSIM_AVX2_TARGET uint64_t LanesRun(const uint64_t* num, const uint64_t* den, int count, bool chain,
                                     uint32_t* out) {
  uint64_t acc = 0;
  for (int i = 0; i < count; i += 4) {
    const __m256i d = _mm256_add_epi64(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(den + i)),
                                       _mm256_set1_epi64x(chain ? static_cast<int64_t>(acc & 1) : 0));
    const __m256i q = Lanes(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(num + i)), d);
    alignas(32) uint64_t v[4];
    _mm256_store_si256(reinterpret_cast<__m256i*>(v), q);
    if (out != nullptr)
      for (int j = 0; j < 4; ++j) out[i + j] = static_cast<uint32_t>(v[j]);
    acc = chain ? v[0] : acc + v[0] + v[1] + v[2] + v[3];
  }
  return acc;
}
#endif
}  // namespace divide

void BM_DofDivide(benchmark::State& state) {
  const int way = static_cast<int>(state.range(0));
  const bool chain = state.range(1) != 0;
  constexpr int kN = 1 << 16;
  std::vector<uint64_t> num(kN), den(kN);
  std::mt19937_64 g(7);
  for (int i = 0; i < kN; ++i) {
    const uint64_t D = (uint64_t{1} << 30) + (g() >> (14 + g() % 33));
    const uint64_t b = (g() >> (30 + g() % 34)) << 18;
    num[i] = (i & 1) ? uint64_t{1} << 30 : D;  // e = 1 / D and r = D / (D + b) alternate
    den[i] = (i & 1) ? D : D + b;
  }
  int64_t mismatches = 0, max_ulp = 0;
  for (int i = 0; i < kN; ++i) {
    const int64_t h = divide::Hardware(num[i], den[i]);
    mismatches += divide::Exact(num[i], den[i]) != h;
    max_ulp = std::max<int64_t>(max_ulp, std::abs(static_cast<int64_t>(divide::Approx(num[i], den[i])) - h));
  }
  if (way == 3) {
#ifdef CAMSIM_X86_AVX2
    if (!CpuHasAvx2()) return state.SkipWithError("no AVX2");
    std::vector<uint32_t> q(kN);
    divide::LanesRun(num.data(), den.data(), kN, false, q.data());
    mismatches = 0;
    for (int i = 0; i < kN; ++i) mismatches += q[static_cast<size_t>(i)] != divide::Hardware(num[i], den[i]);
    for (auto _ : state) benchmark::DoNotOptimize(divide::LanesRun(num.data(), den.data(), kN, chain, nullptr));
    state.counters["per_quotient"] = benchmark::Counter(static_cast<double>(state.iterations()) * kN,
                                                        benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    state.counters["exact_mismatches"] = static_cast<double>(mismatches);
    return;
#else
    return state.SkipWithError("AVX2 lanes: x86-64 only");
#endif
  }
  for (auto _ : state) {
    uint64_t acc = 0;
    for (int i = 0; i < kN; ++i) {
      const uint64_t d = den[i] + (chain ? (acc & 1) : 0);
      const uint32_t q = way == 0 ? divide::Hardware(num[i], d) : way == 1 ? divide::Exact(num[i], d) : divide::Approx(num[i], d);
      acc = chain ? q : acc + q;
    }
    benchmark::DoNotOptimize(acc);
  }
  state.counters["per_quotient"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * kN, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["exact_mismatches"] = static_cast<double>(mismatches);
  state.counters["approx_max_ulp"] = static_cast<double>(max_ulp);
}
BENCHMARK(BM_DofDivide)->ArgsProduct({{0, 1, 2, 3}, {0, 1}})->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace camsim
