// Frame-time benchmarks (Google Benchmark) on the bundled scenes.
//
//   ./build/release/bench/camsim_bench                    all
//   ./build/release/bench/camsim_bench --benchmark_filter=Pipeline/1920
//
// Pipeline/W/H/threads: the demo camera (configs/camera.toml) end to end,
// raw Bayer and RGB8 written to memory. Prefix/W/H/k: the pipeline cut after
// its k-th stage, so consecutive rows give each stage's share. Stage/W/H/i/threads:
// running stage i alone on a captured frame of its input (its label names it;
// the demo camera runs 8 stages, its colour matrix being the identity).
// Peers (OpenCV doing the closest job) are in opencv_peers.cc; bench_main.cc
// prints the camsim/peer ratios and the seed paper's baseline after the run.
#include <benchmark/benchmark.h>

#include <atomic>
#include <map>
#include <memory>
#include <string>
#include <thread>

#include "bench/bench_common.h"
#include "core/base/random.h"
#include "bench/stage_bench.h"
#include "hal/thread_pool.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/scene_input.h"

namespace camsim {
namespace {

using bench::Demo;
using bench::Scene;

void RunPipeline(benchmark::State& state, const PipelineConfig& config, int threads) {
  const int w = config.geometry.width, h = config.geometry.height;
  Pipeline p;
  if (!p.Configure(config, threads, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  const FrameInput in = Scene(w).View();
  const LineFormat f = p.plan().output;
  std::vector<uint8_t> out(static_cast<size_t>(w) * h * f.channels * 4);
  Tap tap;
  tap.format = f.domain == Domain::kEncoded || f.domain == Domain::kLinear ? TapFormat::kU8 : TapFormat::kU32;
  tap.data = out.data();
  tap.stride = static_cast<ptrdiff_t>(w) * f.channels;
  hal::ThreadPool pool(threads);
  constexpr int kStripRows = 16;
  uint32_t frame = 0;
  for (auto _ : state) {
    std::atomic<int> next{0};
    pool.Run([&](int worker) {
      for (int y0; (y0 = next.fetch_add(1) * kStripRows) < h;)
        p.ProcessStrip(in, frame, y0, y0 + kStripRows, worker, &tap, 1, nullptr, nullptr);
    });
    ++frame;
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["workspace_KiB"] = static_cast<double>(p.WorkspaceBytes()) / 1024.0;
  state.SetLabel(std::to_string(p.plan().running) + " stages");
}

void BM_Pipeline(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  RunPipeline(state, Demo(w, h), static_cast<int>(state.range(2)));
}
BENCHMARK(BM_Pipeline)
    ->Args({640, 480, 1})
    ->Args({640, 480, 2})
    ->Args({1920, 1080, 1})
    ->Args({1920, 1080, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_Prefix(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = Demo(w, h);
  c.order_count = static_cast<int>(state.range(2));
  state.SetLabel(StageName(c.order[c.order_count - 1]));
  RunPipeline(state, c, 1);
}
BENCHMARK(BM_Prefix)
    ->ArgsProduct({{640}, {480}, {1, 3, 4, 5, 6, 7, 8, 10}})
    ->ArgsProduct({{1920}, {1080}, {1, 3, 4, 5, 6, 7, 8, 10}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// MotionBlur/W/H/case: the motion_blur stage alone (radiance in and out), one
// thread, strips of 16 rows, on the bundled scene with its depth and vectors.
// Cases: 0 camera pan + tilt + forward motion, 10 ms exposure, 15 us rolling
// shutter (about 8 px of blur, 1+8 samples); 1 the same panning 4x faster
// (about 30 px, 31 samples); 2 the scene's Vector pass over a 10 ms exposure
// at 24 fps; 3 rolling shutter only (1 sample per pixel: the bilinear shift).
void BM_MotionBlur(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const int which = static_cast<int>(state.range(2));
  PipelineConfig c = Demo(w, h);
  c.order[0] = StageId::kMotionBlur;
  c.order_count = 1;
  MotionBlurConfig& m = c.motion_blur;
  m.source = which == 2 ? MotionSource::kVectors : MotionSource::kCamera;
  m.angular_velocity_rad_s[0] = 0.2;
  m.angular_velocity_rad_s[1] = which == 1 ? 2.0 : 0.5;
  m.linear_velocity_m_s[2] = 2.0;
  m.line_time_us = 15.0;
  m.max_displacement_px = 40;
  if (which == 3) c.exposure.exposure_time_us = 10.0;
  static const char* kLabels[] = {"camera ~8 px", "camera ~30 px", "vectors", "rolling shutter only"};
  Pipeline p;
  if (!p.Configure(c, 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  const FrameInput in = Scene(w).View();
  if (!p.CheckInput(in).ok()) std::abort();
  std::vector<uint32_t> out(static_cast<size_t>(w) * h * 3);
  Tap tap;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = static_cast<ptrdiff_t>(w) * 3;
  for (auto _ : state) {
    p.ProcessFrame(in, 0, 16, &tap, 1, nullptr, nullptr);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetLabel(kLabels[which]);
}
BENCHMARK(BM_MotionBlur)
    ->ArgsProduct({{1920}, {1080}, {0, 1, 2, 3}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_Stage(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const int index = static_cast<int>(state.range(2)), threads = static_cast<int>(state.range(3));
  Pipeline p;
  if (!p.Configure(Demo(w, h), threads, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  if (index >= p.plan().running) {
    state.SkipWithError("the demo pipeline has fewer running stages");
    return;
  }
  const FrameInput in = Scene(w).View();
  bench::StageRunner runner(p, index, in, threads);
  uint32_t frame = 0;
  for (auto _ : state) runner.RunFrame(frame++);
  state.SetLabel(runner.stage().name());
  state.counters["ns_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * w * h,
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_Stage)
    ->ArgsProduct({{640}, {480}, {0, 1, 2, 3, 4, 5, 6, 7}, {1, 2}})
    ->ArgsProduct({{1920}, {1080}, {0, 1, 2, 3, 4, 5, 6, 7}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The sensor's random primitives per pixel (what bounds the sensor stage):
// Philox4x32-10 for 16 lanes (4 words per pixel), a Gaussian table sample, and
// a Poisson sample at a mean of 5 (the exact small-count path) and 1000
// electrons (the skew-corrected normal).
void BM_RandomLanes(benchmark::State& state) {
  RandomLanes lanes;
  uint32_t x = 0;
  for (auto _ : state) {
    DrawBitsLanes(1, 2, 3, x, 7, 0, &lanes);
    x += RandomLanes::kLanes;
    benchmark::DoNotOptimize(lanes.v[0][0]);
  }
  state.counters["ns_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * RandomLanes::kLanes,
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_RandomLanes);

void BM_PoissonSample(benchmark::State& state) {
  std::vector<int32_t> g(GaussianTable::kEntries);
  std::vector<uint32_t> q(PoissonTable::kEntries);
  GaussianTable gauss;
  PoissonTable poisson;
  if (!gauss.Build(Span<int32_t>{g.data(), g.size()}).ok() || !poisson.Build(Span<uint32_t>{q.data(), q.size()}).ok())
    std::abort();
  const uint32_t mean_q8 = static_cast<uint32_t>(state.range(0)) * 256u;
  uint32_t u = 12345;
  for (auto _ : state) {
    u = u * 1664525u + 1013904223u;  // cheap stand-in bits: this times the sampler only
    benchmark::DoNotOptimize(poisson.Sample(mean_q8, u, gauss.Sample(u ^ 0x9E3779B9u)));
  }
}
BENCHMARK(BM_PoissonSample)->Arg(5)->Arg(1000);

}  // namespace
}  // namespace camsim
