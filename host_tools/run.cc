#include "host_tools/run.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include "hal/clock.h"
#include "host_tools/presets.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/io/image_read.h"
#include "host_tools/io/image_write.h"
#include "host_tools/io/sequence.h"
#include "host_tools/render.h"
#include "host_tools/scene_input.h"

namespace camsim::host {
namespace {

std::string Stem(const std::string& path) {
  std::string name = path.substr(path.find_last_of('/') + 1);
  const size_t dot = name.find_last_of('.');
  return dot == std::string::npos ? name : name.substr(0, dot);
}

// The name a --dump-stages image of running stage r takes after the stem.
std::string DumpSuffix(int r, StageId id) {
  std::string s = ".";  // appended step by step: GCC 12's -Wrestrict misreads "." + std::string
  s += std::to_string(r);
  s += '_';
  s += StageName(id);
  return s;
}

// The raw sensor output's files: a PGM for one channel (mono or mosaic), a PPM
// for three (RGB, when no CFA stage runs), the .raw samples and their sidecar.
std::vector<std::string> RawOutputs(const std::string& stem, int channels) {
  return {stem + (channels == 3 ? ".raw.ppm" : ".raw.pgm"), stem + ".raw", stem + ".raw.json"};
}

// The files a frame with this stem writes under `plan` (as the writers in
// RunCommand name them).
std::vector<std::string> FrameOutputs(const std::string& stem, const Plan& plan, bool dump_stages) {
  std::vector<std::string> out;
  const Domain d = plan.output.domain;
  int r = 0, sensor = -1, raw_channels = plan.output.channels;
  for (int i = 0; i < plan.count; ++i)
    if (plan.entries[i].runs) {
      if (plan.entries[i].id == StageId::kSensor) {
        sensor = r;
        raw_channels = plan.entries[i].out.channels;
      }
      if (dump_stages) out.push_back(stem + DumpSuffix(r, plan.entries[i].id) + ".exr");
      ++r;
    }
  if (d == Domain::kLinear || d == Domain::kEncoded) out.push_back(stem + ".png");
  else if (d != Domain::kDigital) out.push_back(stem + ".exr");
  if (d == Domain::kDigital || sensor >= 0) {
    const std::vector<std::string> raw = RawOutputs(stem, raw_channels);
    out.insert(out.end(), raw.begin(), raw.end());
  }
  return out;
}

// A path as the file system resolves it, to compare names: the directory
// always, the last component only when `follow` (an input is read through a
// symbolic link; an output is written through one too, but its target may not
// exist yet: OutputKey).
std::string Resolved(const std::string& path, bool follow) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p(path);
  fs::path r;
  if (follow) r = fs::weakly_canonical(p, ec);
  else r = fs::weakly_canonical(fs::absolute(p, ec).parent_path(), ec) / p.filename();
  return ec ? path : r.lexically_normal().string();
}

// The file an output path writes (its symbolic links followed, as the
// writers do, to a target that may not exist yet), resolved as by Resolved.
std::string OutputKey(const std::string& path) {
  std::string error;
  const std::string target = io::FollowSymlinks(path, &error);
  return Resolved(target.empty() ? path : target, false);
}

// Claims the output paths of `who`; false (*error naming both) when one would
// overwrite an input or a file another frame (or the report) writes.
bool ClaimOutputs(const std::vector<std::string>& paths, const std::string& who,
                  const std::map<std::string, std::string>& inputs, std::map<std::string, std::string>* claimed,
                  std::string* error) {
  for (const std::string& p : paths) {
    const std::string key = OutputKey(p);
    const auto in = inputs.find(key);
    if (in != inputs.end()) {
      *error = who + " would write '" + p + "', overwriting the input " + in->second;
      return false;
    }
    const auto [at, fresh] = claimed->emplace(key, who);
    if (!fresh && at->second != who) {
      *error = at->second + " and " + who + " would both write '" + p + "' (outputs are named after the input file)";
      return false;
    }
  }
  return true;
}

constexpr char kReportVersion[] = "0.2.0";  // the report's camsim_version (0.2.0: measured time_saved_ms_per_frame)

// The length of the well-formed UTF-8 sequence at s[i] (RFC 3629: no
// overlong forms, surrogates or code points beyond U+10FFFF), 0 if none.
size_t Utf8SequenceAt(const std::string& s, size_t i) {
  const auto at = [&s](size_t k) { return k < s.size() ? static_cast<unsigned char>(s[k]) : 0u; };
  const unsigned c = at(i);
  const auto tail = [&](size_t k) { return at(k) >= 0x80 && at(k) <= 0xBF; };
  if (c < 0x80) return 1;
  if (c >= 0xC2 && c <= 0xDF) return tail(i + 1) ? 2 : 0;
  if (c >= 0xE0 && c <= 0xEF) {
    const unsigned lo = c == 0xE0 ? 0xA0 : 0x80, hi = c == 0xED ? 0x9F : 0xBF;
    return at(i + 1) >= lo && at(i + 1) <= hi && tail(i + 2) ? 3 : 0;
  }
  if (c >= 0xF0 && c <= 0xF4) {
    const unsigned lo = c == 0xF0 ? 0x90 : 0x80, hi = c == 0xF4 ? 0x8F : 0xBF;
    return at(i + 1) >= lo && at(i + 1) <= hi && tail(i + 2) && tail(i + 3) ? 4 : 0;
  }
  return 0;
}

// A JSON string: quotes, backslashes and control characters escaped, and a
// byte that is not part of well-formed UTF-8 (a file name or an EXR channel
// name can hold any bytes) as U+FFFD, so that the report always parses.
std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (size_t i = 0; i < s.size();) {
    const char ch = s[i];
    const size_t n = Utf8SequenceAt(s, i);
    if (n == 0) {
      out += "\\ufffd";
      ++i;
      continue;
    }
    if (n > 1) {
      out.append(s, i, n);
      i += n;
      continue;
    }
    ++i;
    if (ch == '"' || ch == '\\') out += '\\';
    if (static_cast<unsigned char>(ch) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", ch);
      out += buf;
      continue;
    }
    out += ch;
  }
  return out + "\"";
}

// What the EXR reader replaced (exr_scene.h's rules), as a JSON object.
std::string SanitisedJson(const io::InputSanitizeStats& st) {
  return "{\"nan\": " + std::to_string(st.nan) + ", \"pos_inf\": " + std::to_string(st.pos_inf) +
         ", \"neg_inf\": " + std::to_string(st.neg_inf) + ", \"negative\": " + std::to_string(st.negative) +
         ", \"first_replaced\": " +
         (st.first_channel.empty() ? std::string("null")
                                   : "{\"channel\": " + JsonString(st.first_channel) + ", \"x\": " +
                                         std::to_string(st.first_x) + ", \"y\": " + std::to_string(st.first_y) + "}") +
         "}";
}

// Writes the report: to `path`, atomically (io::WriteTextFile), or with
// --report - to standard output.
bool WriteReport(const std::string& path, const std::string& text, std::string* error) {
  if (path != "-") return io::WriteTextFile(path, text, error);
  errno = 0;
  if (std::fwrite(text.data(), 1, text.size(), stdout) != text.size() || std::fflush(stdout) != 0) {
    *error = std::string("cannot write the report to standard output: ") +
             (errno != 0 ? std::strerror(errno) : "write error");
    return false;
  }
  return true;
}

// The report of a run that failed before it had a pipeline: its error alone.
std::string ErrorReportJson(const std::string& error) {
  return std::string("{\n  \"camsim_version\": \"") + kReportVersion + "\",\n  \"frames\": [],\n  \"error\": " +
         JsonString(error) + "\n}\n";
}

std::string Num(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// Physical unit of a domain's samples, for the report.
const char* UnitOf(Domain d) {
  switch (d) {
    case Domain::kRadiance: return "radiance";
    case Domain::kPhotons: return "photons";
    case Domain::kDigital: return "DN";
    case Domain::kLinear: return "fraction of full scale (linear)";
    case Domain::kEncoded: return "fraction of full scale (encoded)";
  }
  return "";
}

struct FrameRecord {
  std::string input;
  std::vector<std::string> outputs;
  double wall_ms = 0;
  io::InputSanitizeStats radiance_stats, depth_stats;
  std::string layout;
  bool has_depth = false, has_motion = false;    // loaded
  bool depth_used = false, motion_used = false;  // read by a running stage
  bool has_ae = false;                          // auto exposure ran on this frame
  double ae_brightness = 0, ae_error_ev = 0;
  ExposureSettings ae_settings;                 // the settings this frame was taken with
};

// --measure-savings: each frame timed again in rounds, with the stages'
// skipping on and off (PipelineConfig::skip_idle), alternating; per frame the
// fastest round of each, summed over frames.
struct SavingsMeasured {
  int rounds = 0;
  int frames = 0;
  double stage_on_ms[kStageCount] = {}, stage_off_ms[kStageCount] = {};  // by running index
  double wall_on_ms = 0, wall_off_ms = 0;
};

struct Accumulated {
  WorkerStats stats;  // summed over frames and workers
  std::vector<FrameRecord> frames;
  SavingsMeasured savings;
};

// Auto exposure's settings into the configuration of the next frame.
bool ApplyExposure(const ExposureSettings& s, RunConfig* rc) {
  rc->core.exposure.exposure_time_us = s.exposure_time_us;
  rc->core.exposure.f_number = s.f_number;
  rc->core.sensor.gain_db = s.gain_db;
  return true;
}

// A metering weight image resampled to the sensor, Q0.16 (values clamped to [0, 1]).
bool MeteringWeights(const io::FloatPlane& map, int width, int height, std::vector<uint16_t>* out, std::string* error) {
  if (map.width < 1 || map.height < 1) {
    *error = "auto_exposure.metering_image: empty image";
    return false;
  }
  const io::FloatPlane fitted = FitPlane(map, width, height, SceneFit::kScale);
  out->resize(fitted.data.size());
  uint64_t total = 0;  // of the Q0.16 weights the meter uses
  for (size_t i = 0; i < out->size(); ++i) {
    const float v = fitted.data[i];
    const double c = v > 0 ? (v < 1 ? v : 1.0) : 0.0;
    (*out)[i] = static_cast<uint16_t>(c * 65535.0 + 0.5);
    total += (*out)[i];
  }
  if (total == 0) {
    *error = "auto_exposure.metering_image: all weights are 0 (below 1/131070) at the sensor's size";
    return false;
  }
  return true;
}

// The brightness an ideal sensor (no noise, no patterns) would measure on the
// input: weighted mean of the R, G, B radiance times photons per radiance, the
// green QE and K, over the range above black, clipped at 1.
double InputBrightness(const CoreInput& in, const RunConfig& rc, const std::vector<uint16_t>& weights) {
  const double scale = ExposurePhotonsPerRadiance(rc.core.exposure) * rc.core.sensor.quantum_efficiency[kGreen] *
                       rc.core.sensor.system_gain_dn_per_e * std::pow(10.0, rc.core.sensor.gain_db / 20.0) /
                       ((1 << rc.core.geometry.adc_bits) - 1 - rc.core.sensor.black_level_dn) / 65536.0 / 3.0;
  double weighted = 0, total = 0;
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      const size_t i = static_cast<size_t>(y) * in.width + x;
      const double w = rc.metering == Metering::kImage ? weights[i] : MeteringWeight(rc.metering, x, y, in.width, in.height);
      const double v = (double(in.radiance[0][i]) + in.radiance[1][i] + in.radiance[2][i]) * scale;
      weighted += w * (v < 1.0 ? v : 1.0);
      total += w;
    }
  return total > 0 ? weighted / total : 0.0;
}

// t + f, held at the int64 limits: a frame's sums stay below 2^60, but a
// long run of saturated frames adds up past 2^63.
void AddHeld(int64_t* t, int64_t f) {
  if (__builtin_add_overflow(*t, f, t)) *t = f < 0 ? INT64_MIN : INT64_MAX;
}

void AddStats(const WorkerStats& from, int stages, WorkerStats* to) {
  for (int i = 0; i < stages; ++i) {
    StageStats& t = to->stage[i];
    const StageStats& f = from.stage[i];
    for (int c = 0; c < 3; ++c) {
      AddHeld(&t.sum[c], f.sum[c]);
      AddHeld(&t.count[c], f.count[c]);
      AddHeld(&t.aux_sum[c], f.aux_sum[c]);
    }
    AddHeld(&t.skipped_px, f.skipped_px);
    t.ticks += f.ticks;
  }
}

// The GenICam PFNC name of the .raw file's layout as JSON: samples of adc_bits
// in the low bits of 2-byte words is Mono10/12/14/16 or Bayer**10/12/14/16
// (one channel), RGB10/12/14/16 (three, interleaved); other depths (8 bits in
// 2 bytes, odd depths) have no PFNC name: null.
std::string RawPixelFormat(const RunConfig& rc, int channels) {
  const int bits = rc.core.geometry.adc_bits;
  if (bits != 10 && bits != 12 && bits != 14 && bits != 16) return "null";
  return JsonString((channels == 3 ? std::string("RGB") : CfaName(rc.core.geometry.cfa)) + std::to_string(bits));
}

// The line samples' fixed-point format (all channels of a line share its
// domain's), as the --dump-stages images describe their code channels.
std::vector<io::ExrAttribute> CodeAttributes(const std::string& code_channel, Domain d) {
  const std::string key = "camsim/" + code_channel + "/";
  return {{key + "format", DomainName(d)}, {key + "unit", UnitOf(d)},
          {key + "scale", std::ldexp(1.0, -DomainFracBits(d))}};
}

// Writes one tapped image as an EXR: FLOAT channels R, G, B (Y for one
// channel) in the domain's physical unit, code * 2^-DomainFracBits rounded
// to float (exact up to 2^24 codes). With `stage` (the --dump-stages
// images and a run's own NAME.exr), also the exact line samples as UINT channels code.R, code.G,
// code.B (code.Y), and in the header "camsim/stage" (its name) and per code
// channel "camsim/code.C/format" (DomainName: "photons Q24.8", ...),
// "camsim/code.C/unit" and "camsim/code.C/scale" (double: C = code.C * scale).
bool WriteStageImage(const std::string& path_stem, const LineFormat& f, const std::vector<uint32_t>& data, int w,
                     int h, const char* stage, std::vector<std::string>* written, std::string* error) {
  std::vector<float> planes[3];
  std::vector<uint32_t> codes[3];
  std::vector<io::ExrChannel> channels;
  std::vector<io::ExrAttribute> attributes;
  const char* names[3] = {"R", "G", "B"};
  const double scale = std::ldexp(1.0, -DomainFracBits(f.domain));
  for (int c = 0; c < f.channels; ++c) {
    const std::string name = f.channels == 1 ? "Y" : names[c];
    planes[c].resize(static_cast<size_t>(w) * h);
    for (size_t i = 0; i < planes[c].size(); ++i)
      planes[c][i] = static_cast<float>(data[i * f.channels + c] * scale);
    channels.push_back({name, planes[c].data(), w});
    if (stage == nullptr) continue;
    codes[c].resize(planes[c].size());
    for (size_t i = 0; i < codes[c].size(); ++i) codes[c][i] = data[i * f.channels + c];
    channels.push_back({"code." + name, codes[c].data(), w});
    const std::vector<io::ExrAttribute> a = CodeAttributes("code." + name, f.domain);
    attributes.insert(attributes.end(), a.begin(), a.end());
  }
  if (stage != nullptr) attributes.push_back({"camsim/stage", stage});
  const std::string path = path_stem + ".exr";
  if (!io::WriteExr(path, w, h, channels, attributes, error)) return false;
  written->push_back(path);
  return true;
}

// What a stage's skipped pixels (StageStats::skipped_px) are, as "pixels
// ...", and whether skipping them can be turned off (Stage::set_skip_idle)
// to measure the time saved. Flare's skipped pixels source nothing: there is
// no work to run on them, so nothing to measure.
struct SkipMeaning {
  const char* what;
  bool measurable;
};
SkipMeaning Skipped(StageId id) {
  switch (id) {
    case StageId::kDofRows: return {"linked to no neighbour (CoC below dof.min_coc_px): their weights are 1, taken without a division", true};
    case StageId::kDofColumns: return {"linked to no neighbour (CoC below dof.min_coc_px): copied where their whole column tile is", true};
    case StageId::kDofGather: return {"in rows whose window holds no disc wider than a pixel (CoC < 1.75 px), copied", true};
    case StageId::kMotionBlur: return {"not moving, copied", true};
    case StageId::kFlare: return {"in tiles without a bright pixel, no glare or ghosts from them", false};
    default: return {"not needed", false};
  }
}

// The time running stage r saved per frame by skipping, measured
// (--measure-savings): its fastest round without skipping minus its fastest
// with. Timing noise can make it negative.
bool TimeSavedMs(StageId id, int r, const SavingsMeasured& m, double* ms) {
  if (!Skipped(id).measurable || m.frames == 0) return false;
  *ms = (m.stage_off_ms[r] - m.stage_on_ms[r]) / m.frames;
  return true;
}

// --measure-savings: renders the frame `rounds` more times with skipping on
// (`renderer`, into `taps`) and off (`probe`, into buffers of its own),
// alternating, and adds each one's fastest round, per running stage and
// wall, to *m. Skipping changes no byte (PipelineConfig::skip_idle): the
// probe's outputs are compared with `buffers`, and a difference is an error.
bool MeasureSavings(FrameRenderer& renderer, FrameRenderer& probe, uint32_t frame, const std::vector<Tap>& taps,
                    const std::vector<std::vector<uint8_t>>& buffers, int rounds, SavingsMeasured* m,
                    std::string* error) {
  const int running = renderer.pipeline().plan().running;
  std::vector<std::vector<uint8_t>> probe_buffers(taps.size());
  std::vector<Tap> probe_taps = taps;
  for (size_t i = 0; i < taps.size(); ++i) {
    probe_buffers[i].resize(buffers[i].size());
    probe_taps[i].data = probe_buffers[i].data();
  }
  double stage_best[2][kStageCount], wall_best[2] = {HUGE_VAL, HUGE_VAL};
  int64_t skipped[2][kStageCount] = {};  // the last round's counts: the same with skipping off
  for (int s = 0; s < 2; ++s)
    for (int r = 0; r < running; ++r) stage_best[s][r] = HUGE_VAL;
  for (int round = 0; round < rounds; ++round)
    for (int off = 0; off < 2; ++off) {
      FrameRenderer& fr = off ? probe : renderer;
      std::vector<WorkerStats> stats(static_cast<size_t>(fr.threads()));
      const uint64_t t0 = hal::NowNs();
      fr.Render(frame, off ? probe_taps.data() : taps.data(), static_cast<int>(taps.size()), &stats);
      wall_best[off] = std::min(wall_best[off], (hal::NowNs() - t0) / 1e6);
      for (int r = 0; r < running; ++r) {
        double ms = 0;
        skipped[off][r] = 0;
        for (const WorkerStats& ws : stats) {
          ms += ws.stage[r].ticks / 1e6;
          skipped[off][r] += ws.stage[r].skipped_px;
        }
        stage_best[off][r] = std::min(stage_best[off][r], ms);
      }
    }
  for (size_t i = 0; i < taps.size(); ++i)
    if (probe_buffers[i] != buffers[i]) {
      *error = "--measure-savings: frame " + std::to_string(frame) + " came out different with skipping off (tap " +
               std::to_string(i) + "): a fault in the core, please report it";
      return false;
    }
  const Plan& plan = renderer.pipeline().plan();
  for (int i = 0, r = 0; i < plan.count; ++i) {
    if (!plan.entries[i].runs) continue;
    if (skipped[0][r] != skipped[1][r]) {
      *error = "--measure-savings: frame " + std::to_string(frame) + ": " + StageName(plan.entries[i].id) +
               " counted other pixels with skipping off: a fault in the core, please report it";
      return false;
    }
    ++r;
  }
  for (int r = 0; r < running; ++r) {
    m->stage_on_ms[r] += stage_best[0][r];
    m->stage_off_ms[r] += stage_best[1][r];
  }
  m->wall_on_ms += wall_best[0];
  m->wall_off_ms += wall_best[1];
  m->rounds = rounds;
  ++m->frames;
  return true;
}

std::string ReportJson(const RunOptions& o, const RunConfig& rc, const Pipeline& p, int threads,
                       const Accumulated& acc, const std::string& error) {
  const Plan& plan = p.plan();
  std::ostringstream j;
  j << "{\n  \"camsim_version\": \"" << kReportVersion << "\",\n";
  j << "  \"sensor\": {\"width\": " << p.width() << ", \"height\": " << p.height() << ", \"cfa\": "
    << JsonString(CfaName(rc.core.geometry.cfa)) << ", \"adc_bits\": " << rc.core.geometry.adc_bits << "},\n";
  j << "  \"threads\": " << threads << ", \"strip_rows\": "
    << StripRows(o.strip_rows, p.height(), threads) << ",\n";
  j << "  \"workspace_bytes\": {\"total\": " << p.WorkspaceBytes() << ", \"tables\": " << p.TableBytes()
    << ", \"per_worker\": " << p.WorkerBytes() << "},\n";
  if (p.Runs(StageId::kFlare) && rc.core.flare.environment.texels != nullptr && rc.environment_data) {
    const FlareEnvironmentSummary& e = p.flare_stage().environment_summary();
    const io::InputSanitizeStats& st = rc.environment_data->stats;
    j << "  \"flare_environment\": {\"map\": " << JsonString(rc.environment_map) << ", \"width\": "
      << rc.environment_data->width << ", \"height\": " << rc.environment_data->height
      << ", \"sanitised\": " << SanitisedJson(st) << ", \"bright_texels\": " << e.bright_texels
      << ", \"sources\": " << e.sources << ", \"in_frame_skipped\": " << e.in_frame
      << ", \"haze_only_texels\": " << e.haze_only << "},\n";
  }
  j << "  \"stages\": [\n";
  int running = 0;
  const size_t frames = acc.frames.size() ? acc.frames.size() : 1;
  for (int i = 0; i < plan.count; ++i) {
    const PlanEntry& e = plan.entries[i];
    j << "    {\"name\": " << JsonString(StageName(e.id)) << ", \"runs\": " << (e.runs ? "true" : "false");
    if (!e.runs) {
      j << ", \"left_out_because\": " << JsonString(e.reason) << "}";
    } else {
      const StageStats& s = acc.stats.stage[running++];
      const double unit = std::ldexp(1.0, -DomainFracBits(e.out.domain));
      j << ", \"output\": " << JsonString(DomainName(e.out.domain)) << ", \"channels\": " << int(e.out.channels)
        << ", \"mosaic\": " << (e.out.mosaic ? "true" : "false") << ", \"time_ms_per_frame\": "
        << Num(s.ticks / 1e6 / frames) << ", \"unit\": " << JsonString(UnitOf(e.out.domain)) << ", \"mean\": {";
      const char* cn[3] = {"R", "G", "B"};
      bool first = true;
      for (int c = 0; c < 3; ++c) {
        if (s.count[c] == 0) continue;
        j << (first ? "" : ", ") << "\"" << cn[c] << "\": " << Num(s.sum[c] * unit / s.count[c]);
        first = false;
      }
      j << "}";
      if (s.skipped_px > 0) {
        const double frame_px = static_cast<double>(p.width()) * p.height();
        double saved = 0;
        j << ", \"skipped_fraction\": " << Num(s.skipped_px / (frame_px * frames))
          << ", \"skipped_pixels_are\": " << JsonString(Skipped(e.id).what) << ", \"time_saved_ms_per_frame\": "
          << (TimeSavedMs(e.id, running - 1, acc.savings, &saved) ? Num(saved) : std::string("null"));
      }
      if (e.note[0] != '\0') j << ", \"moved_because\": " << JsonString(e.note);
      if (e.id == StageId::kSensor) {
        j << ", \"mean_electrons\": {";
        first = true;
        for (int c = 0; c < 3; ++c) {
          if (s.count[c] == 0) continue;
          j << (first ? "" : ", ") << "\"" << cn[c] << "\": " << Num(s.aux_sum[c] / 256.0 / s.count[c]);
          first = false;
        }
        j << "}";
      }
      j << "}";
    }
    j << (i + 1 < plan.count ? ",\n" : "\n");
  }
  j << "  ],\n";
  const SavingsMeasured& m = acc.savings;
  if (m.frames > 0)
    j << "  \"savings_measured\": {\"rounds\": " << m.rounds << ", \"frames\": " << m.frames
      << ", \"wall_ms_per_frame_skipping\": " << Num(m.wall_on_ms / m.frames)
      << ", \"wall_ms_per_frame_not_skipping\": " << Num(m.wall_off_ms / m.frames) << "},\n";
  j << "  \"frames\": [\n";
  for (size_t i = 0; i < acc.frames.size(); ++i) {
    const FrameRecord& f = acc.frames[i];
    j << "    {\"input\": " << JsonString(f.input) << ", \"wall_ms\": " << Num(f.wall_ms)
      << ", \"sanitised\": " << SanitisedJson(f.radiance_stats) << ", \"layout\": " << JsonString(f.layout)
      << ", \"depth\": " << (f.has_depth ? (f.depth_used ? "\"present, used\"" : "\"present, unused\"") : "null");
    if (f.has_depth) j << ", \"depth_sanitised\": " << SanitisedJson(f.depth_stats);
    j << ", \"motion\": " << (f.has_motion ? (f.motion_used ? "\"present, used\"" : "\"present, unused\"") : "null")
      << ", \"outputs\": [";
    for (size_t k = 0; k < f.outputs.size(); ++k) j << (k ? ", " : "") << JsonString(f.outputs[k]);
    j << "]";
    if (f.has_ae)
      j << ", \"auto_exposure\": {\"exposure_time_us\": " << Num(f.ae_settings.exposure_time_us)
        << ", \"gain_db\": " << Num(f.ae_settings.gain_db) << ", \"f_number\": " << Num(f.ae_settings.f_number)
        << ", \"brightness\": " << Num(f.ae_brightness) << ", \"error_ev\": " << Num(f.ae_error_ev) << "}";
    j << "}" << (i + 1 < acc.frames.size() ? ",\n" : "\n");
  }
  j << "  ],\n  \"error\": " << (error.empty() ? "null" : JsonString(error)) << "\n}\n";
  return j.str();
}

void PrintPlan(const Pipeline& p, const Accumulated& acc) {
  const Plan& plan = p.plan();
  const size_t frames = acc.frames.size() ? acc.frames.size() : 1;
  std::fprintf(stderr, "plan (%dx%d, workspace %zu bytes: tables %zu + %zu per worker):\n", p.width(), p.height(),
               p.WorkspaceBytes(), p.TableBytes(), p.WorkerBytes());
  int running = 0;
  for (int i = 0; i < plan.count; ++i) {
    const PlanEntry& e = plan.entries[i];
    if (!e.runs) {
      std::fprintf(stderr, "  %-14s left out: %s\n", StageName(e.id), e.reason);
      continue;
    }
    const StageStats& s = acc.stats.stage[running++];
    const double unit = std::ldexp(1.0, -DomainFracBits(e.out.domain));
    std::fprintf(stderr, "  %-14s -> %-16s %8.2f ms/frame  mean", StageName(e.id), DomainName(e.out.domain),
                 s.ticks / 1e6 / frames);
    const char* cn[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c)
      if (s.count[c]) std::fprintf(stderr, " %s=%.4g", cn[c], s.sum[c] * unit / s.count[c]);
    if (s.skipped_px > 0) {
      const double frame_px = static_cast<double>(p.width()) * p.height();
      double saved = 0;
      std::fprintf(stderr, "  skipped %.1f %% of pixels: %s",
                   100.0 * static_cast<double>(s.skipped_px) / (frame_px * frames), Skipped(e.id).what);
      if (TimeSavedMs(e.id, running - 1, acc.savings, &saved))
        std::fprintf(stderr, ", saved %.2f ms/frame (measured)", saved);
    }
    if (e.id == StageId::kSensor) {
      std::fprintf(stderr, "  electrons");
      for (int c = 0; c < 3; ++c)
        if (s.count[c]) std::fprintf(stderr, " %s=%.4g", cn[c], s.aux_sum[c] / 256.0 / s.count[c]);
    }
    if (e.id == StageId::kFlare && p.config().flare.environment.texels != nullptr) {
      const FlareEnvironmentSummary& env = p.flare_stage().environment_summary();
      std::fprintf(stderr, "  environment map: %d source(s), %lld bright texel(s): %lld in frame (skipped), %lld haze only",
                   env.sources, static_cast<long long>(env.bright_texels), static_cast<long long>(env.in_frame),
                   static_cast<long long>(env.haze_only));
    }
    std::fprintf(stderr, "\n");
    if (e.note[0] != '\0') std::fprintf(stderr, "  %-14s moved: %s\n", "", e.note);
  }
  const SavingsMeasured& m = acc.savings;
  if (m.frames > 0)
    std::fprintf(stderr, "savings measured (fastest of %d rounds a frame): %.2f ms/frame wall skipping, %.2f not\n",
                 m.rounds, m.wall_on_ms / m.frames, m.wall_off_ms / m.frames);
}

bool SplitStages(const std::string& list, RunConfig* rc, std::string* error) {
  std::vector<std::string> names;
  std::stringstream ss(list);
  std::string name;
  while (std::getline(ss, name, ',')) {
    // "exposure, sensor": spaces around a name are not part of it.
    const size_t a = name.find_first_not_of(" \t"), b = name.find_last_not_of(" \t");
    if (a != std::string::npos) names.push_back(name.substr(a, b - a + 1));
  }
  // --stages keeps the configured order and runs only the named stages.
  for (size_t i = 0; i < names.size(); ++i) {
    StageId id;
    if (!StageFromName(names[i].c_str(), &id)) {
      *error = "--stages: unknown stage '" + names[i] + "'";
      return false;
    }
    // A repeat would be kept once per listing: more entries than kept[] holds.
    if (std::find(names.begin(), names.begin() + i, names[i]) != names.begin() + i) {
      *error = "--stages: stage '" + names[i] + "' is named more than once";
      return false;
    }
  }
  PipelineConfig& p = rc->core;
  for (const std::string& n : names) {
    bool configured = false;
    for (int i = 0; i < p.order_count; ++i) configured = configured || n == StageName(p.order[i]);
    if (!configured) {
      *error = "--stages: stage '" + n + "' is not in [pipeline] stages, so it cannot run";
      return false;
    }
  }
  StageId kept[kStageCount];
  int count = 0;
  for (int i = 0; i < p.order_count; ++i)
    for (const std::string& n : names)
      if (n == StageName(p.order[i])) kept[count++] = p.order[i];
  for (int i = 0; i < count; ++i) p.order[i] = kept[i];
  p.order_count = count;
  return true;
}

// Whether a failed run may write its report at `path`: only where that
// cannot lose a file, i.e. when nothing is there, or an earlier camsim report
// is (which would otherwise pass for this run's). Anything else there (a
// frame of an earlier run, say) is left alone, with a note on stderr.
bool ReportReplaceable(const std::string& path) {
  if (path == "-") return true;  // standard output
  // A symbolic link is followed (the writer replaces its target); a FIFO,
  // device, socket or directory is never opened nor replaced.
  std::string target, why;
  if (!io::WritableTarget(path, &target, &why)) {
    std::fprintf(stderr, "camsim: --report: %s: left as it is\n", why.c_str());
    return false;
  }
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(target, ec);
  bool ours = !std::filesystem::exists(st);
  if (std::filesystem::is_regular_file(st)) {
    const std::string head = std::string("{\n  \"camsim_version\": \"");
    std::ifstream in(target, std::ios::binary);
    std::string start(head.size(), '\0');
    ours = in.read(start.data(), static_cast<std::streamsize>(start.size())) && start == head;
  }
  if (!ours) std::fprintf(stderr, "camsim: --report '%s' is not a camsim report: left as it is\n", path.c_str());
  return ours;
}

// A failure before the run knows its inputs (so before --report is claimed):
// the error goes to the report where ReportReplaceable allows.
int FailBeforeClaim(const RunOptions& o, const std::string& message) {
  std::fprintf(stderr, "camsim: %s\n", message.c_str());
  if (o.report_path.empty() || !ReportReplaceable(o.report_path)) return 1;
  std::string werr;
  if (!WriteReport(o.report_path, ErrorReportJson(message), &werr)) std::fprintf(stderr, "camsim: %s\n", werr.c_str());
  return 1;
}

}  // namespace

int RunCommand(const RunOptions& o) {
  RunConfig rc;
  Origins origins;
  std::string error;
  if (!o.option_error.empty()) return FailBeforeClaim(o, o.option_error);
  if (!o.preset.empty() && !ApplyPreset(o.preset, &rc, &origins, &error)) return FailBeforeClaim(o, error);
  if (!o.config_path.empty() && !LoadConfigFile(o.config_path, &rc, &origins, &error))
    return FailBeforeClaim(o, error);
  for (const std::string& s : o.overrides)
    if (!ApplyOverride(s, &rc, &origins, &error)) return FailBeforeClaim(o, error);
  if (!o.calibration_path.empty()) {  // (camsim_main refuses a path with ' or a newline)
    if (!ApplyOverride("distortion.calibration='" + o.calibration_path + "'", &rc, &origins, &error))
      return FailBeforeClaim(o, error);
    origins["distortion.calibration"] = "--calibration '" + o.calibration_path + "'";
  }
  if (o.stages_given && !SplitStages(o.stages, &rc, &error)) return FailBeforeClaim(o, error);
  if (o.stages_given) origins["pipeline.stages"] = "--stages";
  if (o.threads < 1 || o.threads > 64 || o.strip_rows < 0)
    return FailBeforeClaim(o, "--threads must be 1..64 and --strip-rows >= 1");
  // Every file the run reads (scenes, depth, the configuration and the files
  // it names) by resolved path, and the paths outputs claim: no output may
  // overwrite an input or another output of this run.
  std::map<std::string, std::string> inputs, claimed;
  if (!o.depth_path.empty()) inputs.emplace(Resolved(o.depth_path, true), "'" + o.depth_path + "' (--depth)");
  if (!o.config_path.empty()) inputs.emplace(Resolved(o.config_path, true), "'" + o.config_path + "' (--config)");
  for (const auto& [key, path] : ConfigInputFiles(rc))
    inputs.emplace(Resolved(path, true), "'" + path + "' (" + key + ")");
  std::vector<std::string> files;
  const bool expanded = io::ExpandInputs(o.inputs, &files, &error);
  for (const std::string& in : expanded ? files : o.inputs) inputs.emplace(Resolved(in, true), "'" + in + "'");
  std::string claim_error;
  if (!o.report_path.empty() && o.report_path != "-" &&
      !ClaimOutputs({o.report_path}, "--report", inputs, &claimed, &claim_error)) {
    std::fprintf(stderr, "camsim: %s\n", claim_error.c_str());
    return 1;
  }
  // From here on a failure is also written to the report (when one is asked
  // for), so that an older report at that path cannot pass for this run's.
  const auto fail = [&o](int code, const std::string& message) {
    std::fprintf(stderr, "camsim: %s\n", message.c_str());
    std::string werr;
    if (!o.report_path.empty() && !WriteReport(o.report_path, ErrorReportJson(message), &werr))
      std::fprintf(stderr, "camsim: %s\n", werr.c_str());
    return code;
  };
  if (!expanded) return fail(1, error);
  // Where a sequence starts and ends (a pattern starts at its lowest index present).
  if (!o.quiet && files.size() > 1)
    std::fprintf(stderr, "inputs: %zu frames, %s .. %s\n", files.size(), files.front().c_str(), files.back().c_str());
  if (!o.depth_path.empty() && files.size() > 1)
    return fail(1, "--depth " + o.depth_path + ": the inputs are " + std::to_string(files.size()) +
                       " frames, and one depth file cannot describe a sequence (give each frame its depth channel "
                       "in its own EXR)");
  if (o.out_dir.empty()) return fail(1, "--out DIR is required");
  const int made = mkdir(o.out_dir.c_str(), 0755);
  const int mkdir_errno = errno;
  struct stat st;
  if (stat(o.out_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    const char* why = made == 0 || mkdir_errno == EEXIST ? "a file of that name is in the way" : std::strerror(mkdir_errno);
    return fail(2, "cannot create output directory '" + o.out_dir + "': " + why);
  }
  // A report that could not be written would fail only after every frame
  // (checked once --out exists: the report may go inside it). Through a
  // symbolic link, the target's directory is what must exist.
  if (!o.report_path.empty() && o.report_path != "-") {
    std::error_code ec;
    std::string target, why_not;
    if (!std::filesystem::is_directory(o.report_path, ec) && !io::WritableTarget(o.report_path, &target, &why_not)) {
      std::fprintf(stderr, "camsim: --report: %s\n", why_not.c_str());
      return 2;
    }
    const std::filesystem::path report(target.empty() ? o.report_path : target);
    const std::filesystem::path parent = report.has_parent_path() ? report.parent_path() : ".";
    const char* why = std::filesystem::is_directory(report, ec)          ? "is a directory"
                      : !std::filesystem::is_directory(parent, ec) ? "its directory does not exist"
                                                                   : nullptr;
    if (why != nullptr) {
      std::fprintf(stderr, "camsim: --report '%s': %s\n", o.report_path.c_str(), why);
      return 2;
    }
  }

  FrameRenderer renderer(o.threads, o.strip_rows);
  // --measure-savings: the same frames, skipping off.
  std::unique_ptr<FrameRenderer> probe =
      o.savings_rounds > 0 ? std::make_unique<FrameRenderer>(o.threads, o.strip_rows) : nullptr;
  const RunConfig user_config = rc;  // rc becomes the finished configuration
  Accumulated acc;
  const bool tty = isatty(2) && !o.quiet && files.size() > 1;
  int exit_code = 0;
  int first_w = 0, first_h = 0;
  // Auto exposure: the controller's state is carried from frame to frame; a
  // new setting re-configures the pipeline before the next frame.
  AutoExposure ae;
  const bool ae_on = rc.auto_exposure.mode != AutoExposureMode::kOff;
  bool ae_changed = false;
  std::vector<uint16_t> metering_weights;

  for (size_t f = 0; f < files.size(); ++f) {
    const bool reconfigures = f == 0 || (ae_on && ae_changed);  // the renderer's configuration changes
    io::SceneFrame scene;
    if (!io::LoadSceneExr(files[f], o.depth_path, &scene, &error)) {
      error = "frame " + std::to_string(o.first_frame + f) + ": " + error;
      exit_code = 1;
      break;
    }
    for (const std::string& w : scene.warnings)  // below the progress bar, if one is drawn
      std::fprintf(stderr, "%scamsim: warning: %s\n", tty && f > 0 ? "\n" : "", w.c_str());
    if (f == 0) {
      if (!renderer.Configure(user_config, origins, scene.width, scene.height, &rc, &error)) {
        exit_code = 1;
        break;
      }
      if (ae_on) {
        const Status a = ae.Configure(rc.auto_exposure, {rc.core.exposure.exposure_time_us, rc.core.sensor.gain_db,
                                                         rc.core.exposure.f_number});
        if (!a.ok()) {
          error = DescribeStatus(a, origins);
          exit_code = 1;
          break;
        }
        if (!ApplyExposure(ae.settings(), &rc)) {
          error = "auto_exposure: initial settings out of range";
          exit_code = 1;
          break;
        }
        if (rc.metering == Metering::kImage) {
          io::FloatPlane wmap;
          // Weights above 1 count as 1 (MeteringWeights); NaN and negatives are refused.
          if (!ReadWeightImage(KeyWhere(origins, "auto_exposure.metering_image"), rc.metering_image, HUGE_VAL, &wmap, &error)) {
            exit_code = 1;
            break;
          }
          if (!MeteringWeights(wmap, rc.core.geometry.width, rc.core.geometry.height, &metering_weights, &error)) {
            exit_code = 1;
            break;
          }
        }
        if (!renderer.Configure(rc, origins, scene.width, scene.height, &rc, &error)) {
          exit_code = 1;
          break;
        }
      }
      // The flare environment map's replaced texels, once (it is loaded once).
      if (rc.environment_data)
        for (const std::string& w : rc.environment_data->warnings)
          std::fprintf(stderr, "camsim: warning: flare.environment_map %s\n", w.c_str());
      first_w = scene.width;
      first_h = scene.height;
    } else if (scene.width != first_w || scene.height != first_h) {
      error = files[f] + ": is " + std::to_string(scene.width) + "x" + std::to_string(scene.height) +
              " but the sequence started at " + std::to_string(first_w) + "x" + std::to_string(first_h);
      exit_code = 1;
      break;
    }
    if (f > 0 && ae_on && ae_changed &&
        !renderer.Configure(rc, origins, scene.width, scene.height, &rc, &error)) {
      // The controller changed the exposure: the stages take the new settings.
      error = "auto_exposure: " + error;
      exit_code = 1;
      break;
    }
    if (!renderer.SetScene(scene, &error)) {
      exit_code = 1;
      break;
    }
    const Pipeline& pipeline = renderer.pipeline();

    // Taps: the raw sensor output (when the sensor runs before the end), the
    // final output, and with --dump-stages every running stage.
    const Plan& plan = pipeline.plan();
    const int w = pipeline.width(), h = pipeline.height();
    std::vector<Tap> taps;
    std::vector<std::vector<uint8_t>> buffers;
    // Formats of the running stages, in run order.
    std::vector<LineFormat> formats;
    int sensor_index = -1;
    for (int i = 0; i < plan.count; ++i)
      if (plan.entries[i].runs) {
        if (plan.entries[i].id == StageId::kSensor) sensor_index = static_cast<int>(formats.size());
        formats.push_back(plan.entries[i].out);
      }
    const LineFormat out_fmt = plan.output;
    auto add_tap = [&](int stage, TapFormat fmt) {
      const int channels = formats[static_cast<size_t>(stage)].channels;
      const size_t bytes = fmt == TapFormat::kU8 ? 1 : (fmt == TapFormat::kU16 ? 2 : 4);
      buffers.emplace_back(static_cast<size_t>(w) * h * channels * bytes);
      Tap t;
      t.stage = stage;
      t.format = fmt;
      t.data = buffers.back().data();
      t.stride = static_cast<ptrdiff_t>(w) * channels;
      taps.push_back(t);
    };
    const bool final_is_image = out_fmt.domain == Domain::kLinear || out_fmt.domain == Domain::kEncoded;
    const bool final_is_raw = out_fmt.domain == Domain::kDigital;
    buffers.reserve(2 + formats.size());  // taps point into these buffers
    add_tap(plan.running - 1, final_is_image ? (rc.output_bits == 8 ? TapFormat::kU8 : TapFormat::kU16)
                                             : (final_is_raw ? TapFormat::kU16 : TapFormat::kU32));
    const bool raw_tap = sensor_index >= 0 && sensor_index != plan.running - 1;
    if (raw_tap) add_tap(sensor_index, TapFormat::kU16);
    const size_t first_dump = taps.size();
    if (o.dump_stages)
      for (int i = 0; i < plan.running; ++i) add_tap(i, TapFormat::kU32);

    // Before the first frame writes anything, every frame's files under this
    // plan; later frames again, in case auto exposure changed the plan.
    const auto frame_name = [&](size_t g) {
      return "frame " + std::to_string(o.first_frame + g) + " (" + files[g] + ")";
    };
    bool claims_ok = true;
    int claim_code = 1;
    const size_t claim_end = f == 0 ? files.size() : f + 1;
    for (size_t g = f; g < claim_end && claims_ok; ++g) {
      const std::vector<std::string> outputs = FrameOutputs(o.out_dir + "/" + Stem(files[g]), plan, o.dump_stages);
      claims_ok = ClaimOutputs(outputs, frame_name(g), inputs, &claimed, &error);
      // A FIFO, device, socket or directory in an output's place is refused
      // now, before any frame is rendered, not when its frame is written.
      std::string target, why;
      for (size_t k = 0; k < outputs.size() && claims_ok; ++k)
        if (!io::WritableTarget(outputs[k], &target, &why)) {
          error = frame_name(g) + ": " + why;
          claims_ok = false;
          claim_code = 2;
        }
    }
    if (!claims_ok) {
      exit_code = claim_code;
      break;
    }

    std::vector<WorkerStats> worker_stats(static_cast<size_t>(o.threads));
    const uint32_t frame_index = o.first_frame + static_cast<uint32_t>(f);
    const uint64_t t0 = hal::NowNs();
    renderer.Render(frame_index, taps.data(), static_cast<int>(taps.size()), &worker_stats);
    FrameRecord rec;
    rec.wall_ms = (hal::NowNs() - t0) / 1e6;
    rec.input = scene.source;
    rec.radiance_stats = scene.radiance_stats;
    rec.depth_stats = scene.depth_stats;
    rec.layout = scene.layout;
    rec.has_depth = scene.has_depth;
    rec.has_motion = scene.has_motion;
    for (int i = 0; i < plan.count; ++i) {
      const PlanEntry& e = plan.entries[i];
      if (!e.runs) continue;
      const DofConfig& d = rc.core.dof;
      if (e.id == StageId::kDofGather ||
          (e.id == StageId::kDofRows && d.method == DofMethod::kDiffusion && !d.structural_only))
        rec.depth_used = true;
      const MotionBlurConfig& m = rc.core.motion_blur;
      const bool translating = m.linear_velocity_m_s[0] != 0.0 || m.linear_velocity_m_s[1] != 0.0 ||
                               m.linear_velocity_m_s[2] != 0.0;
      if (e.id == StageId::kMotionBlur && m.source == MotionSource::kCamera && translating) rec.depth_used = true;
      if (e.id == StageId::kMotionBlur && m.source == MotionSource::kVectors) rec.motion_used = true;
    }
    if (probe) {
      RunConfig off = rc;
      off.core.skip_idle = false;
      if ((reconfigures && !probe->Configure(off, origins, scene.width, scene.height, nullptr, &error)) ||
          !probe->SetScene(scene, &error) ||
          !MeasureSavings(renderer, *probe, frame_index, taps, buffers, o.savings_rounds, &acc.savings, &error)) {
        exit_code = 1;
        break;
      }
    }
    for (const WorkerStats& ws : worker_stats) AddStats(ws, plan.running, &acc.stats);
    if (ae_on) {
      // Measure this frame, set the next one's exposure.
      const int max_dn_ae = (1 << rc.core.geometry.adc_bits) - 1;
      const int black_ae = static_cast<int>(rc.core.sensor.black_level_dn);
      double y = 0;
      const uint16_t* raw = raw_tap ? reinterpret_cast<const uint16_t*>(buffers[1].data())
                                    : (final_is_raw ? reinterpret_cast<const uint16_t*>(buffers[0].data()) : nullptr);
      const int raw_channels = sensor_index >= 0 ? formats[static_cast<size_t>(sensor_index)].channels : 1;
      if (rc.meter_input || sensor_index < 0) {
        y = InputBrightness(renderer.input(), rc, metering_weights);
      } else if (rc.metering == Metering::kUniform) {
        // Free: the sensor stage's sums, gathered while its rows were hot.
        int64_t sum = 0, count = 0;
        for (const WorkerStats& ws : worker_stats)
          for (int c = 0; c < 3; ++c) {
            sum += ws.stage[sensor_index].sum[c];
            count += ws.stage[sensor_index].count[c];
          }
        y = count > 0 ? (static_cast<double>(sum) / count - black_ae) / (max_dn_ae - black_ae) : 0.0;
      } else {
        y = WeightedBrightness(raw, w, h, static_cast<ptrdiff_t>(w) * raw_channels, raw_channels, black_ae, max_dn_ae,
                               rc.metering, metering_weights.empty() ? nullptr : metering_weights.data());
      }
      const ExposureSettings before = ae.settings();
      const ExposureSettings next = ae.Update(y);
      ae_changed = next.exposure_time_us != before.exposure_time_us || next.gain_db != before.gain_db ||
                   next.f_number != before.f_number;
      rec.ae_brightness = y;
      rec.ae_error_ev = ae.last_error_ev();
      rec.ae_settings = before;
      rec.has_ae = true;
      if (!o.quiet)
        std::fprintf(stderr, "auto exposure: frame %u at %.1f us, %.2f dB, f/%.2f: brightness %.4f (error_ev %+.2f) -> %.1f us, %.2f dB, f/%.2f\n",
                     frame_index, before.exposure_time_us, before.gain_db, before.f_number, y, ae.last_error_ev(),
                     next.exposure_time_us, next.gain_db, next.f_number);
      ApplyExposure(next, &rc);
    }

    // Files: <stem>.png (ISP), <stem>.raw.pgm or .raw.ppm + .raw + .raw.json
    // (sensor), <stem>.exr (linear domains), <stem>.<i>_<stage>.exr (--dump-stages).
    const std::string stem = o.out_dir + "/" + Stem(files[f]);
    bool ok = true;
    const int max_dn = (1 << rc.core.geometry.adc_bits) - 1;
    // One channel is a mosaic or mono frame; three are one sensor per colour
    // (no CFA stage), written interleaved as RGB.
    auto write_raw = [&](const std::vector<uint8_t>& buf, int channels) {
      if (channels != 1 && channels != 3) {
        error = stem + ".raw: the sensor output has " + std::to_string(channels) +
                " channels; only 1 (mono or mosaic) or 3 (RGB) can be written";
        ok = false;
        return;
      }
      const uint16_t* px = reinterpret_cast<const uint16_t*>(buf.data());
      const ptrdiff_t stride = static_cast<ptrdiff_t>(w) * channels;
      const std::vector<std::string> names = RawOutputs(stem, channels);
      std::ostringstream side;
      const int bits = rc.core.geometry.adc_bits;
      side << "{\"width\": " << w << ", \"height\": " << h << ", \"channels\": " << channels
           << (channels == 3 ? ", \"channel_order\": \"RGB\"" : "")
           << ", \"pixel_format\": " << RawPixelFormat(rc, channels)
           << ", \"cfa\": " << (channels == 3 ? "null" : JsonString(CfaName(rc.core.geometry.cfa)))
           << ", \"adc_bits\": " << bits << ", \"bytes_per_pixel\": " << 2 * channels
           << ", \"significant_bits\": " << bits
           << ", \"alignment\": \"lsb\", \"byte_order\": \"little\", \"black_level_dn\": "
           << Num(rc.core.sensor.black_level_dn) << ", \"frame\": " << frame_index << ", \"seed\": " << rc.core.seed
           << ", \"source\": " << JsonString(scene.source) << "}\n";
      ok = ok && io::WritePnm16(names[0], px, w, h, channels, stride, max_dn, &error) &&
           io::WriteRaw16(names[1], px, w, h, channels, stride, &error) &&
           io::WriteTextFile(names[2], side.str(), &error);
      if (ok) rec.outputs.insert(rec.outputs.end(), names.begin(), names.end());
    };
    if (final_is_image) {
      ok = io::WritePng(stem + ".png", buffers[0].data(), w, h, out_fmt.channels, rc.output_bits, w * out_fmt.channels,
                        &error);
      if (ok) rec.outputs.push_back(stem + ".png");
    } else if (final_is_raw) {
      write_raw(buffers[0], out_fmt.channels);
    } else {
      std::vector<uint32_t> data(reinterpret_cast<const uint32_t*>(buffers[0].data()),
                                 reinterpret_cast<const uint32_t*>(buffers[0].data()) + buffers[0].size() / 4);
      // The last running stage's output, described as a --dump-stages image.
      const char* last = nullptr;
      for (int i = 0; i < plan.count; ++i)
        if (plan.entries[i].runs) last = StageName(plan.entries[i].id);
      ok = WriteStageImage(stem, out_fmt, data, w, h, last, &rec.outputs, &error);
    }
    if (ok && raw_tap) write_raw(buffers[1], formats[static_cast<size_t>(sensor_index)].channels);
    if (ok && o.dump_stages) {
      int r = 0;
      for (int i = 0; i < plan.count && ok; ++i) {
        if (!plan.entries[i].runs) continue;
        const std::vector<uint8_t>& b = buffers[first_dump + static_cast<size_t>(r)];
        std::vector<uint32_t> data(reinterpret_cast<const uint32_t*>(b.data()),
                                   reinterpret_cast<const uint32_t*>(b.data()) + b.size() / 4);
        ok = WriteStageImage(stem + DumpSuffix(r, plan.entries[i].id), plan.entries[i].out, data, w, h,
                             StageName(plan.entries[i].id), &rec.outputs, &error);
        ++r;
      }
    }
    acc.frames.push_back(rec);
    if (!ok) {
      exit_code = 2;
      break;
    }
    if (tty) {
      const int done = static_cast<int>(f + 1), total = static_cast<int>(files.size());
      const int bar = 30 * done / total;
      std::fprintf(stderr, "\r[%.*s%*s] %d/%d frames", bar, "##############################", 30 - bar, "", done,
                   total);
      if (done == total) std::fprintf(stderr, "\n");
    }
  }

  if (exit_code != 0) std::fprintf(stderr, "camsim: %s\n", error.c_str());
  if (!acc.frames.empty() || exit_code == 0) {
    if (!o.quiet) PrintPlan(renderer.pipeline(), acc);
    if (!o.quiet && !acc.frames.empty()) {
      double total = 0;
      for (const FrameRecord& r : acc.frames) total += r.wall_ms;
      const FrameRecord& first = acc.frames.front();
      const bool depth_idle = first.has_depth && !first.depth_used, motion_idle = first.has_motion && !first.motion_used;
      if (depth_idle || motion_idle)
        std::fprintf(stderr, "input %s: %s%spresent but unused (no configured stage needs it)\n", first.layout.c_str(),
                     depth_idle ? "depth " : "", motion_idle ? "motion " : "");
      std::fprintf(stderr, "%zu frame(s), %.2f ms/frame wall on %d thread(s); outputs in %s\n", acc.frames.size(),
                   total / acc.frames.size(), o.threads, o.out_dir.c_str());
    }
  }
  // A failed run writes its report only where ReportReplaceable allows: a
  // clash of --report with a frame's output must not replace that frame.
  if (!o.report_path.empty() && (exit_code == 0 || ReportReplaceable(o.report_path))) {
    // A run that failed before it had a pipeline still writes its error.
    const std::string report = renderer.pipeline().plan().count > 0
                                   ? ReportJson(o, rc, renderer.pipeline(), o.threads, acc, error)
                                   : ErrorReportJson(error);
    std::string werr;
    if (!WriteReport(o.report_path, report, &werr)) {
      std::fprintf(stderr, "camsim: %s\n", werr.c_str());
      if (exit_code == 0) exit_code = 2;
    }
  }
  return exit_code;
}

}  // namespace camsim::host
