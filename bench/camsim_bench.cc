// Frame-time benchmarks (Google Benchmark) on the bundled scenes.
//
//   ./build/release/bench/camsim_bench                    all
//   ./build/release/bench/camsim_bench --benchmark_filter=Pipeline/1920
//
// Pipeline/W/H/threads: the demo camera (configs/camera.toml) end to end,
// its RGB8 output written to memory. Prefix/W/H/k: the pipeline cut after
// its k-th stage, so consecutive rows give each stage's share. Stage/W/H/i/threads:
// running stage i alone on a captured frame of its input (its label names it;
// the demo camera runs 8 stages, its colour matrix being the identity).
// threads: 1 and the machine's hardware threads (ThreadCounts); rows of more
// than one thread are named .../process_time/real_time, as their CPU time is
// the whole process's.
// Peers (OpenCV doing the closest job) are in opencv_peers.cc; bench_main.cc
// prints the camsim/peer ratios and the seed paper's baseline after the run.
#include <benchmark/benchmark.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#ifdef CAMSIM_BENCH_OPENCV
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#endif

#include "tests/support/fixtures.h"
#include "core/lens/distortion_ref.h"
#include "bench/bench_common.h"
#include "bench/stage_bench.h"
#include "core/base/random.h"
#include "core/base/simd.h"
#include "core/sensor/smear.h"
#include "hal/thread_pool.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/render.h"
#include "host_tools/scene_input.h"

namespace camsim {
namespace {

using bench::Demo;
using bench::Scene;

// The thread counts of the multi-thread rows: 1 and all the machine's
// hardware threads (just 1 on a one-thread machine).
std::vector<int> ThreadCounts() {
  const int all = static_cast<int>(std::thread::hardware_concurrency());
  return all > 1 ? std::vector<int>{1, all} : std::vector<int>{1};
}

// A family of `fn` timed on `threads` threads: real time in ms, and with more
// than one thread the CPU time of the whole process (every worker's; the
// calling thread's own is only its share), which names its rows
// .../process_time/real_time.
benchmark::internal::Benchmark* Threaded(const char* name, void (*fn)(benchmark::State&), int threads) {
  benchmark::internal::Benchmark* b = benchmark::RegisterBenchmark(name, fn)->Unit(benchmark::kMillisecond)->UseRealTime();
  return threads > 1 ? b->MeasureProcessCPUTime() : b;
}

// strip_rows 0: host::StripRows' default, as `camsim run`.
void RunPipeline(benchmark::State& state, const PipelineConfig& config, int threads, int strip_rows = 0) {
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
  const int kStripRows = host::StripRows(strip_rows, h, threads);
  uint32_t frame = 0;
  const auto run_frame = [&] {
    std::atomic<int> next{0};
    pool.Run([&](int worker) {
      for (int y0; (y0 = next.fetch_add(1) * kStripRows) < h;)
        p.ProcessStrip(in, frame, y0, y0 + kStripRows, worker, &tap, 1, nullptr, nullptr);
    });
    ++frame;
    benchmark::DoNotOptimize(out.data());
  };
  // One frame untimed, as every peer pair's sides do: Google Benchmark calls
  // this function afresh for each iteration estimate and repetition, and the
  // first frame would pay its buffers' first touch and the workers' start.
  run_frame();
  for (auto _ : state) run_frame();
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["workspace_KiB"] = static_cast<double>(p.WorkspaceBytes()) / 1024.0;
  state.SetLabel(std::to_string(p.plan().running) + " stages");
}

void BM_Pipeline(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  RunPipeline(state, Demo(w, h), static_cast<int>(state.range(2)));
}
const bool kPipelineRows = [] {
  for (const auto& [w, h] : {std::pair{640, 480}, std::pair{1920, 1080}})
    for (const int t : ThreadCounts()) Threaded("BM_Pipeline", BM_Pipeline, t)->Args({w, h, t});
  return true;
}();

// LoadExr/W: reading the bundled scene of width W (Blender multi-layer, ZIP:
// colour half, depth and vectors float) as `camsim run` reads its inputs,
// the chunk check included (wall time; the check and Imf's pool use every core).
void BM_LoadExr(benchmark::State& state) {
  const std::string path = std::string(CAMSIM_SOURCE_DIR "/scenes/") +
                           (state.range(0) == 1920 ? "aisle1080_0001.exr" : "aisle_0001.exr");
  for (auto _ : state) {
    io::SceneFrame frame;
    std::string error;
    if (!io::LoadSceneExr(path, "", &frame, &error)) {
      state.SkipWithError(error.c_str());
      return;
    }
    benchmark::DoNotOptimize(frame.r.data.data());
  }
}
BENCHMARK(BM_LoadExr)->Arg(640)->Arg(1920)->Unit(benchmark::kMillisecond)->UseRealTime();

// The demo camera with diffusion depth of field in front (issue 7's "whole
// default pipeline including diffusion DoF"): the strong blur of dof_bench.cc
// (28 mm, f/1.4, focus 1 m, 18.75 um pixels: CoC ~10..31 px), column window 32.
void BM_PipelineDof(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = Demo(w, h);
  c.exposure.f_number = 1.4;
  c.dof.method = DofMethod::kDiffusion;
  c.dof.focal_length_mm = 28.0;
  c.dof.pixel_pitch_um = 36000.0 / w;
  c.dof.focus_distance_m = 1.0;
  c.dof.max_coc_px = 64.0;
  RunPipeline(state, c, static_cast<int>(state.range(2)), static_cast<int>(state.range(3)));
}
// Last argument: strip rows (0: host::StripRows' default, as `camsim run`).
// Every strip starts with empty rings, so strips of 16 run the DoF row pass
// on several times the frame (the column block + 2 x 32 window rows around
// each strip); 128 rows (a multiple of the column pass's block of 32) bring
// that to about 1.5x, the whole frame to 1x.
const bool kPipelineDofRows = [] {
  for (const int strip_rows : {16, 128, 0})
    for (const int t : ThreadCounts()) Threaded("BM_PipelineDof", BM_PipelineDof, t)->Args({1920, 1080, t, strip_rows});
  return true;
}();

// The demo pipeline cut after its k-th running stage (the stages left out by
// the planner do not count, so k names the same stage whatever the order has).
void BM_Prefix(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const int k = static_cast<int>(state.range(2));
  PipelineConfig c = Demo(w, h);
  Pipeline full;
  if (!full.Configure(c, 1, false).ok()) std::abort();
  int running = 0;
  for (int i = 0; i < full.plan().count; ++i)
    if (full.plan().entries[i].runs && ++running == k) c.order_count = i + 1;
  if (running < k) {
    state.SkipWithError("the demo pipeline has fewer running stages");
    return;
  }
  RunPipeline(state, c, 1);
  // After RunPipeline, whose "N stages" label this replaces.
  state.SetLabel(std::string("up to ") + StageName(c.order[c.order_count - 1]));
}
// Cuts after cfa, exposure, vignetting (the planner runs the Bayer CFA
// first), sensor, black level, white balance, demosaic and gamma (flare,
// blooming and the colour matrix are left out in the demo camera).
BENCHMARK(BM_Prefix)
    ->ArgsProduct({{640}, {480}, {1, 2, 3, 4, 5, 6, 7, 8}})
    ->ArgsProduct({{1920}, {1080}, {1, 2, 3, 4, 5, 6, 7, 8}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// MotionBlur/W/H/case: the motion_blur stage alone (radiance in and out), one
// thread, strips of 16 rows, on the bundled scene with its depth and vectors.
// Cases: 0 camera pan + tilt + forward motion, 10 ms exposure, 15 us rolling
// shutter (about 8 px of blur, 1+8 samples); 1 the same panning 4x faster
// (about 30 px, 31 samples); 2 the scene's Vector pass over a 10 ms exposure
// at 24 fps; 3 rolling shutter only (a 10 us exposure: the shift of a few
// pixels, and 2 samples per pixel, as any motion gives n = 1 + ceil(L) >= 2).
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


// Distortion/W/H/filter/mode, one thread. mode 0: the stage alone, all three
// channels (radiance in, radiance out); mode 2: the same in its most
// accurate setting (SetMostAccurate). mode 1: distortion -> exposure ->
// CFA, where distortion computes only each site's colour and writes the
// mosaic (the CFA is left out; exposure on the mosaic costs about 0.3 ms).
// The distortion stage's most accurate setting for a band-limited image: no
// ringing clamp (which cuts a peak between samples), the finest phases and
// grid.
void SetMostAccurate(DistortionConfig* d) {
  d->ringing_clamp = false;
  d->phases = 256;
  d->grid_step = 4;
}

void BM_Distortion(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c;
  c.geometry.width = w;
  c.geometry.height = h;
  c.distortion.lens = test::TypicalLens(w, h);
  c.distortion.filter = static_cast<ResampleFilter>(state.range(2));
  const bool site_only = state.range(3) == 1;
  if (state.range(3) == 2) SetMostAccurate(&c.distortion);
  c.order[0] = StageId::kDistortion;
  c.order[1] = StageId::kExposure;
  c.order[2] = StageId::kCfa;
  c.order_count = site_only ? 3 : 1;
  static constexpr const char* kNames[4] = {"bilinear", "bicubic", "lanczos3", "lanczos4"};
  RunPipeline(state, c, 1);
  state.SetLabel(std::string(kNames[state.range(2)]) + (site_only ? " site-only (+exposure)" : " RGB") +
                 (state.range(3) == 2 ? ", no ringing clamp, 256 phases, grid step 4" : ""));
}
BENCHMARK(BM_Distortion)
    ->ArgsProduct({{1920}, {1080}, {0, 1, 2, 3}, {0, 1}})
    ->Args({1920, 1080, 2, 2})
    ->Args({1920, 1080, 3, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The demo camera behind the typical lens (Lanczos-3), end to end.
void BM_PipelineLens(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = Demo(w, h);
  c.distortion.lens = test::TypicalLens(w, h);
  RunPipeline(state, c, static_cast<int>(state.range(2)));
}
const bool kPipelineLensRows = [] {
  for (const int t : ThreadCounts()) Threaded("BM_PipelineLens", BM_PipelineLens, t)->Args({1920, 1080, t});
  return true;
}();

// The "sensor path" to raw Bayer: the demo camera behind the typical
// lens (distortion Lanczos-3), cut after the sensor. It runs as distortion
// (computing the CFA sites' colours into the mosaic, so the CFA is left
// out), exposure, vignetting cos4 (both on the mosaic), sensor (EMVA noise,
// PRNU/DSNU, ADC). Raw 12-bit Bayer written to memory. Target: >= 120 fps
// on one thread.
PipelineConfig SensorPath(int w, int h) {
  PipelineConfig c = Demo(w, h);
  c.distortion.lens = test::TypicalLens(w, h);
  c.distortion.filter = ResampleFilter::kLanczos3;
  for (int i = 0; i < c.order_count; ++i)
    if (c.order[i] == StageId::kSensor) c.order_count = i + 1;
  return c;
}
// Last argument: 1 builds the fixed pattern once (sensor.fixed_pattern_table,
// 16.6 MB at 1080p) instead of drawing it every frame; same bytes.
void BM_SensorPath(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = SensorPath(w, h);
  c.sensor.fixed_pattern_table = state.range(3) != 0;
  RunPipeline(state, c, static_cast<int>(state.range(2)));
  state.counters["time_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * w * h,
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
const bool kSensorPathRows = [] {
  for (const int table : {0, 1})
    for (const int t : ThreadCounts()) Threaded("BM_SensorPath", BM_SensorPath, t)->Args({1920, 1080, t, table});
  return true;
}();

// Configure + Init of a pipeline (its tables built): what a change of a
// pipeline setting costs the emulated camera (GigeDevice::Reconfigure, e.g.
// every ExposureTime write or auto-exposure step). Arg 2 = 0: the sensor path,
// 1: the demo pipeline with the typical lens (distortion on), 2: the same with
// flare (glare radius 32). Arg 3 = 1: a reconfiguration from a pipeline
// initialised before with another exposure time (Pipeline::Configure's
// `previous`: unchanged tables are copied), as the camera does.
PipelineConfig ConfigureCase(int w, int h, int which) {
  PipelineConfig c = SensorPath(w, h);
  if (which >= 1) {
    c = Demo(w, h);
    c.distortion.lens = test::TypicalLens(w, h);
  }
  if (which == 2) {
    c.flare.enabled = true;
    c.flare.glare_radius = 32;
  }
  return c;
}
void BM_Configure(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = ConfigureCase(w, h, static_cast<int>(state.range(2)));
  const bool reconfigure = state.range(3) != 0;
  Pipeline previous;
  std::vector<uint8_t> previous_ws;
  if (reconfigure) {
    if (!previous.Configure(c, 1, false).ok()) std::abort();
    previous_ws.resize(previous.WorkspaceBytes());
    if (!previous.Init(Span<uint8_t>{previous_ws.data(), previous_ws.size()}).ok()) std::abort();
    c.exposure.exposure_time_us *= 2;
  }
  std::vector<uint8_t> ws;
  for (auto _ : state) {
    Pipeline p;
    if (!p.Configure(c, 1, false, reconfigure ? &previous : nullptr).ok()) std::abort();
    ws.resize(p.WorkspaceBytes());
    if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}, reconfigure ? &previous : nullptr).ok()) std::abort();
    benchmark::DoNotOptimize(ws.data());
  }
}
BENCHMARK(BM_Configure)
    ->ArgsProduct({{1920}, {1080}, {0, 1, 2}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A configuration from scratch as `camsim run` and camsim-gige make it at
// start (FrameRenderer::Configure: FinishConfig's validation, the pipeline
// configured and initialised): configs/camera.toml with a Brown lens, at
// 1920x1080, one thread; arg 2 = 1 adds auto exposure, whose range's
// corners the validation configures too.
void BM_HostConfigure(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  std::string lens = "[distortion]\nmodel = \"brown\"\nk1 = -0.28\nk2 = 0.07\np1 = 0.0012\n";
  if (state.range(2) != 0) lens += "[auto_exposure]\nmode = \"continuous\"\n";
  if (!host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, &origins, &error) ||
      !host::ParseConfig(lens, "lens", &rc, &origins, &error)) {
    state.SkipWithError(error.c_str());
    return;
  }
  for (auto _ : state) {
    host::FrameRenderer r(1, 0);
    if (!r.Configure(rc, origins, w, h, nullptr, &error)) {
      state.SkipWithError(error.c_str());
      return;
    }
    benchmark::DoNotOptimize(&r);
  }
}
BENCHMARK(BM_HostConfigure)->ArgsProduct({{1920}, {1080}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();

// Each running stage of the sensor path alone (StageRunner, one thread), so
// the rows of SensorPathStage/1920/1080/i add up to about SensorPath.
void BM_SensorPathStage(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const int index = static_cast<int>(state.range(2));
  Pipeline p;
  if (!p.Configure(SensorPath(w, h), 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  if (index >= p.plan().running) {
    state.SkipWithError("the sensor path has fewer running stages");
    return;
  }
  const FrameInput in = Scene(w).View();
  bench::StageRunner runner(p, index, in, 1);
  uint32_t frame = 0;
  for (auto _ : state) runner.RunFrame(frame++);
  state.SetLabel(runner.stage().name());
  state.counters["time_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * w * h,
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_SensorPathStage)
    ->ArgsProduct({{1920}, {1080}, {0, 1, 2, 3}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

#ifdef CAMSIM_BENCH_OPENCV
// OpenCV's cv::remap on the same machine, one thread (cv::setNumThreads(1)),
// 1920x1080 3-channel float, maps of the same transform as camsim's stage:
// each output pixel's exact source position (ReferenceDistortion::Source;
// -10 where it leaves the frame, so the border fills it as camsim fills).
// Arg: interpolation (INTER_LINEAR 1, INTER_LANCZOS4 4); map type 0: two
// CV_32FC1 maps, 1: CV_16SC2 fixed-point maps (OpenCV's fast path, 1/32 px).
// The maps are built untimed, as camsim's tables are.
// A test image for interpolation error: radiance about 1 plus four cosines
// of periods 40, 13, 6 and 4.5 pixels (up to 0.22 cycles per pixel, below
// the 0.5 Nyquist limit) in different directions, shifted per channel. Its
// value at any real position is the truth a resampler should return.
double BandLimitedRadiance(double x, double y, int ch) {
  constexpr double kTwoPi = 6.283185307179586;
  constexpr double kWave[4][4] = {  // cycles per pixel in x and y, amplitude, phase
      {1.0 / 40, 1.0 / 90, 0.30, 0.0},
      {1.0 / 13, -1.0 / 29, 0.15, 1.0},
      {-1.0 / 11, 1.0 / 7.5, 0.08, 2.0},
      {1.0 / 4.5, 1.0 / 60, 0.04, 0.5}};
  double v = 1.0;
  for (const auto& k : kWave) v += k[2] * std::cos(kTwoPi * (k[0] * x + k[1] * y) + k[3] + 0.7 * ch);
  return v;
}

// The distortion stage alone (RGB, one thread) on `in`: its w x h x 3 output.
std::vector<uint32_t> DistortionOutput(const DistortionConfig& d, const FrameInput& in, int w, int h) {
  PipelineConfig c;
  c.geometry.width = w;
  c.geometry.height = h;
  c.distortion = d;
  c.order[0] = StageId::kDistortion;
  c.order_count = 1;
  Pipeline p;
  if (!p.Configure(c, 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  std::vector<uint32_t> out(static_cast<size_t>(w) * h * 3);
  Tap tap;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = static_cast<ptrdiff_t>(w) * 3;
  p.ProcessFrame(in, 0, 16, &tap, 1, nullptr, nullptr);
  return out;
}

// Max and rms of (got - want) over the samples added.
struct ErrorStats {
  double max = 0, sum2 = 0;
  long n = 0;
  void Add(double got, double want) {
    max = std::fmax(max, std::fabs(got - want));
    sum2 += (got - want) * (got - want);
    ++n;
  }
  double rms() const { return std::sqrt(sum2 / n); }
};

// The error counters of one OpenCV remap (interpolation, map types map1/map2)
// and of camsim's stages of the same job; dst: OpenCV's timed output on the
// scene `in`.
using Counters = std::map<std::string, double>;
Counters MeasureRemapErrors(int interp, const cv::Mat& map1, const cv::Mat& map2, const cv::Mat& dst,
                            const host::CoreInput& in, const LensModel& m, const ReferenceDistortion& ref) {
  const int w = in.width, h = in.height;
  Counters counters;
  if (interp == cv::INTER_LINEAR) {
    // Error against the double reference (bilinear at the exact source),
    // Q16.16 LSB, every 5th pixel and row, fills (either side 0) left out:
    // OpenCV's timed output, camsim's bilinear stage (64 phases, grid step 8)
    // on the same scene.
    DistortionConfig d;
    d.lens = m;
    d.filter = ResampleFilter::kBilinear;
    const std::vector<uint32_t> ours = DistortionOutput(d, in.View(), w, h);
    ErrorStats cv_error, our_error;
    for (int y = 0; y < h; y += 5)
      for (int x = 0; x < w; x += 5)
        for (int ch = 0; ch < 3; ++ch) {
          const ImageView<const uint32_t> plane = MakeImageView<const uint32_t>(in.radiance[ch].data(), w, h);
          const double exact = ref.Sample(plane, x, y, ch);
          const double cvv = dst.at<cv::Vec3f>(y, x)[ch] * 65536.0;
          const double us = ours[(static_cast<size_t>(y) * w + x) * 3 + ch];
          if (exact == 0.0 || cvv == 0.0 || us == 0.0) continue;
          cv_error.Add(cvv, exact);
          our_error.Add(us, exact);
        }
    counters["cv_rms_lsb"] = cv_error.rms();
    counters["cv_max_lsb"] = cv_error.max;
    counters["camsim_rms_lsb"] = our_error.rms();
    counters["camsim_max_lsb"] = our_error.max;
  }
  if (interp == cv::INTER_LANCZOS4) {
    // Lanczos-3 and Lanczos-4 are different filters, so neither is the
    // other's reference: both resample a band-limited test image whose value
    // between pixels is known (BandLimitedRadiance), and each output is
    // compared with that value at its exact source position. Q16.16 LSB, every
    // 5th pixel and row, sources within 4 pixels of an edge left out (where
    // the two fill their missing taps differently). OpenCV's remap is the
    // timed call (same maps, same interpolation) on this image.
    host::CoreInput band;
    band.width = w;
    band.height = h;
    cv::Mat band_src(h, w, CV_32FC3), band_dst;
    for (int ch = 0; ch < 3; ++ch) {
      band.radiance[ch].resize(static_cast<size_t>(w) * h);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const uint32_t q = static_cast<uint32_t>(std::lround(BandLimitedRadiance(x, y, ch) * 65536.0));
          band.radiance[ch][static_cast<size_t>(y) * w + x] = q;
          band_src.at<cv::Vec3f>(y, x)[ch] = static_cast<float>(q / 65536.0);
        }
    }
    cv::remap(band_src, band_dst, map1, map2, cv::INTER_LANCZOS4, cv::BORDER_CONSTANT);
    // camsim's Lanczos-3 and Lanczos-4, each by default (with its ringing
    // clamp, which cuts a peak between samples) and in its most accurate
    // setting (BM_Distortion mode 2).
    ErrorStats cv_error, ours[2][2];  // [Lanczos-3, -4][default, most accurate]
    std::vector<uint32_t> out[2][2];
    for (int f = 0; f < 2; ++f)
      for (int a = 0; a < 2; ++a) {
        DistortionConfig d;
        d.lens = m;
        d.filter = f == 0 ? ResampleFilter::kLanczos3 : ResampleFilter::kLanczos4;
        if (a == 1) SetMostAccurate(&d);
        out[f][a] = DistortionOutput(d, band.View(), w, h);
      }
    for (int y = 0; y < h; y += 5)
      for (int x = 0; x < w; x += 5)
        for (int ch = 0; ch < 3; ++ch) {
          double sx = 0, sy = 0;
          if (!ref.Source(x, y, ch, &sx, &sy) || sx < 4 || sy < 4 || sx > w - 5 || sy > h - 5) continue;
          const double exact = BandLimitedRadiance(sx, sy, ch) * 65536.0;
          const size_t i = (static_cast<size_t>(y) * w + x) * 3 + ch;
          cv_error.Add(band_dst.at<cv::Vec3f>(y, x)[ch] * 65536.0, exact);
          for (int f = 0; f < 2; ++f)
            for (int a = 0; a < 2; ++a) ours[f][a].Add(out[f][a][i], exact);
        }
    counters["cv_rms_lsb"] = cv_error.rms();
    counters["cv_max_lsb"] = cv_error.max;
    static constexpr const char* kCounter[2][2] = {{"camsim", "accurate"}, {"l4", "l4_accurate"}};
    for (int f = 0; f < 2; ++f)
      for (int a = 0; a < 2; ++a) {
        counters[std::string(kCounter[f][a]) + "_rms_lsb"] = ours[f][a].rms();
        counters[std::string(kCounter[f][a]) + "_max_lsb"] = ours[f][a].max;
      }
  }
  return counters;
}

// The counters measured so far, by interpolation and map type.
std::map<std::pair<int, int>, Counters>& RemapCounters() {
  static std::map<std::pair<int, int>, Counters> counters;
  return counters;
}

// The remap pairs' error notes, from the counters of the OpenCV map types
// measured so far (bench_main pairs camsim with the faster type).
void SetRemapNotes() {
  struct Note {
    const char* what;
    int interp;
    const char* ours;  // camsim's counters' prefix
    const char* reference;
    char text[240];
  };
  static Note notes[] = {
      {"remap bilinear vs INTER_LINEAR, RGB", cv::INTER_LINEAR, "camsim", "the double bilinear at the exact source", {}},
      {"remap Lanczos-3 vs INTER_LANCZOS4, RGB", cv::INTER_LANCZOS4, "camsim", "a band-limited image's true values", {}},
      {"remap Lanczos-3 most accurate vs INTER_LANCZOS4, RGB", cv::INTER_LANCZOS4, "accurate",
       "a band-limited image's true values", {}},
      {"remap Lanczos-4 vs INTER_LANCZOS4, RGB", cv::INTER_LANCZOS4, "l4", "a band-limited image's true values", {}},
      {"remap Lanczos-4 most accurate vs INTER_LANCZOS4, RGB", cv::INTER_LANCZOS4, "l4_accurate",
       "a band-limited image's true values", {}},
  };
  const auto& all = RemapCounters();
  for (Note& n : notes) {
    const auto f = all.find({n.interp, 0}), s = all.find({n.interp, 1});
    const bool have_f = f != all.end(), have_s = s != all.end();
    if (!have_f && !have_s) continue;
    const Counters& c = have_f ? f->second : s->second;
    const std::string ours = n.ours;
    int len = std::snprintf(n.text, sizeof n.text, "rms/max vs %s, Q16.16 LSB: camsim %.0f/%.0f, OpenCV ",
                            n.reference, c.at(ours + "_rms_lsb"), c.at(ours + "_max_lsb"));
    const auto cv_error = [](const Counters& k) { return std::pair{k.at("cv_rms_lsb"), k.at("cv_max_lsb")}; };
    const size_t room = sizeof n.text - static_cast<size_t>(len);
    if (have_f && have_s && cv_error(f->second) != cv_error(s->second))
      std::snprintf(n.text + len, room, "%.0f/%.0f float maps, %.0f/%.0f CV_16SC2 maps", cv_error(f->second).first,
                    cv_error(f->second).second, cv_error(s->second).first, cv_error(s->second).second);
    else
      std::snprintf(n.text + len, room, "%.0f/%.0f (%s)", cv_error(c).first, cv_error(c).second,
                    have_f && have_s ? "both map types" : have_f ? "float maps" : "CV_16SC2 maps");
    bench::SetPeerError(n.what, n.text);
  }
}

void BM_OpenCvRemap(benchmark::State& state) {
  const int w = 1920, h = 1080;
  cv::setNumThreads(1);
  const LensModel m = test::TypicalLens(w, h);
  DistortionConfig dc;
  dc.lens = m;
  dc.filter = ResampleFilter::kBilinear;
  const ReferenceDistortion ref(dc, SensorGeometry{w, h, Cfa::kBayerRG, 12});
  cv::Mat mx(h, w, CV_32FC1), my(h, w, CV_32FC1), map1, map2;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double sx = -10.0, sy = -10.0;
      ref.Source(x, y, 0, &sx, &sy);
      mx.at<float>(y, x) = static_cast<float>(sx);
      my.at<float>(y, x) = static_cast<float>(sy);
    }
  const int map_type = static_cast<int>(state.range(1));
  if (map_type == 1) {
    cv::convertMaps(mx, my, map1, map2, CV_16SC2);
  } else {
    map1 = mx;
    map2 = my;
  }
  const host::CoreInput& in = Scene(w);
  cv::Mat src(h, w, CV_32FC3), dst;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        src.at<cv::Vec3f>(y, x)[c] = static_cast<float>(in.radiance[c][static_cast<size_t>(y) * w + x] / 65536.0);
  const int interp = static_cast<int>(state.range(0));
  // One call untimed, as camsim's side runs one frame first: dst allocated
  // and its pages touched before the clock runs.
  cv::remap(src, dst, map1, map2, interp, cv::BORDER_CONSTANT);
  for (auto _ : state) {
    cv::remap(src, dst, map1, map2, interp, cv::BORDER_CONSTANT);
    benchmark::DoNotOptimize(dst.data);
  }
  // The errors, measured on the first run of this interpolation and map type
  // (remap is deterministic), set on every run.
  auto& all = RemapCounters();
  auto it = all.find({interp, map_type});
  if (it == all.end()) {
    it = all.emplace(std::pair{interp, map_type}, MeasureRemapErrors(interp, map1, map2, dst, in, m, ref)).first;
    SetRemapNotes();
  }
  for (const auto& [name, value] : it->second) state.counters[name] = value;
  state.SetLabel(std::string(interp == cv::INTER_LINEAR ? "INTER_LINEAR" : "INTER_LANCZOS4") +
                 (map_type == 1 ? " CV_16SC2 maps" : " CV_32FC1 maps"));
}
BENCHMARK(BM_OpenCvRemap)
    ->Args({cv::INTER_LINEAR, 0})
    ->Args({cv::INTER_LINEAR, 1})
    ->Args({cv::INTER_LANCZOS4, 0})
    ->Args({cv::INTER_LANCZOS4, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// camsim's distortion stage alone (RGB, one thread) against cv::remap with
// the faster of its two map types (float maps, or CV_16SC2 fixed-point maps:
// OpenCV rounds float maps to the same 1/32 px, so both err alike; the notes
// say so when both ran). Errors: BM_OpenCvRemap's counters.
const bool kRemapPairs = [] {
  constexpr const char *kLinear = "BM_OpenCvRemap/1/0", *kLinearFixed = "BM_OpenCvRemap/1/1";
  constexpr const char *kLanczos = "BM_OpenCvRemap/4/0", *kLanczosFixed = "BM_OpenCvRemap/4/1";
  bench::AddPeerPair("BM_Distortion/1920/1080/0/0", kLinear, "remap bilinear vs INTER_LINEAR, RGB", "", kLinearFixed);
  bench::AddPeerPair("BM_Distortion/1920/1080/2/0", kLanczos, "remap Lanczos-3 vs INTER_LANCZOS4, RGB", "",
                     kLanczosFixed);
  bench::AddPeerPair("BM_Distortion/1920/1080/2/2", kLanczos, "remap Lanczos-3 most accurate vs INTER_LANCZOS4, RGB",
                     "", kLanczosFixed);
  bench::AddPeerPair("BM_Distortion/1920/1080/2/1", kLanczos, "remap Lanczos-3 site-only (+exposure) vs LANCZOS4",
                     "not like-for-like: camsim computes one channel per pixel into the mosaic, OpenCV remaps three",
                     kLanczosFixed);
  // The same filter as OpenCV's (distortion.filter = "lanczos4").
  bench::AddPeerPair("BM_Distortion/1920/1080/3/0", kLanczos, "remap Lanczos-4 vs INTER_LANCZOS4, RGB", "",
                     kLanczosFixed);
  bench::AddPeerPair("BM_Distortion/1920/1080/3/2", kLanczos, "remap Lanczos-4 most accurate vs INTER_LANCZOS4, RGB",
                     "", kLanczosFixed);
  return true;
}();
#endif
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
  state.counters["time_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * w * h,
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
const bool kStageRows = [] {
  for (const auto& [w, h] : {std::pair{640, 480}, std::pair{1920, 1080}})
    for (int index = 0; index < 8; ++index)
      for (const int t : ThreadCounts()) Threaded("BM_Stage", BM_Stage, t)->Args({w, h, index, t});
  return true;
}();

// The sensor stage (index 3 of the demo pipeline) in less light: the exposure
// time divided by the third argument. Below 12 e- a pixel's shot noise is an
// exact Poisson inverse transform (a search of up to 44 dependent steps)
// instead of the normal approximation, so dark frames cost more per pixel.
void BM_SensorLowLight(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = Demo(w, h);
  c.exposure.exposure_time_us /= static_cast<double>(state.range(2));
  Pipeline p;
  if (!p.Configure(c, 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  bench::StageRunner runner(p, 3, Scene(w).View(), 1);
  if (std::strcmp(runner.stage().name(), "sensor") != 0) std::abort();
  uint32_t frame = 0;
  for (auto _ : state) runner.RunFrame(frame++);
  state.counters["time_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * w * h,
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_SensorLowLight)->ArgsProduct({{1920}, {1080}, {1, 10, 100, 1000}})->Unit(benchmark::kMillisecond)->UseRealTime();

// The colour matrix stage alone (one thread) on the demo camera's demosaiced
// frame, with a typical sensor-to-sRGB matrix (the demo's is the identity,
// so the planner leaves the stage out there).
void BM_ColorMatrix(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = Demo(w, h);
  const double m[9] = {1.6, -0.45, -0.15, -0.3, 1.5, -0.2, 0.05, -0.55, 1.5};
  for (int i = 0; i < 9; ++i) c.color_matrix.m[i] = m[i];
  Pipeline p;
  if (!p.Configure(c, 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  int index = -1;
  for (int i = 0; i < p.plan().running; ++i)
    if (std::strcmp(p.running_stage(i).name(), "color_matrix") == 0) index = i;
  if (index < 0) std::abort();
  bench::StageRunner runner(p, index, Scene(w).View(), 1);
  uint32_t frame = 0;
  for (auto _ : state) runner.RunFrame(frame++);
  state.counters["time_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * w * h,
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_ColorMatrix)->Args({1920, 1080})->Unit(benchmark::kMillisecond)->UseRealTime();

// The flare stage alone (its pre-pass included) on a frame bright in every
// pixel: the worst case for its per-row search of sources. Arg 2 = 1: every
// source visited on every row (FlareStage::ForceEverySourceForTest, the loop
// before sources were found by tile row), 0: found by tile row.
void BM_FlareBright(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c;
  c.geometry = {w, h, Cfa::kBayerRG, 12};
  c.order[0] = StageId::kFlare;
  c.order_count = 1;
  c.flare.enabled = true;
  c.flare.threshold = 1.0;
  Pipeline p;
  if (!p.Configure(c, 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  const_cast<FlareStage&>(p.flare_stage()).ForceEverySourceForTest(state.range(2) != 0);
  // Radiance 2 everywhere (above the threshold): every tile is a source.
  std::vector<uint32_t> plane(static_cast<size_t>(w) * h, 2u << 16);
  FrameInput in;
  for (int ch = 0; ch < 3; ++ch) in.radiance[ch] = MakeImageView<const uint32_t>(plane.data(), w, h);
  std::vector<uint32_t> out(static_cast<size_t>(w) * h * 3);
  Tap tap;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = static_cast<ptrdiff_t>(w) * 3;
  std::vector<FlareSource> sources(static_cast<size_t>(FlareMaxSources(c.geometry)));
  FlareFrame flare;
  for (auto _ : state) {
    ComputeFlare(c.flare, c.geometry, in, Span<FlareSource>{sources.data(), sources.size()}, &flare);
    in.flare = &flare;
    p.ProcessFrame(in, 0, 64, &tap, 1, nullptr, nullptr);
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["sources"] = flare.count;
}
BENCHMARK(BM_FlareBright)
    ->Args({1920, 1080, 0})
    ->Args({1920, 1080, 1})
    ->Args({4096, 2160, 0})
    ->Args({4096, 2160, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The demo camera with the issue-5 artefacts on: flare (its bright-tile
// pre-pass included), blooming, CCD smear (its column pre-pass included), row
// and column FPN and defect pixels. The difference to BM_Pipeline is their cost.
void BM_Artefacts(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  PipelineConfig c = Demo(w, h);
  c.flare.enabled = true;
  c.flare.threshold = 1.5;  // the bundled scene's lamps and highlights
  c.blooming.enabled = true;
  c.sensor.smear_row_transfer_us = 2.0;
  c.sensor.smear_leak = 0.01;
  c.sensor.row_fpn_e = 2.0;
  c.sensor.column_fpn_e = 2.0;
  c.sensor.hot_pixel_fraction = 1e-3;
  c.sensor.dead_pixel_fraction = 1e-4;
  c.sensor.stuck_pixel_fraction = 1e-4;
  Pipeline p;
  if (!p.Configure(c, 1, false).ok()) std::abort();
  std::vector<uint8_t> ws(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{ws.data(), ws.size()}).ok()) std::abort();
  FrameInput in = Scene(w).View();
  std::vector<uint8_t> out(static_cast<size_t>(w) * h * 3);
  Tap tap;
  tap.format = TapFormat::kU8;
  tap.data = out.data();
  tap.stride = static_cast<ptrdiff_t>(w) * 3;
  std::vector<FlareSource> sources(static_cast<size_t>(FlareMaxSources(c.geometry)));
  std::vector<uint32_t> smear(static_cast<size_t>(SmearEntries(c)));
  FlareFrame flare;
  uint32_t frame = 0;
  for (auto _ : state) {
    ComputeFlare(c.flare, c.geometry, in, Span<FlareSource>{sources.data(), sources.size()}, &flare);
    ComputeSmear(c, in, Span<uint32_t>{smear.data(), smear.size()});
    in.flare = &flare;
    in.smear_e = smear.data();
    p.ProcessFrame(in, frame++, 16, &tap, 1, nullptr, nullptr);
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["bright_tiles"] = flare.count;
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Artefacts)->Args({640, 480})->Args({1920, 1080})->Unit(benchmark::kMillisecond)->UseRealTime();

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
  state.counters["time_per_px"] = benchmark::Counter(static_cast<double>(state.iterations()) * RandomLanes::kLanes,
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

#ifdef CAMSIM_X86_AVX512
// What a table lookup in lanes costs, next to a permute: the Gaussian sampler
// gathers twice per 16 draws, ISqrt64Lanes once per 8 roots, gamma once per
// 16 samples. GatherCost/k: AVX-512 gathers of 8 qwords from a 16 KiB table
// (the Gaussian table's size) with k of the 8 lanes enabled; PermuteCost: a
// two-register permute of 16 dwords. The indices come from memory and four
// sums take the results, so the lookups are independent: throughput, not
// latency.
constexpr int kLookups = 64;
struct LookupIndices {
  alignas(64) int64_t q[kLookups][8];
  alignas(64) int32_t d[kLookups][16];
};
const LookupIndices& Indices() {
  static const LookupIndices indices = [] {
    LookupIndices t{};
    uint32_t u = 1;
    for (int i = 0; i < kLookups; ++i) {
      for (int j = 0; j < 8; ++j) t.q[i][j] = (u = u * 1664525u + 1013904223u) >> 21;  // 0 .. 2047
      for (int j = 0; j < 16; ++j) t.d[i][j] = static_cast<int32_t>((u = u * 1664525u + 1013904223u) >> 27);  // 0 .. 31
    }
    return t;
  }();
  return indices;
}

CAMSIM_AVX512_TARGET inline __m512i Gather8(__mmask8 mask, const int64_t* index, const int64_t* table) {
  return _mm512_mask_i64gather_epi64(_mm512_setzero_si512(), mask, _mm512_load_si512(index), table, 8);
}

CAMSIM_AVX512_TARGET void GatherLoop(benchmark::State& state) {
  alignas(64) static int64_t table[2048];
  for (int i = 0; i < 2048; ++i) table[i] = i;
  const LookupIndices& ix = Indices();
  const __mmask8 mask = static_cast<__mmask8>((1u << state.range(0)) - 1);
  __m512i a0 = _mm512_setzero_si512(), a1 = a0, a2 = a0, a3 = a0;
  for (auto _ : state) {
    benchmark::ClobberMemory();  // the indices are loaded again: no lookup is hoisted out of the loop
    for (int i = 0; i < kLookups; i += 4) {
      a0 = _mm512_add_epi64(a0, Gather8(mask, ix.q[i], table));
      a1 = _mm512_add_epi64(a1, Gather8(mask, ix.q[i + 1], table));
      a2 = _mm512_add_epi64(a2, Gather8(mask, ix.q[i + 2], table));
      a3 = _mm512_add_epi64(a3, Gather8(mask, ix.q[i + 3], table));
    }
  }
  benchmark::DoNotOptimize(_mm512_add_epi64(_mm512_add_epi64(a0, a1), _mm512_add_epi64(a2, a3)));
  state.counters["ns_per_lookup"] = benchmark::Counter(static_cast<double>(state.iterations()) * kLookups,
                                                       benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
void BM_GatherCost(benchmark::State& state) {
  if (!CpuHasAvx512()) return state.SkipWithError("needs AVX-512");
  GatherLoop(state);
}
BENCHMARK(BM_GatherCost)->Arg(8)->Arg(1)->Arg(0);

CAMSIM_AVX512_TARGET void PermuteLoop(benchmark::State& state) {
  const LookupIndices& ix = Indices();
  alignas(64) static int32_t entries[32];  // the 32 dwords looked up
  for (int i = 0; i < 32; ++i) entries[i] = 3 * i + 1;
  __m512i a0 = _mm512_setzero_si512(), a1 = a0, a2 = a0, a3 = a0;
  for (auto _ : state) {
    benchmark::ClobberMemory();  // the indices are loaded again: no lookup is hoisted out of the loop
    const __m512i a = _mm512_load_si512(entries), b = _mm512_load_si512(entries + 16);
    for (int i = 0; i < kLookups; i += 4) {
      a0 = _mm512_add_epi32(a0, _mm512_permutex2var_epi32(a, _mm512_load_si512(ix.d[i]), b));
      a1 = _mm512_add_epi32(a1, _mm512_permutex2var_epi32(a, _mm512_load_si512(ix.d[i + 1]), b));
      a2 = _mm512_add_epi32(a2, _mm512_permutex2var_epi32(a, _mm512_load_si512(ix.d[i + 2]), b));
      a3 = _mm512_add_epi32(a3, _mm512_permutex2var_epi32(a, _mm512_load_si512(ix.d[i + 3]), b));
    }
  }
  benchmark::DoNotOptimize(_mm512_add_epi32(_mm512_add_epi32(a0, a1), _mm512_add_epi32(a2, a3)));
  state.counters["ns_per_lookup"] = benchmark::Counter(static_cast<double>(state.iterations()) * kLookups,
                                                       benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
void BM_PermuteCost(benchmark::State& state) {
  if (!CpuHasAvx512()) return state.SkipWithError("needs AVX-512");
  PermuteLoop(state);
}
BENCHMARK(BM_PermuteCost);
#endif

}  // namespace
}  // namespace camsim
