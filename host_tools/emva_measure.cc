#include "host_tools/emva_measure.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/aperture/exposure.h"
#include "core/base/detmath.h"

namespace camsim::host {
namespace {

constexpr double kQuantisationVariance = 1.0 / 12.0;  // DN^2, uniform rounding
constexpr double kInvSqrt2Pi = 0x1.9884533d43651p-2;  // 1 / sqrt(2 pi)
// EMVA 1288 4.0: a dark variance below this is limited by the quantisation;
// sigma_d is then given as the upper limit it sets.
constexpr double kDarkVarianceFloor = 0.24;  // DN^2
constexpr double kFitFraction = 0.70;  // EMVA 1288: fit K and R below 70 % of saturation
constexpr double kPrnuFraction = 0.50; // EMVA 1288: PRNU at 50 % of saturation

// A configured pipeline of exposure and sensor only, and its flat-field input.
class Bench {
 public:
  bool Init(const RunConfig& config, const Origins& origins, int size, std::string* error) {
    PipelineConfig p = config.core;
    p.geometry.width = size;
    p.geometry.height = size;
    p.geometry.cfa = Cfa::kBayerRG;  // unused: 3 planes, one sensor per colour
    p.order[0] = StageId::kExposure;
    p.order[1] = StageId::kSensor;
    p.order_count = 2;
    const Status s = pipeline_.Configure(p, 1, false);
    if (!s.ok()) {
      *error = DescribeStatus(s, origins);
      return false;
    }
    workspace_.resize(pipeline_.WorkspaceBytes());
    const Status i = pipeline_.Init(Span<uint8_t>{workspace_.data(), workspace_.size()});
    if (!i.ok()) {
      *error = i.message();
      return false;
    }
    size_ = size;
    photons_per_radiance_ = ExposurePhotonsPerRadiance(p.exposure);
    // The exposure stage's output saturates at 2^32 - 1 in Q24.8 photons,
    // its Q16.16 radiance input at 2^32 - 1 as well.
    max_photons_ = std::min(4294967295.0 / 256.0, 4294967295.0 / 65536.0 * photons_per_radiance_);
    for (auto& plane : planes_) plane.resize(static_cast<size_t>(size) * size);
    out_.resize(static_cast<size_t>(size) * size * 3);
    return true;
  }

  // Sets the flat field for a mean photon count per pixel; returns the exact
  // photon count of the Q16.16 radiance actually used, at most max_photons().
  double SetPhotons(double photons) {
    const double radiance = photons / photons_per_radiance_;
    const uint32_t raw = static_cast<uint32_t>(std::min(std::llround(radiance * 65536.0), 0xFFFFFFFFll));
    for (auto& plane : planes_) std::fill(plane.begin(), plane.end(), raw);
    return std::min(raw / 65536.0 * photons_per_radiance_, max_photons_);
  }
  // The most photons per pixel the exposure stage delivers (16.7 M).
  double max_photons() const { return max_photons_; }

  // One frame's output plane of channel c (after Run).
  const std::vector<uint32_t>& Run(uint32_t frame) {
    FrameInput in;
    for (int c = 0; c < 3; ++c) in.radiance[c] = MakeImageView<const uint32_t>(planes_[c].data(), size_, size_);
    Tap tap;
    tap.format = TapFormat::kU32;
    tap.data = out_.data();
    tap.stride = static_cast<ptrdiff_t>(size_) * 3;
    pipeline_.ProcessFrame(in, frame, 64, &tap, 1, nullptr, nullptr);
    return out_;
  }
  int pixels() const { return size_ * size_; }

 private:
  Pipeline pipeline_;
  std::vector<uint8_t> workspace_;
  std::vector<uint32_t> planes_[3];
  std::vector<uint32_t> out_;
  double photons_per_radiance_ = 0;
  double max_photons_ = 0;
  int size_ = 0;
};

// Mean (of both frames) and temporal variance (difference / 2) of a frame pair, per channel.
struct PairStats {
  double photons = 0;
  double mean[3] = {};
  double var[3] = {};
  double zero_share[3] = {};  // share of the pixels (both frames) that read 0
};

PairStats MeasurePair(Bench& bench, double photons, uint32_t frame) {
  PairStats s;
  s.photons = bench.SetPhotons(photons);
  const std::vector<uint32_t> a = bench.Run(frame);
  const std::vector<uint32_t>& b = bench.Run(frame + 1);
  const int n = bench.pixels();
  for (int c = 0; c < 3; ++c) {
    double sum = 0, dsum = 0, dsq = 0;
    int zeros = 0;
    for (int i = 0; i < n; ++i) {
      const double va = a[static_cast<size_t>(i) * 3 + c], vb = b[static_cast<size_t>(i) * 3 + c];
      sum += va + vb;
      dsum += va - vb;
      dsq += (va - vb) * (va - vb);
      zeros += (va == 0) + (vb == 0);
    }
    s.mean[c] = sum / (2.0 * n);
    s.zero_share[c] = zeros / (2.0 * n);
    const double dmean = dsum / n;
    s.var[c] = (dsq / n - dmean * dmean) * n / (n - 1.0) / 2.0;
  }
  return s;
}

// Average of L frames: mean and spatial variance of the averaged image, per channel.
struct AverageStats {
  double mean[3] = {};
  double spatial_var[3] = {};
};

AverageStats MeasureAverage(Bench& bench, double photons, int frames, uint32_t first_frame) {
  bench.SetPhotons(photons);
  const int n = bench.pixels();
  std::vector<double> sum(static_cast<size_t>(n) * 3, 0.0);
  for (int f = 0; f < frames; ++f) {
    const std::vector<uint32_t>& img = bench.Run(first_frame + static_cast<uint32_t>(f));
    for (size_t i = 0; i < sum.size(); ++i) sum[i] += img[i];
  }
  AverageStats s;
  for (int c = 0; c < 3; ++c) {
    double m = 0;
    for (int i = 0; i < n; ++i) m += sum[static_cast<size_t>(i) * 3 + c] / frames;
    m /= n;
    double v = 0;
    for (int i = 0; i < n; ++i) {
      const double d = sum[static_cast<size_t>(i) * 3 + c] / frames - m;
      v += d * d;
    }
    s.mean[c] = m;
    s.spatial_var[c] = v / (n - 1.0);
  }
  return s;
}

// Least-squares slope through the origin.
double SlopeThroughOrigin(const std::vector<double>& x, const std::vector<double>& y) {
  double sxy = 0, sxx = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxy += x[i] * y[i];
    sxx += x[i] * x[i];
  }
  return sxx > 0 ? sxy / sxx : 0.0;
}

// Where EMVA 1288 puts saturation for a signal clipped at c (electrons): the
// mean of min(X, c) at the maximum of its variance, X ~ N(m, m + read^2) (the
// Poisson charge with read noise). A clipped signal's variance peaks some
// sigma below the clip (2.9 sigma for a 10 000 e- well; 2.5 at 1 000 e-, 3.3
// at 100 000 e-), so an EMVA saturation capacity is always somewhat less than
// the full well (the exact clipped Poisson distribution's peak is within 2 e-
// of this one for the presets). The peak is found by golden-section search over m (the
// variance rises with the Poisson charge, then falls as the clip takes over),
// with detmath and IEEE basic operations only, so that a well derived from it
// (FullWellForEmvaSaturation) is the same on every platform.
double EmvaSaturation(double c, double read_e) {
  // Mean and variance of min(X, c) = m + s min(Z, a), X = m + s Z, a = (c - m) / s,
  // from the moments of the clipped standard normal min(Z, a).
  const auto moments = [&](double m, double* mean, double* var) {
    const double s = std::sqrt(std::max(m, 0.0) + read_e * read_e);
    const double a = (c - m) / s;
    const double phi = detmath::Exp(-0.5 * a * a) * kInvSqrt2Pi, Phi = detmath::NormalCdf(a);
    const double m1 = a * (1 - Phi) - phi;                 // E[min(Z, a)]
    const double m2 = Phi - a * phi + a * a * (1 - Phi);  // E[min(Z, a)^2]
    *mean = m + s * m1;
    *var = s * s * (m2 - m1 * m1);
  };
  const auto variance = [&](double m) {
    double mean, var;
    moments(m, &mean, &var);
    return var;
  };
  const double s0 = std::sqrt(c + read_e * read_e);
  double lo = std::max(c - 8 * s0, 0.01 * c), hi = c + 2 * s0;  // m > 0 keeps s > 0 without read noise
  constexpr double kGolden = 0.6180339887498949;  // (sqrt(5) - 1) / 2
  double x1 = hi - kGolden * (hi - lo), x2 = lo + kGolden * (hi - lo);
  double v1 = variance(x1), v2 = variance(x2);
  for (int i = 0; i < 40; ++i) {  // the bracket shrinks to 0.618^40 = 4e-9 of its 10 sigma
    if (v1 < v2) {
      lo = x1;
      x1 = x2;
      v1 = v2;
      x2 = lo + kGolden * (hi - lo);
      v2 = variance(x2);
    } else {
      hi = x2;
      x2 = x1;
      v2 = v1;
      x1 = hi - kGolden * (hi - lo);
      v1 = variance(x1);
    }
  }
  double mean, var;
  moments(0.5 * (lo + hi), &mean, &var);
  return mean;
}

// DCNU: the pixels' dark currents are the mean times max(0, 1 + s z), z
// standard normal (s = dcnu_percent / 100; emva.h). With a = 1 / s, the
// factor's mean is Phi(a) + s phi(a) and its mean square (1 + s^2) Phi(a) +
// s phi(a); *rms is its standard deviation (mean 1, rms 0 for s = 0).
void DcnuFactor(double dcnu_percent, double* mean, double* rms) {
  *mean = 1.0;
  *rms = 0.0;
  const double s = dcnu_percent / 100.0;
  if (!(s > 0)) return;
  const double a = 1.0 / s, cdf = detmath::NormalCdf(a);
  const double pdf = std::exp(-0.5 * a * a) * 0.39894228040143267794;  // phi(a): 1 / sqrt(2 pi)
  *mean = cdf + s * pdf;
  *rms = std::sqrt(std::max(0.0, (1.0 + s * s) * cdf + s * pdf - *mean * *mean));
}

// The ADC's clip in electrons above the black level.
double AdcClipElectrons(const RunConfig& config, double system_gain) {
  const double max_dn = (1 << config.core.geometry.adc_bits) - 1;
  return (max_dn - config.core.sensor.black_level_dn) / system_gain;
}

}  // namespace

EmvaFigures ConfiguredEmva(const RunConfig& config) {
  const SensorConfig& s = config.core.sensor;
  EmvaFigures f;
  // detmath, as the sensor stage computes them (and deterministic for FullWellForEmvaSaturation).
  f.system_gain = s.system_gain_dn_per_e * detmath::Pow(10.0, s.gain_db / 20.0);
  for (int c = 0; c < 3; ++c) f.qe[c] = s.quantum_efficiency[c];
  // The dark charge of the mean dark current, and its pixels' mean and spread with DCNU.
  const double mean_dark_e = s.dark_current_e_per_s * (config.core.exposure.exposure_time_us * 1e-6) *
                             detmath::Exp2((s.temperature_c - s.dark_current_ref_c) / s.dark_current_doubling_c);
  double dcnu_mean = 1.0, dcnu_rms = 0.0;
  DcnuFactor(s.dcnu_percent, &dcnu_mean, &dcnu_rms);
  const double dark_e = s.dcnu_percent > 0 ? mean_dark_e * dcnu_mean : mean_dark_e;
  const double dcnu_e = mean_dark_e * dcnu_rms;
  // Dark-current shot noise is temporal noise in the dark: EMVA folds it into sigma_d.
  f.dark_noise_e = std::sqrt(s.dark_noise_e * s.dark_noise_e + (s.shot_noise ? dark_e : 0.0));
  // Photo charge that fits: the well less the dark charge, or the ADC's range if that ends first.
  f.full_well_e = std::min(s.full_well_e, AdcClipElectrons(config, f.system_gain));
  // PRNU is left out: it spreads the pixels' clips over their responses, and
  // the variance averaged over the pixels peaks a little earlier (by 0.3-0.6 %
  // for the presets' 0.43-0.8 % PRNU, in the clipped-normal model).
  f.saturation_e = EmvaSaturation(f.full_well_e, s.dark_noise_e) - dark_e;
  const double dark_var_dn2 = f.system_gain * f.system_gain * f.dark_noise_e * f.dark_noise_e + kQuantisationVariance;
  f.dynamic_range_bits = EmvaDynamicRangeBits(f.saturation_e, dark_var_dn2, f.system_gain);
  f.snr_max = std::sqrt(f.saturation_e);
  // EMVA's DSNU is the total spatial offset variance of the dark signal at this
  // exposure time: pixel, row and column patterns and the DCNU's spread together.
  f.dsnu_e = std::sqrt(s.dsnu_e * s.dsnu_e + s.row_fpn_e * s.row_fpn_e + s.column_fpn_e * s.column_fpn_e +
                       dcnu_e * dcnu_e);
  f.prnu_percent = s.prnu_percent;
  return f;
}

double DcnuPercentForSpreadRatio(double ratio_percent) {
  const auto ratio = [](double percent) {
    double mean = 1.0, rms = 0.0;
    DcnuFactor(percent, &mean, &rms);
    return 100.0 * rms / mean;
  };
  if (!(ratio_percent > 0)) return 0.0;
  if (ratio_percent >= ratio(100.0)) return 100.0;
  double lo = 0.0, hi = 100.0;  // the ratio grows with the percentage
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (ratio(mid) < ratio_percent ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

bool FullWellForEmvaSaturation(const RunConfig& config, double saturation_e, double* full_well_e,
                               std::string* error) {
  RunConfig c = config;
  const auto saturation = [&](double well) {
    c.core.sensor.full_well_e = well;
    return ConfiguredEmva(c).saturation_e;
  };
  // Bisection between the saturation itself (a well there saturates below it)
  // and the ADC's clip (above it the ADC clips first and the saturation stops
  // growing); 50 halvings leave far less than 0.001 e-.
  double lo = saturation_e, hi = AdcClipElectrons(config, ConfiguredEmva(config).system_gain);
  if (!(saturation(hi) > saturation_e)) {
    char b[200];
    std::snprintf(b, sizeof b,
                  "an EMVA saturation capacity of %.1f e- needs a well at or above the ADC's clip (%.1f e-)",
                  saturation_e, hi);
    *error = b;
    return false;
  }
  for (int i = 0; i < 50; ++i) {
    const double mid = 0.5 * (lo + hi);
    (saturation(mid) < saturation_e ? lo : hi) = mid;
  }
  *full_well_e = hi;
  return true;
}

bool MeasureEmva(const RunConfig& config, const Origins& origins, const EmvaOptions& o, EmvaReport* report,
                 std::string* error) {
  if (o.size < 16 || o.size > 4096 || o.levels < 20 || o.levels > 1000 || o.average_frames < 2 ||
      o.average_frames > 256) {
    *error = "emva: size must be 16..4096, levels 20..1000, average frames 2..256";
    return false;
  }
  Bench bench;
  if (!bench.Init(config, origins, o.size, error)) return false;
  constexpr int kG = 1;
  uint32_t frame = 0;  // every frame pair gets its own frame numbers (independent noise)
  const PairStats dark = MeasurePair(bench, 0.0, frame);
  frame += 2;
  if (dark.zero_share[kG] > kEmvaMaxDarkZeroShare) {
    const auto origin = origins.find("sensor.black_level_dn");
    char b[400];
    std::snprintf(b, sizeof b,
                  "emva: %.3g %% of the dark pixels read 0, more than the 0.5 %% EMVA 1288 allows: the dark signal "
                  "is clipped at 0, so its noise and DSNU would read low; raise sensor.black_level_dn (%g DN, %s)",
                  100.0 * dark.zero_share[kG], config.core.sensor.black_level_dn,
                  origin != origins.end() ? ("from " + origin->second).c_str() : "the default");
    *error = b;
    return false;
  }

  // Past saturation: the signal above dark stops doubling when the photons
  // double. The search must stay within what the exposure stage delivers:
  // beyond that the photons stop growing, not the signal.
  double p_max = 16.0;
  double previous = 0, clipped = 0;
  for (int i = 0;; ++i, p_max *= 2.0) {
    if (p_max > bench.max_photons()) {
      const EmvaFigures c = ConfiguredEmva(config);
      char b[400];
      std::snprintf(b, sizeof b,
                    "emva: no saturation below %.0f photons per pixel, the most the exposure stage delivers (its "
                    "Q24.8 output): the clip of %.0f e- (the well or the ADC's range) at G's quantum efficiency "
                    "%.3g takes %.0f; lower sensor.full_well_e or raise sensor.quantum_efficiency",
                    bench.max_photons(), c.full_well_e, c.qe[kG], c.full_well_e / c.qe[kG]);
      *error = b;
      return false;
    }
    const PairStats s = MeasurePair(bench, p_max, frame);
    frame += 2;
    const double signal = s.mean[kG] - dark.mean[kG];
    if (i > 0 && signal < 1.2 * previous) {
      clipped = signal;
      break;
    }
    previous = signal;
  }
  // p_max is 1.7-3.3 times the saturation: levels up to it would lie 1.7-3.3 %
  // of it apart and miss the variance peak (which is narrow: the variance
  // falls by a quarter within 2 sigma above it) by up to that much. So bracket
  // the clip: bisect for the photons at half the clipped signal (where the
  // response is linear), and end the levels at 1.2 times the clip, 2.4 times
  // that. Saturation, 2.5-3.3 sigma below the clip, then falls at 75-83 % of
  // the range: 100 levels step 1.2-1.35 % of it. The highest level's
  // variance stays EMVA's (and the datasets') estimate: a parabola through it
  // and its neighbours halves the scatter but is pulled low by the lopsided
  // peak (the variance rises under 1 % per sigma below it, falls steeply
  // above): presets -0.7 to -1.1 % against -0.3 to -1.0 % at 256 x 256.
  // Bigger frames (--size) are what reduce the scatter.
  double lo = 0, hi = p_max;
  for (int i = 0; i < 10; ++i) {  // to p_max / 1024
    const double mid = 0.5 * (lo + hi);
    const PairStats s = MeasurePair(bench, mid, frame);
    frame += 2;
    (s.mean[kG] - dark.mean[kG] < 0.5 * clipped ? lo : hi) = mid;
  }
  const double p_top = std::min(2.4 * 0.5 * (lo + hi), p_max);

  std::vector<PairStats> points;
  for (int i = 1; i <= o.levels; ++i) {
    points.push_back(MeasurePair(bench, p_top * i / o.levels, frame));
    frame += 2;
  }

  EmvaReport r;
  r.configured = ConfiguredEmva(config);
  std::vector<TransferLevel> levels;
  for (const PairStats& p : points) {
    TransferLevel l;
    l.photons = p.photons;
    l.mean = p.mean[kG];
    l.var = p.var[kG];
    l.dark_mean = dark.mean[kG];
    l.dark_var = dark.var[kG];
    levels.push_back(l);
  }
  TransferFit fit;
  if (!FitPhotonTransfer(levels, dark.var[kG], &fit, error)) return false;
  r.saturation_photons = fit.saturation_photons;
  r.top_photons = points.back().photons;
  r.fit_points = fit.fit_points;
  const double K = fit.system_gain;
  r.measured.system_gain = K;
  // QE per channel: its responsivity over its own levels below 70 % of its
  // own saturation (a channel more sensitive than G saturates first), over K.
  for (int c = 0; c < 3; ++c) {
    std::vector<TransferLevel> channel;
    for (const PairStats& p : points) channel.push_back({p.photons, p.mean[c], p.var[c], dark.mean[c], dark.var[c]});
    TransferFit channel_fit;
    std::string channel_error;
    if (!FitPhotonTransfer(channel, dark.var[c], &channel_fit, &channel_error)) {
      *error = std::string("emva: channel ") + "RGB"[c] + ": " + channel_error;
      return false;
    }
    r.measured.qe[c] = channel_fit.responsivity / K;
  }
  r.measured.dark_noise_e = fit.dark_noise_e;
  r.measured.dark_noise_upper_limit = fit.dark_noise_upper_limit;
  r.measured.saturation_e = fit.saturation_e;
  r.measured.dynamic_range_bits = fit.dynamic_range_bits;
  r.measured.snr_max = fit.snr_max;

  // DSNU and PRNU from averages of L frames.
  const int L = o.average_frames;
  const AverageStats dark_avg = MeasureAverage(bench, 0.0, L, frame);
  frame += static_cast<uint32_t>(L);
  const double p50 = kPrnuFraction * r.saturation_photons;
  const PairStats half = MeasurePair(bench, p50, frame);
  frame += 2;
  const AverageStats half_avg = MeasureAverage(bench, p50, L, frame);
  const FrameStack dark_stack{dark_avg.mean[kG], dark_avg.spatial_var[kG], dark.var[kG], L};
  const FrameStack half_stack{half_avg.mean[kG], half_avg.spatial_var[kG], half.var[kG], L};
  if (!NonUniformity(dark_stack, half_stack, K, &r.measured.dsnu_e, &r.measured.prnu_percent, error)) return false;
  *report = r;
  return true;
}

bool FitPhotonTransfer(const std::vector<TransferLevel>& levels, double dark_var, TransferFit* fit,
                       std::string* error) {
  if (levels.empty()) {
    *error = "emva: no photon levels";
    return false;
  }
  size_t sat = 0;  // EMVA 1288: saturation at the maximum of the temporal variance
  for (size_t i = 1; i < levels.size(); ++i)
    if (levels[i].var > levels[sat].var) sat = i;
  if (!(levels[sat].var > dark_var)) {
    *error = "emva: the temporal variance never rises above the dark variance: no photon transfer to fit "
             "(a noiseless sensor, or a bright series without light)";
    return false;
  }
  const double sat_signal = levels[sat].mean - levels[sat].dark_mean;
  TransferFit f;
  f.saturation_photons = levels[sat].photons;
  std::vector<double> x, y, p;
  for (size_t i = 0; i < sat; ++i) {
    const double signal = levels[i].mean - levels[i].dark_mean;
    if (signal > kFitFraction * sat_signal) break;
    x.push_back(signal);
    y.push_back(levels[i].var - levels[i].dark_var);
    p.push_back(levels[i].photons);
  }
  f.fit_points = static_cast<int>(x.size());
  if (f.fit_points < 5) {
    *error = "emva: fewer than 5 levels below 70 % of saturation (" + std::to_string(f.fit_points) +
             "); measure more levels";
    return false;
  }
  f.system_gain = SlopeThroughOrigin(x, y);
  if (!(f.system_gain > 0)) {
    *error = "emva: the temporal variance does not grow with the signal (system gain <= 0)";
    return false;
  }
  f.responsivity = SlopeThroughOrigin(p, x);
  if (!(f.responsivity > 0)) {
    *error = "emva: the signal does not grow with the photon count (responsivity <= 0): check the photon values";
    return false;
  }
  f.dark_noise_upper_limit = dark_var < kDarkVarianceFloor;
  f.dark_noise_e = std::sqrt(std::max(dark_var, kDarkVarianceFloor) - kQuantisationVariance) / f.system_gain;
  f.saturation_e = f.responsivity / f.system_gain * f.saturation_photons;  // QE * mu_p.sat
  f.dynamic_range_bits = EmvaDynamicRangeBits(f.saturation_e, dark_var, f.system_gain);
  f.snr_max = std::sqrt(f.saturation_e);
  *fit = f;
  return true;
}

double EmvaDynamicRangeBits(double saturation_e, double dark_var_dn2, double system_gain) {
  const double sigma_y_dark = std::sqrt(std::max(dark_var_dn2, kDarkVarianceFloor));
  return std::log2(saturation_e / (sigma_y_dark / system_gain + 0.5));
}

bool NonUniformity(const FrameStack& dark, const FrameStack& bright, double K, double* dsnu_e, double* prnu_percent,
                   std::string* error) {
  if (!(bright.mean > dark.mean)) {
    *error = "emva: the bright stack's mean (" + std::to_string(bright.mean) + " DN) is not above the dark stack's (" +
             std::to_string(dark.mean) + " DN): no signal to measure the PRNU against";
    return false;
  }
  // The averaged image keeps 1/L of the temporal variance: take it out.
  const double s2_dark = dark.spatial_var - dark.temporal_var / dark.frames;
  const double s2_bright = bright.spatial_var - bright.temporal_var / bright.frames;
  *dsnu_e = std::sqrt(std::max(0.0, s2_dark)) / K;
  *prnu_percent = 100.0 * std::sqrt(std::max(0.0, s2_bright - s2_dark)) / (bright.mean - dark.mean);
  return true;
}

std::string FormatEmvaReport(const std::string& title, const EmvaReport& r) {
  std::string t = "EMVA 1288 photon-transfer measurement: " + title + "\n";
  char line[200];
  std::snprintf(line, sizeof line, "%-30s %12s %12s %9s\n", "quantity", "configured", "measured", "error");
  t += line;
  const auto row = [&](const char* name, double configured, double measured) {
    std::snprintf(line, sizeof line, "%-30s %12.4g %12.4g %+8.2f%%\n", name, configured, measured,
                  configured != 0 ? 100.0 * (measured - configured) / configured : 0.0);
    t += line;
  };
  row("system gain K (DN/e-)", r.configured.system_gain, r.measured.system_gain);
  row("quantum efficiency R", r.configured.qe[0], r.measured.qe[0]);
  row("quantum efficiency G", r.configured.qe[1], r.measured.qe[1]);
  row("quantum efficiency B", r.configured.qe[2], r.measured.qe[2]);
  row("temporal dark noise (e-)", r.configured.dark_noise_e, r.measured.dark_noise_e);
  if (r.measured.dark_noise_upper_limit)
    t += "  (an upper limit, and the dynamic range a lower one: the dark variance is below 0.24 DN^2, where "
         "quantisation hides the dark noise)\n";
  std::snprintf(line, sizeof line, "%-30s %12.4g\n", "full well or ADC clip (e-)", r.configured.full_well_e);
  t += line;
  row("saturation capacity (e-)", r.configured.saturation_e, r.measured.saturation_e);
  row("dynamic range (bit)", r.configured.dynamic_range_bits, r.measured.dynamic_range_bits);
  row("maximum SNR", r.configured.snr_max, r.measured.snr_max);
  row("DSNU (e-)", r.configured.dsnu_e, r.measured.dsnu_e);
  row("PRNU (%)", r.configured.prnu_percent, r.measured.prnu_percent);
  std::snprintf(line, sizeof line,
                "(saturation at %.0f photons of levels up to %.0f; K and QE fitted on %d levels)\n",
                r.saturation_photons, r.top_photons, r.fit_points);
  t += line;
  return t;
}

}  // namespace camsim::host
