#include "host_tools/report/tradeoff.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "core/pipeline/pipeline_ref.h"
#include "hal/clock.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/io/image_read.h"
#include "host_tools/io/image_write.h"
#include "host_tools/render.h"
#include "host_tools/report/plot.h"
#include "host_tools/scene_input.h"

namespace camsim::host {

const std::vector<PrecisionKnob>& PrecisionKnobs() {
  static const std::vector<PrecisionKnob> knobs = {
      {"distortion", "distortion.filter", {"bilinear", "bicubic", "lanczos3", "lanczos4"},
       "resampling kernel (2, 4, 6, 8 taps)", true},
      {"distortion", "distortion.grid_step", {"4", "8", "16", "32", "64"}, "remap table spacing, pixels"},
      {"distortion", "distortion.phases", {"16", "32", "64", "128", "256"}, "sub-pixel filter phases"},
      {"demosaic", "demosaic.method", {"bilinear", "malvar"}, "interpolation kernel (3x3 vs 5x5)", true},
      {"motion_blur", "motion.samples_per_px", {"0.25", "0.5", "1", "2", "4"}, "time samples per pixel of motion"},
      {"motion_blur", "motion.max_samples", {"2", "4", "8", "64"}, "bound on the time samples of a pixel"},
      {"dof_columns", "dof.column_window", {"8", "16", "32", "64", "128"},
       "diffusion DoF: rows solved each side per column (truncation of the column solve)"},
      {"dof_gather", "dof.max_radius_px", {"4", "8", "16", "32"}, "gather DoF: disc radius cap"},
      {"blooming", "blooming.rows", {"1", "4", "16", "64"},
       "rows a spill is followed each way (truncation of the column's charge flow)"},
  };
  return knobs;
}

namespace {

// The noise-free camera: what the references model (no temporal noise, no
// fixed patterns, no defect pixels).
constexpr const char* kNoiseOff[] = {"sensor.shot_noise=false",      "sensor.dark_noise_e=0",
                                     "sensor.dsnu_e=0",              "sensor.prnu_percent=0",
                                     "sensor.dcnu_percent=0",
                                     "sensor.row_fpn_e=0",           "sensor.column_fpn_e=0",
                                     "sensor.hot_pixel_fraction=0",  "sensor.dead_pixel_fraction=0",
                                     "sensor.stuck_pixel_fraction=0", "sensor.defects_file=\"\""};

struct Error {
  double max_abs = 0, rms = 0, psnr_db = 0;
  size_t excluded = 0;  // pixels left out: distortion fill disagreement and its spread
};

struct StageResult {
  std::string name;
  std::string unit;
  double ms = 0;  // per frame
  Error error;
};

// The end-to-end error per pixel, kept until every setting has run: the
// pixels left out are the union of every setting's (FillSpread), so that all
// settings' errors are over the same pixels.
struct PixelErrors {
  std::vector<float> sum2, max_abs;  // over the pixel's channels
  std::vector<uint8_t> skip;         // this setting's pixels to leave out
  int channels = 0;
  double peak = 1;
};

// What one run of a configuration measured.
struct Measured {
  double frame_ms = 0;
  std::vector<StageResult> stages;  // each against its own model's reference
  Error end_to_end;      // against the configured model's reference chain
  Error own_end_to_end;  // against its own model's (the same unless the knob picks a model)
  size_t fill_edge = 0;  // pixels where distortion and its reference disagree on the fill
  std::string output_unit;
  PixelErrors pixels, own_pixels;
};

// One row of the results: a knob's value and what its run measured.
struct Setting : Measured {
  std::string knob, value;  // "(as configured)" for the baseline
  bool configured = false;  // the value the configuration has
  bool frontier = false;
};

// Full scale of a domain for PSNR: DN and Q0.16 have one; radiance and photons
// take the reference's largest value.
double Peak(Domain d, int adc_bits, const ref::RefImage& want) {
  switch (d) {
    case Domain::kDigital: return std::ldexp(1.0, adc_bits) - 1.0;
    case Domain::kLinear:
    case Domain::kEncoded: return 65535.0;
    case Domain::kRadiance:
    case Domain::kPhotons: break;
  }
  double peak = 0;
  for (const auto& p : want.planes)
    for (double v : p) peak = std::max(peak, v);
  return peak > 0 ? peak : 1.0;
}

// Per pixel, the squared differences summed over channels and the largest
// one; `got` interleaves want's planes.
PixelErrors PerPixel(const std::vector<uint32_t>& got, Domain d, const ref::RefImage& want, double peak) {
  PixelErrors e;
  const size_t planes = want.planes.size(), n = want.planes.empty() ? 0 : want.planes[0].size();
  e.channels = static_cast<int>(planes);
  e.peak = peak;
  e.sum2.assign(n, 0.0f);
  e.max_abs.assign(n, 0.0f);
  for (size_t i = 0; i < n; ++i) {
    double sum2 = 0, worst = 0;
    for (size_t c = 0; c < planes; ++c) {
      const double diff = ref::SampleToReal(d, got[i * planes + c]) - want.planes[c][i];
      worst = std::max(worst, std::fabs(diff));
      sum2 += diff * diff;
    }
    e.sum2[i] = static_cast<float>(sum2);
    e.max_abs[i] = static_cast<float>(worst);
  }
  return e;
}

// The error over the pixels `skip` (empty, or one byte per pixel) does not mark.
Error Summarise(const PixelErrors& p, const std::vector<uint8_t>& skip) {
  Error e;
  double sum2 = 0;
  size_t counted = 0;
  for (size_t i = 0; i < p.sum2.size(); ++i) {
    if (!skip.empty() && skip[i]) {
      ++e.excluded;
      continue;
    }
    ++counted;
    e.max_abs = std::max(e.max_abs, static_cast<double>(p.max_abs[i]));
    sum2 += p.sum2[i];
  }
  e.rms = counted ? std::sqrt(sum2 / static_cast<double>(counted * static_cast<size_t>(p.channels))) : 0.0;
  e.psnr_db = e.rms > 0 ? 20.0 * std::log10(p.peak / e.rms) : INFINITY;
  return e;
}

ref::RefImage ToRef(const std::vector<uint32_t>& data, Domain d, int channels, int w, int h) {
  ref::RefImage r;
  r.width = w;
  r.height = h;
  r.planes.assign(static_cast<size_t>(channels), std::vector<double>(static_cast<size_t>(w) * h));
  for (size_t i = 0; i < r.planes[0].size(); ++i)
    for (int c = 0; c < channels; ++c) r.planes[c][i] = ref::SampleToReal(d, data[i * channels + c]);
  return r;
}

// The pixels whose error the fill disagreement at stage `at` (FillDisagreement)
// reaches through the later stages' neighbourhoods (demosaic's 5x5 and so on):
// `flip` dilated by the sum of their row reaches (from each stage's input row
// window over the frame) and, apart, of their column reaches (Margin).
std::vector<uint8_t> FillSpread(const Pipeline& p, int at, const std::vector<uint8_t>& flip) {
  const int w = p.width(), h = p.height();
  int rows = 0, cols = 0;
  for (int i = at + 1; i < p.plan().running; ++i) {
    const Stage& s = p.running_stage(i);
    int reach = 0;
    for (int y = 0; y < h; ++y) {
      const RowWindow win = s.InputRows(y, h);
      reach = std::max({reach, y - win.first, win.last - y});
    }
    rows += reach;
    cols += s.Margin();
  }
  std::vector<uint8_t> out(flip.size(), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (!flip[static_cast<size_t>(y) * w + x]) continue;
      for (int v = std::max(0, y - rows); v <= std::min(h - 1, y + rows); ++v)
        for (int u = std::max(0, x - cols); u <= std::min(w - 1, x + cols); ++u) out[static_cast<size_t>(v) * w + u] = 1;
    }
  return out;
}

const char* UnitName(Domain d) {
  switch (d) {
    case Domain::kRadiance: return "radiance";
    case Domain::kPhotons: return "photons";
    case Domain::kDigital: return "DN";
    case Domain::kLinear: return "Q0.16 LSB";
    case Domain::kEncoded: return "Q0.16 LSB";
  }
  return "";
}

// One configuration, ready to run: its pipeline on one worker and its
// input; `ref_p`, the pipeline of the configuration as given, gives the
// end-to-end reference, so a knob that picks a cheaper model (the remap
// filter, the demosaic method) is measured against the configured model;
// with `own_model` its own model's reference chain is measured too, and
// gives each stage's error.
struct Run {
  RunConfig rc;
  std::unique_ptr<Pipeline> p;
  const Pipeline* ref_p = nullptr;
  bool own_model = false;
  std::vector<uint8_t> workspace;
  CoreInput input;
  std::vector<FlareSource> flare_sources;
  std::vector<uint32_t> smear;
  FlareFrame flare;
  FrameInput view;
  int strip_rows = 0;
  double best_ms = INFINITY;  // the fastest timed frame
  WorkerStats best_stats;

  FrameInput Prepass() {  // part of every frame's cost, as in `camsim run`
    return p->RunPrepasses(input.View(), Span<FlareSource>{flare_sources.data(), flare_sources.size()}, &flare,
                           Span<uint32_t>{smear.data(), smear.size()});
  }
};

bool Prepare(RunConfig rc, const Pipeline& ref_p, const Origins& origins, const io::SceneFrame& scene,
             const io::FloatPlane* mask, Run* run, std::string* error) {
  // (mask is the file rc.vignetting_mask names, so the validation's pipeline is configured for it.)
  if (!FinishConfig(&rc, scene.width, scene.height, origins, 1, error, nullptr, &run->p)) return false;
  run->rc = rc;
  run->ref_p = &ref_p;
  Pipeline& p = *run->p;
  bool same_stages = ref_p.plan().running == p.plan().running;
  for (int i = 0; same_stages && i < p.plan().running; ++i)
    same_stages = std::strcmp(ref_p.running_stage(i).name(), p.running_stage(i).name()) == 0;
  if (!same_stages) {
    *error = "the knob changes which stages run; its error has no common reference";
    return false;
  }
  run->workspace.resize(p.WorkspaceBytes());
  if (!p.Init(Span<uint8_t>{run->workspace.data(), run->workspace.size()}).ok()) {
    *error = "workspace";
    return false;
  }
  PrepareInput(scene, p.width(), p.height(), rc.fit, &run->input);
  if (mask != nullptr) PrepareMask(*mask, p.width(), p.height(), &run->input);
  // The frame's pre-passes (flare sources, smear charge), then the input
  // check `camsim run` makes: a stage without its depth or vectors is an
  // error here too, not a read of a plane the scene does not have.
  run->flare_sources.resize(static_cast<size_t>(p.PrepassFlareSources()));
  run->smear.resize(static_cast<size_t>(p.PrepassSmearEntries()));
  run->view = run->Prepass();
  const Status checked = p.CheckInput(run->view);
  if (!checked.ok()) {
    *error = scene.source + ": " + checked.message();
    return false;
  }
  run->strip_rows = StripRows(0, p.height(), 1);  // as `camsim run` on one thread
  p.ProcessFrame(run->view, 0, run->strip_rows, nullptr, 0, nullptr, nullptr);  // warm caches and tables
  return true;
}

// One timed frame on one worker; the fastest counts.
void TimeFrame(Run* run) {
  const Clock clock = hal::NanosecondClock();
  WorkerStats stats;
  const uint64_t t0 = hal::NowNs();
  run->Prepass();
  run->p->ProcessFrame(run->view, 0, run->strip_rows, nullptr, 0, &stats, &clock);
  const double ms = (hal::NowNs() - t0) / 1e6;
  if (ms < run->best_ms) {
    run->best_ms = ms;
    run->best_stats = stats;
  }
}

// One untimed run with every stage tapped, against the references. False
// when a reference does not model the stage's output (its plane count).
bool Errors(const Run& run, Measured* out, std::string* error) {
  Pipeline& p = *run.p;
  const Pipeline& ref_p = *run.ref_p;
  const FrameInput& view = run.view;
  const int w = p.width(), h = p.height(), n = p.plan().running;
  out->frame_ms = run.best_ms;
  std::vector<std::vector<uint32_t>> taps(static_cast<size_t>(n));
  std::vector<Tap> tap(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    taps[i].resize(static_cast<size_t>(w) * h * p.running_format(i).channels);
    tap[i].stage = i;
    tap[i].format = TapFormat::kU32;
    tap[i].data = taps[i].data();
    tap[i].stride = static_cast<ptrdiff_t>(w) * p.running_format(i).channels;
  }
  p.ProcessFrame(view, 0, run.strip_rows, tap.data(), n, nullptr, nullptr);

  const int bits = run.rc.core.geometry.adc_bits;
  const Pipeline& own_p = run.own_model ? p : ref_p;  // each stage's model
  ref::RefImage chain = ref::SceneRadiance(view, w, h);
  ref::RefImage own_chain;  // with own_model: the chain of the run's own model
  if (run.own_model) own_chain = chain;
  out->stages.clear();
  // From the distortion stage on, the chain's error leaves out the pixels
  // where the fill decision differs (a whole pixel value, not precision).
  std::vector<uint8_t> chain_skip;
  out->fill_edge = 0;
  for (int i = 0; i < n; ++i) {
    const LineFormat f = p.running_format(i);
    const ref::RefImage in = i == 0 ? chain
                                    : ToRef(taps[i - 1], p.running_format(i - 1).domain,
                                            p.running_format(i - 1).channels, w, h);
    const ref::RefImage want = ref::RunStageReference(own_p, i, i == 0 ? chain : in, view);
    StageResult r;
    r.name = p.running_stage(i).name();
    r.unit = UnitName(f.domain);
    r.ms = run.best_stats.stage[i].ticks / 1e6;
    if (want.planes.size() != static_cast<size_t>(f.channels)) {
      *error = std::string("the ") + r.name + " stage's reference has " + std::to_string(want.planes.size()) +
               " planes for its " + std::to_string(f.channels) + " channels";
      return false;
    }
    const std::vector<uint8_t> flip = ref::FillDisagreement(p, i);
    if (!flip.empty()) {
      out->fill_edge = static_cast<size_t>(std::count(flip.begin(), flip.end(), 1));
      chain_skip = FillSpread(p, i, flip);
    }
    r.error = Summarise(PerPixel(taps[i], f.domain, want, Peak(f.domain, bits, want)), flip);
    out->stages.push_back(r);
    chain = ref::RunStageReference(ref_p, i, chain, view);
    if (run.own_model) own_chain = ref::RunStageReference(p, i, own_chain, view);
  }
  const LineFormat last = p.running_format(n - 1);
  if (chain.planes.size() != static_cast<size_t>(last.channels) ||
      (run.own_model && own_chain.planes.size() != static_cast<size_t>(last.channels))) {
    *error = "the reference chain ends with " + std::to_string(chain.planes.size()) + " planes for " +
             std::to_string(last.channels) + " channels";
    return false;
  }
  out->pixels = PerPixel(taps[n - 1], last.domain, chain, Peak(last.domain, bits, chain));
  out->pixels.skip = chain_skip;
  // (The same peak for both: PSNR on one scale.)
  if (run.own_model) out->own_pixels = PerPixel(taps[n - 1], last.domain, own_chain, out->pixels.peak);
  out->own_pixels.skip = std::move(chain_skip);
  out->output_unit = UnitName(last.domain);
  return true;
}

std::string Fmt(double v, const char* f = "%.4g") {
  if (std::isinf(v)) return "inf";
  char buf[48];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

int TradeoffCommand(const TradeoffOptions& o) {
  std::string error;
  RunConfig rc;
  Origins origins;
  if (!o.config_path.empty() && !LoadConfigFile(o.config_path, &rc, &origins, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  for (const std::string& a : o.overrides)
    if (!ApplyOverride(a, &rc, &origins, &error)) {
      std::fprintf(stderr, "camsim: %s\n", error.c_str());  // ApplyOverride names the --set
      return 1;
    }
  for (const char* a : kNoiseOff)
    if (!ApplyOverride(a, &rc, &origins, &error)) {
      std::fprintf(stderr, "camsim: %s: %s\n", a, error.c_str());
      return 1;
    }
  if (o.input.empty() || o.out_dir.empty()) {
    std::fprintf(stderr, "camsim: tradeoff needs --input EXR and --out DIR\n");
    return 1;
  }
  io::SceneFrame scene;
  if (!io::LoadSceneExr(o.input, "", &scene, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  io::FloatPlane mask;
  const bool has_mask = !rc.vignetting_mask.empty();
  if (has_mask && !ReadWeightImage(KeyWhere(origins, "vignetting.mask"), rc.vignetting_mask, kMaxMaskGain, &mask, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  const int made = mkdir(o.out_dir.c_str(), 0755);
  const int mkdir_errno = errno;
  struct stat st;
  if (stat(o.out_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    const char* why =
        made == 0 || mkdir_errno == EEXIST ? "a file of that name is in the way" : std::strerror(mkdir_errno);
    std::fprintf(stderr, "camsim: cannot create output directory '%s': %s\n", o.out_dir.c_str(), why);
    return 2;
  }
  // The files to write, checked before the sweep: a FIFO, device or
  // directory in the way is refused now; a symbolic link is written through
  // (its target replaced, as the io writers do).
  const std::string out = o.out_dir + "/tradeoff";
  const std::string names[3] = {out + ".csv", out + ".md", out + ".png"};
  std::string targets[3];
  for (int i = 0; i < 3; ++i)
    if (!io::WritableTarget(names[i], &targets[i], &error)) {
      std::fprintf(stderr, "camsim: %s\n", error.c_str());
      return 2;
    }

  // The configuration as given; it stays in the results only when no knob is
  // swept (otherwise the knob's configured value is the same run).
  std::vector<Setting> settings;
  std::vector<std::unique_ptr<Run>> runs;
  const io::FloatPlane* mask_plane = has_mask ? &mask : nullptr;
  std::unique_ptr<Pipeline> reference;  // the configuration as given: every setting's references
  RunConfig reference_rc = rc;
  if (!FinishConfig(&reference_rc, scene.width, scene.height, origins, 1, &error, nullptr, &reference)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  Setting base;
  base.knob = "(as configured)";
  base.configured = true;
  runs.push_back(std::make_unique<Run>());
  if (!Prepare(rc, *reference, origins, scene, mask_plane, runs.back().get(), &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  settings.push_back(base);
  std::vector<size_t> run_of = {0};  // each setting's run
  std::vector<std::string> running;
  for (int i = 0; i < runs[0]->p->plan().running; ++i) running.push_back(runs[0]->p->running_stage(i).name());
  std::vector<std::string> swept;
  for (const PrecisionKnob& k : PrecisionKnobs()) {
    if (std::find(running.begin(), running.end(), k.stage) == running.end()) continue;
    swept.push_back(std::string(k.key) + " (" + k.what + ")");
    for (const std::string& v : k.values) {
      RunConfig variant = rc;
      Origins vo = origins;
      if (!ApplyOverride(std::string(k.key) + "=" + v, &variant, &vo, &error)) {
        std::fprintf(stderr, "camsim: knob %s=%s: %s\n", k.key, v.c_str(), error.c_str());
        return 1;
      }
      Setting s;
      s.knob = k.key;
      s.value = v;
      s.configured = ConfigToToml(variant, false) == ConfigToToml(rc, false);
      // Each knob's configured value is the configuration as given: one run
      // for all of them, so they share one time and one error.
      if (!s.configured) {
        runs.push_back(std::make_unique<Run>());
        runs.back()->own_model = k.model;
        if (!Prepare(variant, *reference, vo, scene, mask_plane, runs.back().get(), &error)) {
          std::fprintf(stderr, "camsim: knob %s=%s: %s\n", k.key, v.c_str(), error.c_str());
          return 1;
        }
      }
      run_of.push_back(s.configured ? 0 : runs.size() - 1);
      settings.push_back(s);
    }
  }
  // Timed in rounds, one frame of every setting a round, so that a machine
  // whose speed drifts (a shared VM) slows all settings alike; each round
  // starts one setting later, so none always follows the same one.
  for (int f = 0; f < o.frames; ++f)
    for (size_t i = 0; i < runs.size(); ++i) TimeFrame(runs[(i + static_cast<size_t>(f)) % runs.size()].get());
  std::vector<Measured> measured(runs.size());
  for (size_t r = 0; r < runs.size(); ++r)
    if (!Errors(*runs[r], &measured[r], &error)) {
      std::fprintf(stderr, "camsim: tradeoff: %s\n", error.c_str());
      return 2;
    }
  // The end-to-end errors over the same pixels for every setting: all
  // settings' left-out pixels together.
  std::vector<uint8_t> left_out;
  for (const Measured& m : measured)
    if (!m.pixels.skip.empty()) {
      if (left_out.empty()) left_out.assign(m.pixels.skip.size(), 0);
      for (size_t i = 0; i < left_out.size(); ++i) left_out[i] |= m.pixels.skip[i];
    }
  for (Measured& m : measured) {
    m.end_to_end = Summarise(m.pixels, left_out);
    m.own_end_to_end = m.own_pixels.sum2.empty() ? m.end_to_end : Summarise(m.own_pixels, left_out);
    m.pixels = m.own_pixels = PixelErrors();
  }
  for (size_t i = 0; i < settings.size(); ++i) {
    static_cast<Measured&>(settings[i]) = measured[run_of[i]];
    if (i > 0)
      std::fprintf(stderr, "  %s=%s: %.2f ms, end-to-end rms %.4g %s\n", settings[i].knob.c_str(),
                   settings[i].value.c_str(), settings[i].frame_ms, settings[i].end_to_end.rms,
                   settings[i].output_unit.c_str());
  }
  runs.clear();
  if (settings.size() > 1) settings.erase(settings.begin());
  // The error-time frontier: settings no other setting beats on both.
  for (Setting& a : settings) {
    a.frontier = true;
    for (const Setting& b : settings)
      if (&a != &b && b.frame_ms <= a.frame_ms && b.end_to_end.rms <= a.end_to_end.rms &&
          (b.frame_ms < a.frame_ms || b.end_to_end.rms < a.end_to_end.rms))
        a.frontier = false;
  }

  std::ostringstream csv, md;
  // scope end_to_end: against the configured model's reference; end_to_end_own_model: against the
  // setting's own (the same unless the knob picks a model); a stage's row: against its own model's.
  csv << "knob,value,configured,scope,ms_per_frame,max_abs,rms,psnr_db,unit,excluded_px,frontier\n";
  for (const Setting& s : settings) {
    csv << s.knob << "," << s.value << "," << (s.configured ? 1 : 0) << ",end_to_end," << Fmt(s.frame_ms) << ","
        << Fmt(s.end_to_end.max_abs) << "," << Fmt(s.end_to_end.rms) << "," << Fmt(s.end_to_end.psnr_db) << ","
        << s.output_unit << "," << s.end_to_end.excluded << "," << (s.frontier ? 1 : 0) << "\n";
    csv << s.knob << "," << s.value << "," << (s.configured ? 1 : 0) << ",end_to_end_own_model,"
        << Fmt(s.frame_ms) << "," << Fmt(s.own_end_to_end.max_abs) << "," << Fmt(s.own_end_to_end.rms) << ","
        << Fmt(s.own_end_to_end.psnr_db) << "," << s.output_unit << "," << s.own_end_to_end.excluded << ",\n";
    for (const StageResult& r : s.stages)
      csv << s.knob << "," << s.value << "," << (s.configured ? 1 : 0) << "," << r.name << "," << Fmt(r.ms) << ","
          << Fmt(r.error.max_abs) << "," << Fmt(r.error.rms) << "," << Fmt(r.error.psnr_db) << "," << r.unit << ","
          << r.error.excluded << ",\n";
  }
  md << "# Error against run time\n\n";
  md << "Generated by `camsim tradeoff` on `" << o.input << "` (" << scene.width << "x" << scene.height
     << "), one thread, the fastest of " << o.frames
     << " frames per setting. Errors are against the double-precision reference on the same input, with sensor "
        "noise, DSNU, PRNU, fixed patterns and defect pixels off. The end-to-end reference is the configuration as "
        "given, so a knob that picks another model (the remap filter, the demosaic method) is measured against "
        "the configured model: what choosing it changes. Column \"RMS own model\" gives that setting's error "
        "against its own model's reference chain instead (its fixed-point precision; the same as RMS for a knob "
        "that only sets a precision), and each stage's error (the per-stage table) is against its own model. The "
        "reference does not round to whole DN, so the ADC's rounding sets the floor of the end-to-end error.\n\n"
        "Fill edge: where a pixel's source lies within the remap grid's error of the frame edge, the distortion "
        "stage and its exact reference can put it on different sides, one reading the scene and the other the "
        "black fill (docs/lens-distortion.md). That difference is a whole pixel value, not precision, so those "
        "pixels (column \"fill edge\") are counted apart and left out of the distortion stage's error; the end "
        "to end error also leaves out what the later stages spread them to (column \"left out\"), the same "
        "pixels for every setting: all settings' together.\n\n"
        "Frontier: the settings no other setting beats on both time per frame and end-to-end RMS error.\n\n"
        "No stage's fixed-point fractional bits are configurable (each stage's header states its formats as "
        "constants), so none is swept.\n\n";
  md << "Knobs swept" << (swept.empty() ? std::string(": none (no stage with a knob runs)") : ":") << "\n\n";
  for (const std::string& k : swept) md << "- `" << k << "`\n";
  md << "\n## End to end\n\n| knob | value | ms/frame | max abs | RMS | PSNR dB | RMS own model | unit | fill edge | "
        "left out | frontier |\n|---|---|---:|---:|---:|---:|---:|---|---:|---:|---|\n";
  for (const Setting& s : settings)
    md << "| " << s.knob << " | " << s.value << (s.configured && !s.value.empty() ? " (configured)" : "") << " | "
       << Fmt(s.frame_ms, "%.2f") << " | " << Fmt(s.end_to_end.max_abs) << " | " << Fmt(s.end_to_end.rms) << " | "
       << Fmt(s.end_to_end.psnr_db, "%.1f") << " | " << Fmt(s.own_end_to_end.rms) << " | " << s.output_unit << " | "
       << s.fill_edge << " | " << s.end_to_end.excluded << " | " << (s.frontier ? "yes" : "") << " |\n";
  md << "\n## Per stage (each against its own model's reference on its own fixed-point input)\n\n"
        "| knob | value | stage | ms/frame | max abs | RMS | PSNR dB | unit |\n|---|---|---|---:|---:|---:|---:|---|\n";
  for (const Setting& s : settings)
    for (const StageResult& r : s.stages)
      md << "| " << s.knob << " | " << s.value << " | " << r.name << " | " << Fmt(r.ms, "%.2f") << " | "
         << Fmt(r.error.max_abs) << " | " << Fmt(r.error.rms) << " | " << Fmt(r.error.psnr_db, "%.1f") << " | "
         << r.unit << " |\n";

  std::vector<PlotPoint> points;
  for (const Setting& s : settings) {
    PlotPoint pt;
    pt.x = s.frame_ms;
    pt.y = s.end_to_end.rms;
    pt.series = s.knob.empty() ? "configured" : s.knob;
    pt.label = s.value.empty() ? "configured" : s.value;
    pt.highlight = s.frontier;
    points.push_back(pt);
  }
  PlotSpec spec;
  spec.title = "Error against time per frame";
  spec.x_label = "ms per frame (1 thread)";
  spec.y_label = "RMS error, " + settings[0].output_unit;
  spec.log_y = true;
  // The three files belong together: each is written as TARGET.new (beside
  // the file a link points to), and only when all are written (and nothing
  // but a regular file has since taken a final name: rename would replace a
  // FIFO and cannot replace a directory) are they renamed over the old ones.
  // A signal before then removes them (as a failure does, below).
  const io::RemovedOnSignal pending[3] = {io::RemovedOnSignal(targets[0] + ".new"),
                                          io::RemovedOnSignal(targets[1] + ".new"),
                                          io::RemovedOnSignal(targets[2] + ".new")};
  bool ok = io::WriteTextFile(targets[0] + ".new", csv.str(), &error) &&
            io::WriteTextFile(targets[1] + ".new", md.str(), &error) &&
            WriteScatterPng(targets[2] + ".new", spec, points, &error);
  for (int i = 0; i < 3 && ok; ++i) {
    std::string now;
    ok = io::WritableTarget(names[i], &now, &error);
    if (ok && now != targets[i]) {
      error = "cannot write '" + names[i] + "': it became a link to '" + now + "' during the run";
      ok = false;
    }
  }
  for (int i = 0; i < 3 && ok; ++i)
    if (std::rename((targets[i] + ".new").c_str(), targets[i].c_str()) != 0) {
      error = "cannot write '" + names[i] + "': renaming '" + targets[i] + ".new' onto it failed: " +
              std::strerror(errno);
      ok = false;
    }
  if (!ok) {
    for (const std::string& n : targets) std::remove((n + ".new").c_str());
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 2;
  }
  std::fprintf(stderr, "camsim: wrote %s/tradeoff.{csv,md,png} (%zu settings)\n", o.out_dir.c_str(), settings.size());
  return 0;
}

}  // namespace camsim::host
