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
#include <cmath>
#include <map>
#include <vector>

#include "bench/bench_common.h"
#include "core/lens/dof_ref.h"

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

}  // namespace
}  // namespace camsim
