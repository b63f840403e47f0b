// camsim stages against OpenCV doing the closest job, on the same frame and
// one thread each (cv::setNumThreads(1)). bench_main.cc prints camsim/peer.
//
//   Demosaic: camsim's bilinear demosaic (eq. 23-24) on the demo camera's
//     white-balanced mosaic vs cv::cvtColor(COLOR_BayerBG2RGB) on the same
//     samples as 16-bit and as 8-bit (OpenCV's BayerBG is GenICam's BayerRG:
//     OpenCV names the 2x2 cell starting at (1, 1)). camsim works on its
//     32-bit line format. Each side's error is measured once, on the frame it
//     was timed writing, against one reference for both: the double bilinear
//     demosaic of the 16-bit mosaic (x 255/65535 for the 8-bit pair), away
//     from a 2-pixel border where OpenCV pads differently.
//   Every benchmark of a pair runs its job once untimed before the timed
//     loop, so neither side pays its buffers' first touch in the timing.
//   Noise: camsim's EMVA 1288 sensor stage (Poisson shot noise, dark noise,
//     DSNU, PRNU, saturation, quantisation; counter-based) vs cv::randn filling
//     a float image with one Gaussian per pixel (sequential generator): a
//     lower bound for any noise model, not the same job. The same job as that
//     randn is BM_Peer_CamsimGaussian: one standard normal per pixel,
//     counter-based as the sensor draws its read noise (a Philox4x32 call per
//     pixel pair, GaussianTable), into an int32 Q15.16 plane of the same size.
//     The same job as the sensor stage is BM_Peer_OpenCVEmva: the model built
//     from OpenCV's float operations (its fixed pattern drawn every frame, or
//     stored as camsim's sensor.fixed_pattern_table stores it).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "bench/stage_bench.h"
#include "core/base/random.h"
#include "core/isp/isp_ref.h"
#include "core/sensor/emva.h"

namespace camsim {
namespace {

using bench::Demo;
using bench::Scene;

constexpr int kBorder = 2;  // pixels left out of the error at each edge

// A pipeline configured and initialised, and the running index of one of its stages.
struct ConfiguredStage {
  Pipeline pipeline;
  std::vector<uint8_t> workspace;
  int index = -1;
  ConfiguredStage(const PipelineConfig& c, const char* stage) {
    if (!pipeline.Configure(c, 1, false).ok()) std::abort();
    workspace.resize(pipeline.WorkspaceBytes());
    if (!pipeline.Init(Span<uint8_t>{workspace.data(), workspace.size()}).ok()) std::abort();
    for (int i = 0; i < pipeline.plan().running; ++i)
      if (std::strcmp(pipeline.running_stage(i).name(), stage) == 0) index = i;
    if (index < 0) std::abort();
  }
};

// The demo camera with bilinear demosaic.
struct Bilinear : ConfiguredStage {
  Bilinear(int w, int h) : ConfiguredStage(Config(w, h), "demosaic") {}
  static PipelineConfig Config(int w, int h) {
    PipelineConfig c = Demo(w, h);
    c.demosaic.method = DemosaicMethod::kBilinear;
    return c;
  }
};

// Max and rms of |got - want * scale| over the interior and the three
// channels of an interleaved RGB frame; want: the reference's planes.
struct DemosaicError {
  double max = 0, rms = 0;
};
DemosaicError InteriorError(const ref::RefImage& want, double scale, int w, int h, const auto& got) {
  double worst = 0.0, sum2 = 0.0, n = 0.0;
  for (int c = 0; c < 3; ++c)
    for (int y = kBorder; y < h - kBorder; ++y)
      for (int x = kBorder; x < w - kBorder; ++x) {
        const double d =
            std::fabs(static_cast<double>(got(x, y, c)) - want.planes[static_cast<size_t>(c)][static_cast<size_t>(y) * w + x] * scale);
        worst = std::fmax(worst, d);
        sum2 += d * d;
        n += 1;
      }
  return {worst, std::sqrt(sum2 / n)};
}

// The 8-bit samples OpenCV's 8-bit demosaic reads: round(v * 255 / 65535).
uint8_t To8Bits(uint32_t v) { return static_cast<uint8_t>((std::min(v, 0xFFFFu) + 128u) / 257u); }

// The demosaic pairs' references, built once from the white-balanced mosaic
// both sides read: the double bilinear demosaic of the 16-bit mosaic (the
// reference of both pairs; for the 8-bit pair scaled by 255 / 65535), and
// of the 8-bit mosaic OpenCV's 8-bit side reads.
struct DemosaicReference {
  ref::RefImage of16, of8;
};
const DemosaicReference& DemosaicRef(const Bilinear& b, const std::vector<uint32_t>& mosaic, int w, int h) {
  static const DemosaicReference r = [&] {
    const Cfa cfa = b.pipeline.config().geometry.cfa;
    ref::RefImage in16{w, h, {std::vector<double>(mosaic.size())}}, in8{w, h, {std::vector<double>(mosaic.size())}};
    for (size_t i = 0; i < mosaic.size(); ++i) {
      in16.planes[0][i] = std::min(mosaic[i], 0xFFFFu);
      in8.planes[0][i] = To8Bits(mosaic[i]);
    }
    return DemosaicReference{ref::RefDemosaicBilinear(in16, cfa), ref::RefDemosaicBilinear(in8, cfa)};
  }();
  return r;
}

// Each side's error on the frame it was timed writing, measured once per side
// and bit depth ([camsim, OpenCV][16-bit, 8-bit]; [..][..][0]: against the
// 16-bit reference, [1]: against the 8-bit one); the notes once both sides ran.
DemosaicError demosaic_error[2][2][2];
bool demosaic_measured[2][2] = {};
void MeasureDemosaicError(int side, int bits, const Bilinear& b, const std::vector<uint32_t>& mosaic, int w, int h,
                          const auto& got) {
  const int depth = bits == 8 ? 1 : 0;
  if (demosaic_measured[side][depth]) return;
  demosaic_measured[side][depth] = true;
  const DemosaicReference& r = DemosaicRef(b, mosaic, w, h);
  demosaic_error[side][depth][0] = InteriorError(r.of16, bits == 8 ? 255.0 / 65535.0 : 1.0, w, h, got);
  if (bits == 8) demosaic_error[side][depth][1] = InteriorError(r.of8, 1.0, w, h, got);
  if (!demosaic_measured[0][depth] || !demosaic_measured[1][depth]) return;
  const DemosaicError(&e)[2][2][2] = demosaic_error;
  static char note16[200], note8[300];
  if (bits == 16) {
    std::snprintf(note16, sizeof note16,
                  "max/rms vs the double bilinear of the 16-bit mosaic: camsim %.3f/%.3f, OpenCV %.3f/%.3f (16-bit LSB)",
                  e[0][0][0].max, e[0][0][0].rms, e[1][0][0].max, e[1][0][0].rms);
    bench::SetPeerError("bilinear demosaic, 16-bit", note16);
  } else {
    std::snprintf(note8, sizeof note8,
                  "max/rms vs the double bilinear of the 16-bit mosaic x 255/65535: camsim %.3f/%.3f, OpenCV %.3f/%.3f "
                  "(8-bit LSB; vs that of the 8-bit mosaic OpenCV reads: camsim %.3f/%.3f, OpenCV %.3f/%.3f)",
                  e[0][1][0].max, e[0][1][0].rms, e[1][1][0].max, e[1][1][0].rms, e[0][1][1].max, e[0][1][1].rms,
                  e[1][1][1].max, e[1][1][1].rms);
    bench::SetPeerError("bilinear demosaic, 8-bit", note8);
  }
}

// Last argument: the interleaved RGB frame it writes, 16 or 8 bits a sample,
// as cv::cvtColor writes its output Mat. Its error is measured on that frame.
void BM_Peer_CamsimDemosaic(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const int bits = static_cast<int>(state.range(2));
  Bilinear b(w, h);
  const FrameInput in = Scene(w).View();
  bench::StageRunner runner(b.pipeline, b.index, in, 1);
  runner.SetOutput(bits == 8 ? TapFormat::kU8 : TapFormat::kU16);
  uint32_t frame = 0;
  // One frame untimed on both sides of every pair: Google Benchmark calls
  // this function afresh for each iteration estimate and repetition, and a
  // first call would pay its buffers' allocation and first touch.
  runner.RunFrame(frame++);
  for (auto _ : state) {
    runner.RunFrame(frame++);
    benchmark::DoNotOptimize(runner.output_frame().data());
  }
  const uint8_t* out = runner.output_frame().data();
  const size_t stride = static_cast<size_t>(w) * 3;
  if (bits == 8)
    MeasureDemosaicError(0, 8, b, runner.input_frame(), w, h,
                         [&](int x, int y, int c) { return out[y * stride + 3 * static_cast<size_t>(x) + c]; });
  else
    MeasureDemosaicError(0, 16, b, runner.input_frame(), w, h, [&](int x, int y, int c) {
      return reinterpret_cast<const uint16_t*>(out)[y * stride + 3 * static_cast<size_t>(x) + c];
    });
}
BENCHMARK(BM_Peer_CamsimDemosaic)->Args({1920, 1080, 16})->Args({1920, 1080, 8})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Peer_OpenCVDemosaic(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const int bits = static_cast<int>(state.range(2));
  cv::setNumThreads(1);
  Bilinear b(w, h);
  const FrameInput in = Scene(w).View();
  bench::StageRunner runner(b.pipeline, b.index, in, 1);
  const std::vector<uint32_t>& mosaic = runner.input_frame();
  cv::Mat m(h, w, bits == 8 ? CV_8UC1 : CV_16UC1), rgb;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const uint32_t v = mosaic[static_cast<size_t>(y) * w + x];
      if (bits == 8)
        m.at<uint8_t>(y, x) = To8Bits(v);
      else
        m.at<uint16_t>(y, x) = static_cast<uint16_t>(std::min(v, 0xFFFFu));
    }
  cv::cvtColor(m, rgb, cv::COLOR_BayerBG2RGB);  // untimed, as camsim's side
  for (auto _ : state) {
    cv::cvtColor(m, rgb, cv::COLOR_BayerBG2RGB);
    benchmark::DoNotOptimize(rgb.data);
  }
  if (bits == 8)
    MeasureDemosaicError(1, 8, b, mosaic, w, h, [&](int x, int y, int c) { return rgb.at<cv::Vec3b>(y, x)[c]; });
  else
    MeasureDemosaicError(1, 16, b, mosaic, w, h, [&](int x, int y, int c) { return rgb.at<cv::Vec3w>(y, x)[c]; });
}
BENCHMARK(BM_Peer_OpenCVDemosaic)->Args({1920, 1080, 16})->Args({1920, 1080, 8})->Unit(benchmark::kMillisecond)->UseRealTime();

// The demo camera, for its sensor stage (pattern_table: sensor.fixed_pattern_table).
struct SensorAlone : ConfiguredStage {
  SensorAlone(int w, int h, bool pattern_table) : ConfiguredStage(Config(w, h, pattern_table), "sensor") {}
  static PipelineConfig Config(int w, int h, bool pattern_table) {
    PipelineConfig c = Demo(w, h);
    c.sensor.fixed_pattern_table = pattern_table;
    return c;
  }
  const SensorStage& stage() const { return static_cast<const SensorStage&>(pipeline.running_stage(index)); }
};

// The sensor stage alone over its captured input (photons at the Bayer
// sites). Last argument: 1 builds the fixed pattern once
// (sensor.fixed_pattern_table), 0 draws it every frame (the default).
void BM_Peer_CamsimNoise(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  SensorAlone s(w, h, state.range(2) != 0);
  const FrameInput in = Scene(w).View();
  bench::StageRunner runner(s.pipeline, s.index, in, 1);
  runner.SetOutput(TapFormat::kU16);  // the raw frame in DN, as OpenCV's model writes its CV_16U Mat
  uint32_t frame = 0;
  runner.RunFrame(frame++);  // untimed, as the peers' first call (BM_Peer_CamsimDemosaic)
  for (auto _ : state) {
    runner.RunFrame(frame++);
    benchmark::DoNotOptimize(runner.output_frame().data());
  }
}
BENCHMARK(BM_Peer_CamsimNoise)->Args({1920, 1080, 0})->Args({1920, 1080, 1})->Unit(benchmark::kMillisecond)->UseRealTime();

// The same EMVA 1288 model as OpenCV operations on float images, what one
// would write without camsim, on the same photons and parameters: QE per CFA
// site; PRNU gain 1 + prnu z1 and DSNU offset dsnu z2 from cv::randn, drawn
// every frame (BM_Peer_OpenCVEmva's last argument 1, as camsim's default) or
// once (0, as sensor.fixed_pattern_table); shot noise by the normal
// approximation mu + sqrt(mu) z3 for every mean (OpenCV has no Poisson
// sampler; camsim draws the exact Poisson below 12 e-), clipped at the full
// well; read noise sigma_d z4; DN = K v + black level, rounded and saturated
// by convertTo.
struct OpenCvEmva {
  const SensorConfig sc;
  const double k, dark_e;
  cv::Mat qe, gain, dsnu, mu, sigma, z, v;
  OpenCvEmva(const SensorAlone& s, int w, int h)
      : sc(s.pipeline.config().sensor),
        k(s.stage().system_gain()),
        dark_e(s.stage().dark_electrons()),
        qe(h, w, CV_32FC1),
        gain(h, w, CV_32FC1),
        dsnu(h, w, CV_32FC1),
        z(h, w, CV_32FC1) {
    const Cfa cfa = s.pipeline.config().geometry.cfa;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) qe.at<float>(y, x) = static_cast<float>(sc.quantum_efficiency[CfaColour(cfa, x, y)]);
    DrawPattern();
  }
  void DrawPattern() {
    cv::randn(gain, 1.0, sc.prnu_percent / 100.0);  // 1 + prnu z1
    cv::randn(dsnu, 0.0, sc.dsnu_e);
  }
  void Frame(const cv::Mat& photons, cv::Mat* dn) {
    cv::multiply(photons, qe, mu);
    cv::multiply(mu, gain, mu);
    cv::add(mu, cv::Scalar(dark_e), mu);
    cv::sqrt(mu, sigma);
    cv::randn(z, 0.0, 1.0);
    cv::multiply(sigma, z, sigma);
    cv::add(mu, sigma, v);
    cv::min(v, cv::Scalar(sc.full_well_e), v);
    cv::randn(z, 0.0, sc.dark_noise_e);
    cv::add(v, z, v);
    cv::add(v, dsnu, v);
    v.convertTo(*dn, CV_16U, k, sc.black_level_dn);
  }
};

// The photons of a captured sensor input (Q24.8) as a float image.
cv::Mat PhotonsImage(const std::vector<uint32_t>& q8, int w, int h) {
  cv::Mat photons(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) photons.at<float>(y, x) = static_cast<float>(q8[static_cast<size_t>(y) * w + x] / 256.0);
  return photons;
}

// The noise pair's error, measured once: flat fields at a ladder of levels
// through camsim's sensor stage and the OpenCV model. Over each CFA site's
// pixels of one frame (the patterns vary over pixels as the temporal noise
// does), the mean and variance against the model's:
//   mean = K m + black,  var = K^2 (m + (p QE prnu)^2 + dsnu^2 + sigma_d^2) + 1/12,
// m = p QE + dark charge: Poisson variance m plus PRNU's, the offsets, read
// noise and the rounding. The levels stay 5 sd below the full well, so
// neither clip matters.
void MeasureNoiseErrors(const SensorAlone& s, OpenCvEmva& model, int w, int h) {
  static bool done = false;
  if (done) return;
  done = true;
  const FrameInput in = Scene(w).View();
  bench::StageRunner runner(s.pipeline, s.index, in, 1);
  runner.SetOutput(TapFormat::kU16);
  const SensorConfig& sc = model.sc;
  const Cfa cfa = s.pipeline.config().geometry.cfa;
  const double prnu = sc.prnu_percent / 100.0;
  constexpr double kGreenElectrons[] = {0, 1, 3, 10, 30, 100, 300, 1000, 3000, 8000};
  double worst_z[2] = {0, 0}, worst_var[2] = {0, 0}, var_sd = 0;
  cv::Mat dn;
  for (const double level : kGreenElectrons) {
    const uint32_t q8 = static_cast<uint32_t>(std::lround(level / sc.quantum_efficiency[kGreen] * 256.0));
    const double p = q8 / 256.0;
    runner.SetInput(std::vector<uint32_t>(static_cast<size_t>(w) * h, q8));
    runner.RunFrame(0);
    model.Frame(PhotonsImage(runner.input_frame(), w, h), &dn);
    const auto* ours = reinterpret_cast<const uint16_t*>(runner.output_frame().data());
    for (int site = 0; site < 4; ++site) {
      const int sx = site & 1, sy = site >> 1;
      const double m = p * sc.quantum_efficiency[CfaColour(cfa, sx, sy)] + model.dark_e;
      const double signal_prnu = (m - model.dark_e) * prnu;
      const double want_mean = model.k * m + sc.black_level_dn;
      const double want_var = model.k * model.k *
                                  (m + signal_prnu * signal_prnu + sc.dsnu_e * sc.dsnu_e +
                                   sc.dark_noise_e * sc.dark_noise_e) +
                              1.0 / 12.0;
      for (int who = 0; who < 2; ++who) {
        double sum = 0, sum2 = 0, n = 0;
        for (int y = sy; y < h; y += 2)
          for (int x = sx; x < w; x += 2) {
            const double d = (who == 0 ? ours[static_cast<size_t>(y) * w + x] : dn.at<uint16_t>(y, x)) - want_mean;
            sum += d;
            sum2 += d * d;
            n += 1;
          }
        const double mean_err = sum / n, var = sum2 / n - mean_err * mean_err;
        worst_z[who] = std::fmax(worst_z[who], std::fabs(mean_err) / std::sqrt(want_var / n));
        worst_var[who] = std::fmax(worst_var[who], std::fabs(var / want_var - 1.0));
        var_sd = std::sqrt(2.0 / n);  // the variance's relative sampling sd (normal samples)
      }
    }
  }
  static char note[200];
  std::snprintf(note, sizeof note,
                "flat fields 0..8000 e-, 4 sites: worst mean error camsim %.1f, OpenCV %.1f standard errors; "
                "variance camsim %.2f %%, OpenCV %.2f %% (sampling sd %.2f %%)",
                worst_z[0], worst_z[1], 100 * worst_var[0], 100 * worst_var[1], 100 * var_sd);
  bench::SetPeerError("sensor noise vs the model in OpenCV", note);
  bench::SetPeerError("the same, fixed pattern stored", note);
}

void BM_Peer_OpenCVEmva(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const bool pattern_per_frame = state.range(2) != 0;
  cv::setNumThreads(1);
  SensorAlone s(w, h, false);
  const PipelineConfig& config = s.pipeline.config();
  const FrameInput in = Scene(w).View();
  const bench::StageRunner runner(s.pipeline, s.index, in, 1);
  if (runner.input_channels() != 1) std::abort();
  OpenCvEmva model(s, w, h);
  MeasureNoiseErrors(s, model, w, h);
  const cv::Mat photons = PhotonsImage(runner.input_frame(), w, h);
  cv::Mat dn;
  const auto frame = [&] {
    if (pattern_per_frame) model.DrawPattern();
    model.Frame(photons, &dn);
    benchmark::DoNotOptimize(dn.data);
  };
  frame();  // untimed, as camsim's side: mu, sigma, v and dn allocated, z written
  for (auto _ : state) frame();
  // A check that it is the same job: the frame's mean DN against the model's
  // mean (ReferenceSensorMeanDn per pixel; the patterns and noises have zero mean).
  const Cfa cfa = config.geometry.cfa;
  double got = 0.0, want = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      got += dn.at<uint16_t>(y, x);
      want += ReferenceSensorMeanDn(config.sensor, config.geometry, config.exposure.exposure_time_us,
                                    CfaColour(cfa, x, y), photons.at<float>(y, x));
    }
  state.counters["mean_dn_minus_model"] = (got - want) / (static_cast<double>(w) * h);
}
BENCHMARK(BM_Peer_OpenCVEmva)->Args({1920, 1080, 1})->Args({1920, 1080, 0})->Unit(benchmark::kMillisecond)->UseRealTime();

// How close a plane of samples is to the standard normal: the
// Kolmogorov-Smirnov distance sup |F_n - Phi| (a perfect generator gives
// about 0.87 / sqrt(n)), and the count beyond 4 sd against Phi's (expected
// n * 6.33e-5).
struct NormalFit {
  double ks = 0, tail_ratio = 0;
  bool done = false;
};
NormalFit FitNormal(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const double n = static_cast<double>(v.size());
  NormalFit fit;
  double tail = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    const double phi = 0.5 * std::erfc(-v[i] / std::sqrt(2.0));
    fit.ks = std::fmax(fit.ks, std::fmax(static_cast<double>(i + 1) / n - phi, phi - static_cast<double>(i) / n));
    if (std::fabs(v[i]) > 4.0) tail += 1;
  }
  fit.tail_ratio = tail / (n * std::erfc(4.0 / std::sqrt(2.0)));
  fit.done = true;
  return fit;
}

// The Gaussian pair's error note, once both sides have measured theirs.
NormalFit camsim_fit, randn_fit;
void SetGaussianError() {
  if (!camsim_fit.done || !randn_fit.done) return;
  static char note[200];
  std::snprintf(note, sizeof note,
                "against N(0, 1): KS distance camsim %.5f, randn %.5f (sampling ~%.5f); beyond 4 sd camsim %.2f, "
                "randn %.2f x expected",
                camsim_fit.ks, randn_fit.ks, 0.87 / std::sqrt(1920.0 * 1080.0), camsim_fit.tail_ratio,
                randn_fit.tail_ratio);
  bench::SetPeerError("one Gaussian per pixel, counter-based vs randn", note);
}

void BM_Peer_OpenCVRandn(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  cv::setNumThreads(1);
  cv::Mat noise(h, w, CV_32FC1);
  cv::randn(noise, 0.0, 1.0);  // untimed, as camsim's side: the plane's pages touched
  for (auto _ : state) {
    cv::randn(noise, 0.0, 1.0);
    benchmark::DoNotOptimize(noise.data);
  }
  if (!randn_fit.done && w == 1920 && h == 1080) {
    randn_fit = FitNormal(std::vector<double>(noise.begin<float>(), noise.end<float>()));
    SetGaussianError();
  }
}
BENCHMARK(BM_Peer_OpenCVRandn)->Args({1920, 1080})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Peer_CamsimGaussian(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  std::vector<int32_t> table(GaussianTable::kEntries);
  GaussianTable gauss;
  if (!gauss.Build(Span<int32_t>{table.data(), table.size()}).ok()) std::abort();
  std::vector<int32_t> plane(static_cast<size_t>(w) * h);
  constexpr int kBlock = 2 * RandomLanes::kLanes;  // pixels per DrawBitsLanes, as the sensor
  constexpr uint64_t kSeed = 1;
  uint32_t frame = 0;
  const auto draw_frame = [&] {
    for (int y = 0; y < h; ++y) {
      int32_t* row = plane.data() + static_cast<size_t>(y) * w;
      for (int x0 = 0; x0 < w; x0 += kBlock) {
        RandomLanes t;
        DrawBitsLanes(kSeed, 0, frame, static_cast<uint32_t>(x0) >> 1, static_cast<uint32_t>(y), 0, &t);
        // Pixel x takes word 2 (x & 1) + 1 of its pair's call: words 1 and 3.
        int32_t z[2][RandomLanes::kLanes];
        gauss.SampleLanes(t.v[1], z[0], RandomLanes::kLanes);
        gauss.SampleLanes(t.v[3], z[1], RandomLanes::kLanes);
        const int n = w - x0 < kBlock ? w - x0 : kBlock;
        if (n == kBlock) {  // pairs by lanes: a shape the compiler turns into vector shuffles
          for (int i = 0; i < RandomLanes::kLanes; ++i) {
            row[x0 + 2 * i] = z[0][i];
            row[x0 + 2 * i + 1] = z[1][i];
          }
        } else {
          for (int i = 0; i < n; ++i) row[x0 + i] = z[i & 1][i >> 1];
        }
      }
    }
    benchmark::DoNotOptimize(plane.data());
    ++frame;
  };
  draw_frame();  // untimed, as the OpenCV side
  for (auto _ : state) draw_frame();
  // A check that the plane is standard normal (so the pair compares like with like).
  if (!camsim_fit.done && w == 1920 && h == 1080) {
    std::vector<double> z(plane.size());
    for (size_t i = 0; i < plane.size(); ++i) z[i] = plane[i] / 65536.0;
    camsim_fit = FitNormal(std::move(z));
    SetGaussianError();
  }
}
BENCHMARK(BM_Peer_CamsimGaussian)->Args({1920, 1080})->Unit(benchmark::kMillisecond)->UseRealTime();

// Registered before main runs (static initialisation order within this file).
const bool kPairs = [] {
  bench::AddPeerPair("BM_Peer_CamsimDemosaic/1920/1080/16", "BM_Peer_OpenCVDemosaic/1920/1080/16",
                     "bilinear demosaic, 16-bit");
  bench::AddPeerPair("BM_Peer_CamsimDemosaic/1920/1080/8", "BM_Peer_OpenCVDemosaic/1920/1080/8",
                     "bilinear demosaic, 8-bit");
  bench::AddPeerPair("BM_Peer_CamsimNoise/1920/1080/0", "BM_Peer_OpenCVRandn/1920/1080",
                     "sensor noise vs one Gaussian per pixel",
                     "not the same job: one Gaussian per pixel is a lower bound for any noise model; no error compared");
  bench::AddPeerPair("BM_Peer_CamsimNoise/1920/1080/0", "BM_Peer_OpenCVEmva/1920/1080/1",
                     "sensor noise vs the model in OpenCV");
  bench::AddPeerPair("BM_Peer_CamsimNoise/1920/1080/1", "BM_Peer_OpenCVEmva/1920/1080/0",
                     "the same, fixed pattern stored");
  bench::AddPeerPair("BM_Peer_CamsimGaussian/1920/1080", "BM_Peer_OpenCVRandn/1920/1080",
                     "one Gaussian per pixel, counter-based vs randn");
  return true;
}();

}  // namespace
}  // namespace camsim
