#include "host_tools/emva_dataset.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <vector>

#include "host_tools/io/image_read.h"
#include "host_tools/io/text_read.h"

namespace camsim::host {
namespace {

// One series of the descriptor: a "b" or "d" line and its "i" lines.
struct Series {
  bool bright = false;
  double exposure = 0, photons = 0;
  std::vector<std::string> images;
  int line = 0;  // of the "b" / "d" line
};

struct Descriptor {
  int bits = 0, width = 0, height = 0;
  std::vector<Series> series;
};

bool ParseNumber(const std::string& s, double* v) {
  std::string t = s;
  std::replace(t.begin(), t.end(), ',', '.');  // some labs write decimal commas
  char* end = nullptr;
  *v = std::strtod(t.c_str(), &end);
  return end != t.c_str() && *end == '\0' && std::isfinite(*v) && *v >= 0;
}

bool ParseDescriptor(const std::string& path, Descriptor* out, std::string* error) {
  std::string file, why;
  if (!io::ReadTextFile(path, &file, &why)) {
    *error = path + ": cannot read the EMVA 1288 descriptor: " + why;
    return false;
  }
  std::istringstream in(file);
  const std::string dir = path.find('/') == std::string::npos ? "" : path.substr(0, path.rfind('/') + 1);
  Descriptor d;
  std::string text;
  int line = 0;
  const auto fail = [&](const std::string& what) {
    *error = path + ":" + std::to_string(line) + ": " + what;
    return false;
  };
  while (std::getline(in, text)) {
    ++line;
    std::istringstream words(text);
    std::vector<std::string> w;
    for (std::string x; words >> x;) w.push_back(x);
    if (w.empty() || w[0][0] == '#') continue;
    const std::string& key = w[0];
    if (key == "v") continue;
    if (key == "n") {
      long bits = 0, width = 0, height = 0;
      const auto whole = [](const std::string& t, long* v) {  // all of t, or 0 (refused below)
        char* end = nullptr;
        *v = std::strtol(t.c_str(), &end, 10);
        if (end == t.c_str() || *end != '\0') *v = 0;
      };
      if (w.size() == 4) {
        whole(w[1], &bits);
        whole(w[2], &width);
        whole(w[3], &height);
      }
      if (w.size() != 4 || bits < 1 || bits > 16 || width < 2 || width > 16384 || height < 2 || height > 16384)
        return fail("expected 'n BITS WIDTH HEIGHT' with BITS 1..16 and a size of 2..16384");
      if (d.bits != 0) return fail("a second 'n' line");
      d.bits = static_cast<int>(bits);
      d.width = static_cast<int>(width);
      d.height = static_cast<int>(height);
    } else if (key == "b" || key == "d") {
      Series s;
      s.bright = key == "b";
      s.line = line;
      if (w.size() != (s.bright ? 3u : 2u) || !ParseNumber(w[1], &s.exposure) ||
          (s.bright && !ParseNumber(w[2], &s.photons)))
        return fail(s.bright ? "expected 'b EXPOSURE PHOTONS' (numbers >= 0)" : "expected 'd EXPOSURE' (a number >= 0)");
      d.series.push_back(s);
    } else if (key == "i") {
      if (w.size() != 2) return fail("expected 'i PATH' (no spaces in the path)");
      if (d.series.empty()) return fail("an image before any 'b' or 'd' line");
      std::string p = w[1];
      std::replace(p.begin(), p.end(), '\\', '/');
      d.series.back().images.push_back(p[0] == '/' ? p : dir + p);
    } else {
      return fail("unknown line '" + key + "' (expected v, n, b, d, i or #)");
    }
  }
  if (d.bits == 0) {
    *error = path + ": no 'n BITS WIDTH HEIGHT' line";
    return false;
  }
  for (const Series& s : d.series)
    if (s.images.size() < 2) {
      line = s.line;
      return fail("a series needs at least 2 images (a pair, or a stack)");
    }
  *out = std::move(d);
  return true;
}

// Streams a series' images, checking each against the descriptor.
class ImageReader {
 public:
  explicit ImageReader(const Descriptor& d) : d_(d) {}
  bool Read(const std::string& path, std::vector<uint16_t>* v, std::string* error) const {
    int w = 0, h = 0, depth = 0;
    if (!io::ReadPngGrayRaw(path, v, &w, &h, &depth, error)) return false;
    if (w != d_.width || h != d_.height) {
      *error = "'" + path + "' is " + std::to_string(w) + "x" + std::to_string(h) + ", the descriptor says " +
               std::to_string(d_.width) + "x" + std::to_string(d_.height);
      return false;
    }
    const uint16_t max = static_cast<uint16_t>((1u << d_.bits) - 1);
    const auto hi = std::max_element(v->begin(), v->end());
    if (hi != v->end() && *hi > max) {
      *error = "'" + path + "' holds " + std::to_string(*hi) + ", above the descriptor's " +
               std::to_string(d_.bits) + "-bit range (raw values expected, not scaled ones)";
      return false;
    }
    return true;
  }

 private:
  const Descriptor& d_;
};

// Mean of a pair, its temporal variance (of the difference, / 2) and, unless
// null, the share of its pixels (both images) that read 0 and the spatial
// variance of the pair's average (temporal share included).
bool PairOf(const ImageReader& r, const Series& s, double* mean, double* var, double* zero_share,
            double* spatial_var, std::string* error) {
  std::vector<uint16_t> a, b;
  if (!r.Read(s.images[0], &a, error) || !r.Read(s.images[1], &b, error)) return false;
  const double n = static_cast<double>(a.size());
  double sum = 0, dsum = 0, dsq = 0;
  size_t zeros = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = static_cast<double>(a[i]) - b[i];
    sum += static_cast<double>(a[i]) + b[i];
    dsum += d;
    dsq += d * d;
    zeros += (a[i] == 0) + (b[i] == 0);
  }
  if (zero_share != nullptr) *zero_share = static_cast<double>(zeros) / (2 * n);
  *mean = sum / (2 * n);
  *var = (dsq / n - (dsum / n) * (dsum / n)) * n / (n - 1) / 2;
  if (spatial_var != nullptr) {
    double ss = 0;
    for (size_t i = 0; i < a.size(); ++i) {
      const double d = 0.5 * (static_cast<double>(a[i]) + b[i]) - *mean;
      ss += d * d;
    }
    *spatial_var = ss / (n - 1);
  }
  return true;
}

bool StackOf(const ImageReader& r, const Series& s, FrameStack* out, std::string* error) {
  std::vector<double> sum, sq;
  std::vector<uint16_t> v;
  for (const std::string& p : s.images) {
    if (!r.Read(p, &v, error)) return false;
    if (sum.empty()) sum.assign(v.size(), 0.0), sq.assign(v.size(), 0.0);
    for (size_t i = 0; i < v.size(); ++i) {
      sum[i] += v[i];
      sq[i] += static_cast<double>(v[i]) * v[i];
    }
  }
  const double L = static_cast<double>(s.images.size()), n = static_cast<double>(sum.size());
  double m = 0, temporal = 0;
  for (size_t i = 0; i < sum.size(); ++i) {
    m += sum[i] / L;
    temporal += (sq[i] - sum[i] * sum[i] / L) / (L - 1);  // per pixel, unbiased
  }
  m /= n;
  double spatial = 0;
  for (double x : sum) spatial += (x / L - m) * (x / L - m);
  out->mean = m;
  out->spatial_var = spatial / (n - 1);
  out->temporal_var = temporal / n;
  out->frames = static_cast<int>(L);
  return true;
}

// Fits the dark pairs' spatial variance as a + b t^2 (least squares):
// sqrt(b) / K is the dark current's spatial rms. Not measurable with fewer
// than 2 exposure times, or when the mean dark signal grows by less than
// 1 e- over them (no dark current to take a spread of).
DcnuEstimate EstimateDcnu(std::vector<DcnuPoint> points, double dark_current_e, double K) {
  DcnuEstimate e;
  std::sort(points.begin(), points.end(),
            [](const DcnuPoint& a, const DcnuPoint& b) { return a.exposure < b.exposure; });
  e.points = points;
  size_t times = 0;
  for (size_t i = 0; i < points.size(); ++i) times += i == 0 || points[i].exposure != points[i - 1].exposure;
  char b[300];
  if (times < 2) {
    std::snprintf(b, sizeof b, "the dark pairs are at %zu exposure time; the spread's growth needs 2 or more", times);
    e.not_measurable = b;
    return e;
  }
  const double t_min = points.front().exposure, t_max = points.back().exposure;
  const double growth_e = dark_current_e * (t_max - t_min);
  if (!(growth_e >= 1.0)) {
    std::snprintf(b, sizeof b,
                  "the mean dark signal grows by %.3g e- from exposure %g to %g, less than 1 e-: no dark current to "
                  "take a spread of",
                  growth_e, t_min, t_max);
    e.not_measurable = b;
    return e;
  }
  double sx = 0, sy = 0;
  for (const DcnuPoint& p : points) sx += p.exposure * p.exposure, sy += p.spatial_var_dn2;
  const double n = static_cast<double>(points.size());
  sx /= n;
  sy /= n;
  double sxx = 0, sxy = 0;
  for (const DcnuPoint& p : points) {
    const double x = p.exposure * p.exposure - sx;
    sxx += x * x;
    sxy += x * (p.spatial_var_dn2 - sy);
  }
  e.slope_dn2 = sxy / sxx;
  e.intercept_dn2 = sy - e.slope_dn2 * sx;
  e.measured = true;
  // A spread that does not grow (noise around 0) is no DCNU.
  e.spread_e = std::sqrt(std::max(0.0, e.slope_dn2)) / K;
  e.ratio_percent = 100.0 * e.spread_e / dark_current_e;
  e.dcnu_percent = DcnuPercentForSpreadRatio(e.ratio_percent);
  return e;
}

}  // namespace

bool MeasureEmvaDataset(const std::string& path, EmvaDatasetReport* report, std::string* error) {
  Descriptor d;
  if (!ParseDescriptor(path, &d, error)) return false;
  const ImageReader reader(d);
  EmvaDatasetReport r;
  r.bits = d.bits;
  r.width = d.width;
  r.height = d.height;

  // Dark pairs by exposure; the shortest gives sigma_d and the black level.
  struct DarkPair {
    double exposure, mean, var, spatial_var;
  };
  std::vector<DarkPair> darks;
  const Series* dark_stack = nullptr;
  const Series* bright_stack = nullptr;
  for (const Series& s : d.series) {
    if (s.images.size() > 2) {
      (s.bright ? bright_stack : dark_stack) = &s;
      continue;
    }
    if (s.bright) continue;
    DarkPair p{s.exposure, 0, 0, 0};
    double zero_share = 0;
    if (!PairOf(reader, s, &p.mean, &p.var, &zero_share, &p.spatial_var, error)) return false;
    // A dark pair at 0 is clipped (the dark stack is taken at one of the pairs' exposures).
    if (zero_share > kEmvaMaxDarkZeroShare) {
      char b[300];
      std::snprintf(b, sizeof b,
                    ": %.3g %% of the dark pixels read 0, more than the 0.5 %% EMVA 1288 allows: the dark signal "
                    "is clipped at 0, so its noise and DSNU would read low; record with a higher offset (black level)",
                    100.0 * zero_share);
      *error = path + ":" + std::to_string(s.line) + b;
      return false;
    }
    darks.push_back(p);
  }
  if (darks.empty()) {
    *error = path + ": no dark pair ('d' with 2 images)";
    return false;
  }
  const auto shortest = std::min_element(darks.begin(), darks.end(),
                                         [](const DarkPair& a, const DarkPair& b) { return a.exposure < b.exposure; });
  r.dark_mean_dn = shortest->mean;

  std::vector<TransferLevel> levels;
  r.exposure_min = INFINITY;
  for (const Series& s : d.series) {
    if (!s.bright || s.images.size() != 2) continue;
    const auto dark = std::find_if(darks.begin(), darks.end(), [&](const DarkPair& p) { return p.exposure == s.exposure; });
    if (dark == darks.end()) {
      *error = path + ":" + std::to_string(s.line) + ": no dark pair at this exposure time";
      return false;
    }
    TransferLevel l;
    l.photons = s.photons;
    if (!PairOf(reader, s, &l.mean, &l.var, nullptr, nullptr, error)) return false;
    l.dark_mean = dark->mean;
    l.dark_var = dark->var;
    levels.push_back(l);
    r.exposure_min = std::min(r.exposure_min, s.exposure);
    r.exposure_max = std::max(r.exposure_max, s.exposure);
  }
  // Dark current: slope of mu_y.dark against the exposure time, in DN, then / K below.
  double dark_slope_dn = 0;
  if (darks.size() >= 2) {
    double st = 0, sm = 0;
    for (const DarkPair& p : darks) st += p.exposure, sm += p.mean;
    st /= darks.size();
    sm /= darks.size();
    double stt = 0, stm = 0;
    for (const DarkPair& p : darks) stt += (p.exposure - st) * (p.exposure - st), stm += (p.exposure - st) * (p.mean - sm);
    if (stt > 0) dark_slope_dn = stm / stt;
  }
  std::sort(levels.begin(), levels.end(), [](const TransferLevel& a, const TransferLevel& b) { return a.photons < b.photons; });
  r.levels = static_cast<int>(levels.size());
  if (!FitPhotonTransfer(levels, shortest->var, &r.fit, error)) {
    *error = path + ": " + *error;
    return false;
  }
  r.dark_current_e = dark_slope_dn / r.fit.system_gain;
  std::vector<DcnuPoint> points;
  for (const DarkPair& p : darks) points.push_back({p.exposure, p.spatial_var - p.var / 2, p.var});
  r.dcnu = EstimateDcnu(points, r.dark_current_e, r.fit.system_gain);
  if (dark_stack != nullptr && bright_stack != nullptr) {
    FrameStack ds, bs;
    if (!StackOf(reader, *dark_stack, &ds, error) || !StackOf(reader, *bright_stack, &bs, error)) return false;
    if (!NonUniformity(ds, bs, r.fit.system_gain, &r.dsnu_e, &r.prnu_percent, error)) {
      *error = path + ": " + *error;
      return false;
    }
    r.has_nonuniformity = true;
    r.stack_photons = bright_stack->photons;
  }
  *report = r;
  return true;
}

std::string FormatEmvaDatasetReport(const std::string& descriptor, const EmvaDatasetReport& r) {
  char b[2048];
  const double qe = r.fit.responsivity / r.fit.system_gain;
  std::snprintf(b, sizeof b,
                "EMVA 1288 photon-transfer measurement of the dataset %s\n"
                "(%dx%d, %d bits, %d bright pairs, exposure %g .. %g as written)\n"
                "%-30s %12.4g\n%-30s %12.4g\n%-30s %12.4g\n%-30s %12.4g\n%-30s %12.4g\n%-30s %12.4g\n"
                "%-30s %12.4g\n%-30s %12.4g  (per unit of exposure as written)\n"
                "(saturation at %.0f photons; K and QE fitted on %d levels)\n",
                descriptor.c_str(), r.width, r.height, r.bits, r.levels, r.exposure_min, r.exposure_max,
                "system gain K (DN/e-)", r.fit.system_gain, "quantum efficiency", qe, "temporal dark noise (e-)",
                r.fit.dark_noise_e, "saturation capacity (e-)", r.fit.saturation_e, "dynamic range (bit)",
                r.fit.dynamic_range_bits, "maximum SNR", r.fit.snr_max, "dark level (DN)", r.dark_mean_dn,
                "dark current (e-)", r.dark_current_e, r.fit.saturation_photons, r.fit.fit_points);
  std::string t = b;
  const DcnuEstimate& dc = r.dcnu;
  if (dc.measured) {
    std::snprintf(b, sizeof b,
                  "%-30s %12.4g  (per unit of exposure as written)\n%-30s %12.4g  (sensor.dcnu_percent %.4g in "
                  "camsim's clipped-normal model)\n(DCNU: the dark pairs' spatial variance, temporal / 2 removed, "
                  "fitted as a + b t^2: a %.4g DN^2, b %.4g DN^2 per unit^2%s)\n%14s %16s %12s %16s\n",
                  "DCNU (e-, dark current rms)", dc.spread_e, "DCNU (% of the dark current)", dc.ratio_percent,
                  dc.dcnu_percent, dc.intercept_dn2, dc.slope_dn2,
                  dc.slope_dn2 > 0 ? "" : "; it does not grow: no DCNU", "exposure", "spatial (DN^2)", "fit (DN^2)",
                  "temporal (DN^2)");
    t += b;
    for (const DcnuPoint& p : dc.points) {
      std::snprintf(b, sizeof b, "%14g %16.4g %12.4g %16.4g\n", p.exposure, p.spatial_var_dn2,
                    dc.intercept_dn2 + dc.slope_dn2 * p.exposure * p.exposure, p.temporal_var_dn2);
      t += b;
    }
  } else {
    t += "DCNU: not measurable: " + dc.not_measurable + "\n";
  }
  // EMVA 1288 4.0: a dark variance below 0.24 DN^2 gives only an upper limit.
  if (r.fit.dark_noise_upper_limit)
    t += "note: the temporal dark noise is an upper limit, and the dynamic range a lower one: the dark variance is "
         "below 0.24 DN^2, where quantisation hides the dark noise\n";
  if (r.has_nonuniformity) {
    std::snprintf(b, sizeof b, "%-30s %12.4g\n%-30s %12.4g\n(non-uniformity: stacks at 0 and %.0f photons)\n",
                  "DSNU (e-)", r.dsnu_e, "PRNU (%)", r.prnu_percent, r.stack_photons);
    t += b;
  } else {
    t += "DSNU, PRNU: not measured (the dataset has no dark and bright stack)\n";
  }
  // A starting point for a preset: the measured figures as camsim keys.
  std::snprintf(b, sizeof b,
                "\n[sensor]\nadc_bits = %d\nquantum_efficiency = [%.3f, %.3f, %.3f]\ndark_noise_e = %.2f%s\n"
                "system_gain_dn_per_e = %.4f\nblack_level_dn = %.1f\n",
                r.bits, qe, qe, qe, r.fit.dark_noise_e, r.fit.dark_noise_upper_limit ? "  # an upper limit" : "",
                r.fit.system_gain, r.dark_mean_dn);
  t += b;
  if (r.has_nonuniformity) {
    std::snprintf(b, sizeof b, "dsnu_e = %.2f\nprnu_percent = %.2f\n", r.dsnu_e, r.prnu_percent);
    t += b;
  }
  if (dc.measured) {
    std::snprintf(b, sizeof b, "dcnu_percent = %.2f\n", dc.dcnu_percent);
    t += b;
  }
  return t;
}

}  // namespace camsim::host
