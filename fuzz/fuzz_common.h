// Shared by the fuzz targets and the seed generator: the compact binary
// description of a core configuration that fuzz_core reads, and a checked run
// of a configured pipeline (strip-height and worker invariance, output ranges).
//
// Blob layout (every read past the end gives 0, so any byte string decodes;
// 0 bytes mostly mean "the default", so short blobs give valid configurations):
//   byte  width  = 1 + b % 64           byte  height = 1 + b % 64
//   byte  cfa    = b % 6  (5 is not a Cfa: the core must refuse it or cope)
//   byte  adc_bits = 12 for 0, else 6 + b % 13  (6..18; the valid range is 8..16)
//   byte  order mode: even -> the default order filtered by a kStageCount-bit
//         mask (2 bytes follow; an empty mask means every stage); odd ->
//         (b >> 1) % (kStageCount + 2) stage ids follow, each byte %
//         (kStageCount + 1) (kStageCount is not a stage); counts 0 and
//         kStageCount + 1 are out of range
//   2 bytes seed
//   enum bytes (vignetting mode % 5, table count % 66, demosaic method % 3,
//   gamma curve % 4, shot noise: b != 1, vignetting mask & 1), then one number
//   per parameter in Params() order (see DecodeNumber), then radiance samples:
//   each sample is 4 little-endian bytes (any uint32, 0xFFFFFFFF included);
//   when the blob runs out, the samples already read repeat (a blob without
//   samples gives a ramp through 0 and 0xFFFFFFFF). The optional Q2.14
//   vignetting mask, the inverse depth plane (any uint32, the invalid marker
//   included) and the motion vectors (any int32) are derived from the radiance.
//   The enum bytes of the later stages (dof method, structural-only, motion
//   source, distortion model, resampling filter (top bit: no ringing clamp),
//   blooming on, flare on)
//   follow the numbers, before the samples.
//
// A number byte b: 0 keeps the default; 1..8 are specials {NaN, +inf, -inf, 0,
// -0, -1, lo, hi}; 9..15 lie just outside or far outside [lo, hi]; 16..254 map
// over [lo, hi] (logarithmically for log-scaled parameters); 255 is followed
// by the 8 bytes of a raw little-endian double (any value, exactly).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <vector>

#include "core/pipeline/pipeline.h"

namespace camsim::fuzz {

#define FUZZ_CHECK(cond, ...)                                        \
  do {                                                               \
    if (!(cond)) {                                                   \
      std::fprintf(stderr, "FUZZ_CHECK failed: %s: ", #cond);        \
      std::fprintf(stderr, __VA_ARGS__);                             \
      std::fprintf(stderr, "\n");                                    \
      std::abort();                                                  \
    }                                                                \
  } while (0)

class ByteReader {
 public:
  ByteReader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  uint8_t Byte() { return pos_ < size_ ? data_[pos_++] : 0; }
  size_t remaining() const { return size_ - pos_; }
  const uint8_t* here() const { return data_ + pos_; }
  double RawDouble() {
    uint8_t b[8];
    for (uint8_t& x : b) x = Byte();
    double v;
    std::memcpy(&v, b, sizeof v);  // little-endian hosts only (x86-64, aarch64)
    return v;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

struct NumberParam {
  const char* name;
  double lo, hi;
  bool log;
  double& (*ref)(PipelineConfig&);
};

#define CAMSIM_FUZZ_PARAM(name, lo, hi, log, expr) \
  NumberParam { name, lo, hi, log, [](PipelineConfig& c) -> double& { return expr; } }

// Every double of PipelineConfig, with its documented valid range.
inline const std::vector<NumberParam>& Params() {
  static const std::vector<NumberParam> params = {
      CAMSIM_FUZZ_PARAM("exposure_time_us", 1.0, 1e8, true, c.exposure.exposure_time_us),
      CAMSIM_FUZZ_PARAM("f_number", 0.5, 128.0, true, c.exposure.f_number),
      CAMSIM_FUZZ_PARAM("photons_per_radiance_ms", 1e-3, 1e9, true, c.exposure.photons_per_radiance_ms),
      CAMSIM_FUZZ_PARAM("focal_length_px", 1.0, 1e6, true, c.vignetting.focal_length_px),
      CAMSIM_FUZZ_PARAM("table0", 0.0, 4.0, false, c.vignetting.table[0]),
      CAMSIM_FUZZ_PARAM("table1", 0.0, 4.0, false, c.vignetting.table[1]),
      CAMSIM_FUZZ_PARAM("table2", 0.0, 4.0, false, c.vignetting.table[2]),
      CAMSIM_FUZZ_PARAM("table_last", 0.0, 4.0, false, c.vignetting.table[VignettingConfig::kMaxTable - 1]),
      CAMSIM_FUZZ_PARAM("mono_weight_r", 0.0, 1.0, false, c.cfa.mono_weights[0]),
      CAMSIM_FUZZ_PARAM("mono_weight_g", 0.0, 1.0, false, c.cfa.mono_weights[1]),
      CAMSIM_FUZZ_PARAM("mono_weight_b", 0.0, 1.0, false, c.cfa.mono_weights[2]),
      CAMSIM_FUZZ_PARAM("qe_r", 0.0, 1.0, false, c.sensor.quantum_efficiency[0]),
      CAMSIM_FUZZ_PARAM("qe_g", 0.0, 1.0, false, c.sensor.quantum_efficiency[1]),
      CAMSIM_FUZZ_PARAM("qe_b", 0.0, 1.0, false, c.sensor.quantum_efficiency[2]),
      CAMSIM_FUZZ_PARAM("full_well_e", 1.0, 1e6, true, c.sensor.full_well_e),
      CAMSIM_FUZZ_PARAM("system_gain_dn_per_e", 1e-3, 1e3, true, c.sensor.system_gain_dn_per_e),
      CAMSIM_FUZZ_PARAM("gain_db", 0.0, 48.0, false, c.sensor.gain_db),
      CAMSIM_FUZZ_PARAM("dark_noise_e", 0.0, 1000.0, false, c.sensor.dark_noise_e),
      CAMSIM_FUZZ_PARAM("dark_current_e_per_s", 0.0, 1e6, false, c.sensor.dark_current_e_per_s),
      CAMSIM_FUZZ_PARAM("temperature_c", -100.0, 150.0, false, c.sensor.temperature_c),
      CAMSIM_FUZZ_PARAM("dark_current_ref_c", -100.0, 150.0, false, c.sensor.dark_current_ref_c),
      CAMSIM_FUZZ_PARAM("dark_current_doubling_c", 1.0, 100.0, false, c.sensor.dark_current_doubling_c),
      CAMSIM_FUZZ_PARAM("dsnu_e", 0.0, 1000.0, false, c.sensor.dsnu_e),
      CAMSIM_FUZZ_PARAM("prnu_percent", 0.0, 50.0, false, c.sensor.prnu_percent),
      CAMSIM_FUZZ_PARAM("dcnu_percent", 0.0, 100.0, false, c.sensor.dcnu_percent),
      CAMSIM_FUZZ_PARAM("sensor_black_level_dn", 0.0, 65534.0, false, c.sensor.black_level_dn),
      CAMSIM_FUZZ_PARAM("isp_black_level_dn", -1.0, 65534.0, false, c.black_level.black_level_dn),
      CAMSIM_FUZZ_PARAM("wb_r", 0.0, 16.0, false, c.white_balance.gain[0]),
      CAMSIM_FUZZ_PARAM("wb_g", 0.0, 16.0, false, c.white_balance.gain[1]),
      CAMSIM_FUZZ_PARAM("wb_b", 0.0, 16.0, false, c.white_balance.gain[2]),
      CAMSIM_FUZZ_PARAM("m0", -16.0, 16.0, false, c.color_matrix.m[0]),
      CAMSIM_FUZZ_PARAM("m1", -16.0, 16.0, false, c.color_matrix.m[1]),
      CAMSIM_FUZZ_PARAM("m2", -16.0, 16.0, false, c.color_matrix.m[2]),
      CAMSIM_FUZZ_PARAM("m3", -16.0, 16.0, false, c.color_matrix.m[3]),
      CAMSIM_FUZZ_PARAM("m4", -16.0, 16.0, false, c.color_matrix.m[4]),
      CAMSIM_FUZZ_PARAM("m5", -16.0, 16.0, false, c.color_matrix.m[5]),
      CAMSIM_FUZZ_PARAM("m6", -16.0, 16.0, false, c.color_matrix.m[6]),
      CAMSIM_FUZZ_PARAM("m7", -16.0, 16.0, false, c.color_matrix.m[7]),
      CAMSIM_FUZZ_PARAM("m8", -16.0, 16.0, false, c.color_matrix.m[8]),
      CAMSIM_FUZZ_PARAM("gamma", 0.1, 10.0, true, c.gamma.gamma),
      CAMSIM_FUZZ_PARAM("dof_focus_distance_m", 0.01, 1e6, true, c.dof.focus_distance_m),
      CAMSIM_FUZZ_PARAM("dof_max_coc_px", 0.25, 1023.0, true, c.dof.max_coc_px),
      CAMSIM_FUZZ_PARAM("dof_pixel_pitch_um", 0.1, 1000.0, true, c.dof.pixel_pitch_um),
      CAMSIM_FUZZ_PARAM("dof_structural_poly0", 0.0, 1023.0, false, c.dof.structural_poly[0]),
      CAMSIM_FUZZ_PARAM("motion_wx", -100.0, 100.0, false, c.motion_blur.angular_velocity_rad_s[0]),
      CAMSIM_FUZZ_PARAM("motion_wy", -100.0, 100.0, false, c.motion_blur.angular_velocity_rad_s[1]),
      CAMSIM_FUZZ_PARAM("motion_vz", -100.0, 100.0, false, c.motion_blur.linear_velocity_m_s[2]),
      CAMSIM_FUZZ_PARAM("motion_fx_px", 1.0, 1e5, true, c.motion_blur.fx_px),
      CAMSIM_FUZZ_PARAM("motion_line_time_us", 0.0, 1e4, false, c.motion_blur.line_time_us),
      CAMSIM_FUZZ_PARAM("lens_fx", 1.0, 1e5, true, c.distortion.lens.fx),
      CAMSIM_FUZZ_PARAM("lens_k1", -2.0, 2.0, false, c.distortion.lens.k[0]),
      CAMSIM_FUZZ_PARAM("lens_k2", -2.0, 2.0, false, c.distortion.lens.k[1]),
      CAMSIM_FUZZ_PARAM("lens_p1", -0.1, 0.1, false, c.distortion.lens.p1),
      CAMSIM_FUZZ_PARAM("chromatic_r", 0.9, 1.1, false, c.distortion.chromatic_scale[0]),
      CAMSIM_FUZZ_PARAM("smear_row_transfer_us", 0.0, 1000.0, false, c.sensor.smear_row_transfer_us),
      CAMSIM_FUZZ_PARAM("smear_leak", 0.0, 1.0, false, c.sensor.smear_leak),
      CAMSIM_FUZZ_PARAM("flare_threshold", 0.01, 60000.0, true, c.flare.threshold),
      CAMSIM_FUZZ_PARAM("flare_haze", 0.0, 1.0, false, c.flare.haze),
  };
  return params;
}

inline double DecodeNumber(ByteReader& r, const NumberParam& p, double current) {
  const uint8_t b = r.Byte();
  const double span = p.hi - p.lo;
  switch (b) {
    case 0: return current;
    case 1: return std::numeric_limits<double>::quiet_NaN();
    case 2: return std::numeric_limits<double>::infinity();
    case 3: return -std::numeric_limits<double>::infinity();
    case 4: return 0.0;
    case 5: return -0.0;
    case 6: return -1.0;
    case 7: return p.lo;
    case 8: return p.hi;
    case 9: return p.lo - span * 1e-9;
    case 10: return p.hi + span * 1e-9;
    case 11: return std::nextafter(p.lo, -std::numeric_limits<double>::infinity());
    case 12: return std::nextafter(p.hi, std::numeric_limits<double>::infinity());
    case 13: return p.hi * 1e6 + 1.0;
    case 14: return std::numeric_limits<double>::max();
    case 15: return std::numeric_limits<double>::denorm_min();
    case 255: return r.RawDouble();
    default: break;
  }
  const double t = (b - 16) / 238.0;  // 0..1
  if (p.log) return std::pow(10.0, std::log10(p.lo) + (std::log10(p.hi) - std::log10(p.lo)) * t);
  return p.lo + span * t;
}

struct CoreCase {
  PipelineConfig config;
  bool has_mask = false;
  std::vector<uint32_t> radiance[3];
  std::vector<uint16_t> mask;
  std::vector<uint32_t> inverse_depth;
  std::vector<int32_t> motion[2];

  FrameInput View() const {
    FrameInput in;
    const int w = config.geometry.width, h = config.geometry.height;
    for (int c = 0; c < 3; ++c) in.radiance[c] = MakeImageView<const uint32_t>(radiance[c].data(), w, h);
    if (has_mask) in.vignetting_mask = MakeImageView<const uint16_t>(mask.data(), w, h);
    if (!inverse_depth.empty()) in.inverse_depth = MakeImageView<const uint32_t>(inverse_depth.data(), w, h);
    for (int d = 0; d < 2; ++d)
      if (!motion[d].empty()) in.motion_vectors[d] = MakeImageView<const int32_t>(motion[d].data(), w, h);
    return in;
  }
};

inline CoreCase DecodeCoreCase(const uint8_t* data, size_t size) {
  ByteReader r(data, size);
  CoreCase k;
  PipelineConfig& c = k.config;
  c.geometry.width = 1 + r.Byte() % 64;
  c.geometry.height = 1 + r.Byte() % 64;
  c.geometry.cfa = static_cast<Cfa>(r.Byte() % 6);
  const uint8_t bits = r.Byte();
  c.geometry.adc_bits = bits == 0 ? 12 : 6 + bits % 13;
  const uint8_t mode = r.Byte();
  if (mode % 2 == 0) {
    constexpr uint32_t kAll = (1u << kStageCount) - 1;
    uint32_t mask = (r.Byte() | (uint32_t{r.Byte()} << 8)) & kAll;
    if (mask == 0) mask = kAll;
    c.order_count = 0;
    for (int i = 0; i < kStageCount; ++i)
      if (mask & (1u << i)) c.order[c.order_count++] = static_cast<StageId>(i);
  } else {
    c.order_count = (mode >> 1) % (kStageCount + 2);
    for (int i = 0; i < c.order_count; ++i) {
      const StageId id = static_cast<StageId>(r.Byte() % (kStageCount + 1));
      if (i < kStageCount) c.order[i] = id;
    }
  }
  c.seed = r.Byte() | (uint64_t{r.Byte()} << 8);
  c.vignetting.mode = static_cast<VignettingMode>(r.Byte() % 5);
  c.vignetting.table_count = r.Byte() % 66;
  c.demosaic.method = static_cast<DemosaicMethod>(r.Byte() % 3);
  c.gamma.curve = static_cast<GammaCurve>(r.Byte() % 4);
  c.sensor.shot_noise = r.Byte() != 1;
  k.has_mask = r.Byte() & 1;
  // Defaults the host would fill in (so that a stage switched on below can run).
  c.dof.pixel_pitch_um = 5.0;
  c.motion_blur.fx_px = c.motion_blur.fy_px = 100.0;
  c.distortion.lens.fx = c.distortion.lens.fy = c.geometry.width;
  c.distortion.lens.cx = (c.geometry.width - 1) / 2.0;
  c.distortion.lens.cy = (c.geometry.height - 1) / 2.0;
  for (const NumberParam& p : Params()) p.ref(c) = DecodeNumber(r, p, p.ref(c));
  c.dof.method = static_cast<DofMethod>(r.Byte() % 3);
  c.dof.structural_only = r.Byte() & 1;
  if (c.dof.structural_poly[0] != 0.0) c.dof.structural_poly_count = 1;
  c.motion_blur.source = static_cast<MotionSource>(r.Byte() % 3);
  c.distortion.lens.model = static_cast<DistortionModel>(r.Byte() % 3);
  c.distortion.lens.fy = c.distortion.lens.fx;
  const uint8_t filter = r.Byte();
  c.distortion.filter = static_cast<ResampleFilter>((filter & 0x7F) % 4);
  c.distortion.ringing_clamp = (filter & 0x80) == 0;  // the filter byte's top bit turns the clamp off
  c.blooming.enabled = r.Byte() & 1;
  c.flare.enabled = r.Byte() & 1;
  // Table entries not named in Params() repeat the decoded ones.
  for (int i = 3; i < VignettingConfig::kMaxTable - 1; ++i) c.vignetting.table[i] = c.vignetting.table[i % 3];

  const size_t n = static_cast<size_t>(c.geometry.width) * c.geometry.height;
  std::vector<uint32_t> samples;
  while (r.remaining() >= 4 && samples.size() < 3 * n) {
    const uint8_t* p = r.here();
    samples.push_back(p[0] | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24));
    for (int i = 0; i < 4; ++i) r.Byte();
  }
  if (samples.empty()) samples = {0u, 0x8000u, 0x10000u, 0x7FFFFFFFu, 0xFFFFFFFFu, 1u, 0x640000u};
  for (int ch = 0; ch < 3; ++ch) {
    k.radiance[ch].resize(n);
    for (size_t i = 0; i < n; ++i) k.radiance[ch][i] = samples[(ch * n + i) % samples.size()];
  }
  k.mask.resize(n);
  for (size_t i = 0; i < n; ++i) k.mask[i] = static_cast<uint16_t>(k.radiance[0][i] ^ (k.radiance[1][i] >> 16));
  k.inverse_depth.resize(n);
  for (size_t i = 0; i < n; ++i) k.inverse_depth[i] = k.radiance[2][i] ^ (k.radiance[0][i] << 7);
  for (int d = 0; d < 2; ++d) {
    k.motion[d].resize(n);
    for (size_t i = 0; i < n; ++i) k.motion[d][i] = static_cast<int32_t>(k.radiance[d][i] * 2654435761u);
  }
  return k;
}

// The inverse for seeds: a blob that decodes to exactly this configuration
// (numbers as raw doubles; orders as explicit lists; samples verbatim).
inline std::vector<uint8_t> EncodeCoreCase(const PipelineConfig& config, bool has_mask,
                                           const std::vector<uint32_t>& samples) {
  PipelineConfig c = config;
  std::vector<uint8_t> b;
  b.push_back(static_cast<uint8_t>(c.geometry.width - 1));
  b.push_back(static_cast<uint8_t>(c.geometry.height - 1));
  b.push_back(static_cast<uint8_t>(c.geometry.cfa));
  b.push_back(static_cast<uint8_t>(c.geometry.adc_bits - 6 + 13));  // never 0 (which means 12)
  b.push_back(static_cast<uint8_t>(1 + 2 * c.order_count));
  for (int i = 0; i < c.order_count; ++i) b.push_back(static_cast<uint8_t>(c.order[i]));
  b.push_back(static_cast<uint8_t>(c.seed));
  b.push_back(static_cast<uint8_t>(c.seed >> 8));
  b.push_back(static_cast<uint8_t>(c.vignetting.mode));
  b.push_back(static_cast<uint8_t>(c.vignetting.table_count));
  b.push_back(static_cast<uint8_t>(c.demosaic.method));
  b.push_back(static_cast<uint8_t>(c.gamma.curve));
  b.push_back(c.sensor.shot_noise ? 0 : 1);
  b.push_back(has_mask ? 1 : 0);
  for (const NumberParam& p : Params()) {
    b.push_back(255);
    uint8_t raw[8];
    std::memcpy(raw, &p.ref(c), 8);
    b.insert(b.end(), raw, raw + 8);
  }
  b.push_back(static_cast<uint8_t>(c.dof.method));
  b.push_back(c.dof.structural_only ? 1 : 0);
  b.push_back(static_cast<uint8_t>(c.motion_blur.source));
  b.push_back(static_cast<uint8_t>(c.distortion.lens.model));
  b.push_back(static_cast<uint8_t>(static_cast<uint8_t>(c.distortion.filter) | (c.distortion.ringing_clamp ? 0 : 0x80)));
  b.push_back(c.blooming.enabled ? 1 : 0);
  b.push_back(c.flare.enabled ? 1 : 0);
  for (uint32_t s : samples)
    for (int i = 0; i < 4; ++i) b.push_back(static_cast<uint8_t>(s >> (8 * i)));
  return b;
}

// The largest value a sample of `domain` may take.
inline uint32_t DomainMax(Domain d, int adc_bits) {
  switch (d) {
    case Domain::kDigital: return (1u << adc_bits) - 1;
    case Domain::kLinear:
    case Domain::kEncoded: return 65535u;
    case Domain::kRadiance:
    case Domain::kPhotons: break;
  }
  return 0xFFFFFFFFu;
}

// Changes a reconfiguration may make besides Params(): what sizes or fills a
// stage's tables (fuzz_reconfigure). Selector s >= Params().size() picks
// (s - Params().size()) % kExtraChanges; one value byte follows.
inline constexpr int kExtraChanges = 9;
inline void DecodeChange(ByteReader& r, PipelineConfig* c) {
  const size_t n = Params().size();
  const size_t s = r.Byte();
  if (s < n) {
    double& v = Params()[s].ref(*c);
    v = DecodeNumber(r, Params()[s], v);
    return;
  }
  const uint8_t b = r.Byte();
  switch ((s - n) % kExtraChanges) {
    case 0: c->seed += 1u + b; break;
    case 1: c->flare.glare_radius = 1 + b % 40; break;  // 33..40: refused
    case 2: c->flare.blades = b % 18; break;            // 1, 2, 17: refused
    case 3: c->distortion.phases = 16 << (b % 6); break;  // 512: refused
    case 4: c->distortion.grid_step = 4 << (b % 6); break;  // 128: refused
    case 5: c->sensor.fixed_pattern_table = b & 1; break;
    case 6: c->sensor.column_fpn_e = b / 8.0; break;
    case 7: c->distortion.filter = static_cast<ResampleFilter>(b % 4); break;
    case 8: c->distortion.ringing_clamp = b & 1; break;
  }
}

// A frame through every running stage of a configured, initialised
// pipeline: each stage's output (tap), prefilled with `fill`.
struct TappedRun {
  std::vector<std::vector<uint32_t>> out;
  std::vector<Tap> taps;
  std::vector<LineFormat> formats;
  TappedRun(const Pipeline& p, uint32_t fill) {
    const Plan& plan = p.plan();
    for (int e = 0; e < plan.count; ++e)
      if (plan.entries[e].runs) formats.push_back(plan.entries[e].out);
    FUZZ_CHECK(static_cast<int>(formats.size()) == plan.running, "plan entries");
    out.resize(formats.size());
    taps.resize(formats.size());
    for (size_t i = 0; i < out.size(); ++i) {
      out[i].assign(static_cast<size_t>(p.width()) * p.height() * formats[i].channels, fill);
      taps[i].stage = static_cast<int>(i);
      taps[i].format = TapFormat::kU32;
      taps[i].data = out[i].data();
      taps[i].stride = static_cast<ptrdiff_t>(p.width()) * formats[i].channels;
    }
  }
};

// The per-frame pre-passes (flare, smear) the configuration asks for, as the
// host runs them, into storage the returned input points to.
struct Prepassed {
  std::vector<FlareSource> flare_sources;
  FlareFrame flare;
  std::vector<uint32_t> smear;
  FrameInput input;
  Prepassed(const Pipeline& p, const FrameInput& plain)
      : flare_sources(static_cast<size_t>(p.PrepassFlareSources())),
        smear(static_cast<size_t>(p.PrepassSmearEntries())) {
    input = p.RunPrepasses(plain, Span<FlareSource>{flare_sources.data(), flare_sources.size()}, &flare,
                           Span<uint32_t>{smear.data(), smear.size()});
  }
};

// Configures (errors are fine: returns false), then runs the frame twice: the
// whole frame in strips of `rows_a` on worker 0, and in strips of `rows_b`
// alternating between workers 0 and 1, with every tap prefilled differently.
// Aborts if the outputs differ, a sample is out of its domain's range, or a
// step that must succeed for a valid configuration fails.
inline bool RunChecked(const PipelineConfig& config, const FrameInput& plain, bool has_mask, int rows_a,
                       int rows_b) {
  Pipeline p;
  if (!p.Configure(config, 2, has_mask).ok()) return false;
  // Garbage, not zeros: a ring row that is read before it was written shows up
  // as 0xA5A5A5A5, out of range in every domain after the sensor.
  std::vector<uint8_t> workspace(p.WorkspaceBytes(), 0xA5);
  const Status init = p.Init(Span<uint8_t>{workspace.data(), workspace.size()});
  FUZZ_CHECK(init.ok(), "Init failed after Configure succeeded: %s", init.message());
  const Prepassed prepassed(p, plain);
  const FrameInput& input = prepassed.input;
  const Status in = p.CheckInput(input);
  FUZZ_CHECK(in.ok(), "CheckInput refused a well-formed frame: %s", in.message());

  const Plan& plan = p.plan();
  FUZZ_CHECK(plan.running >= 1 && plan.running <= kStageCount, "running %d", plan.running);
  const int h = p.height();
  // Tap every running stage.
  TappedRun a(p, 0xA5A5A5A5u), b(p, 0x5A5A5A5Au);
  std::vector<std::vector<uint32_t>>& out_a = a.out;
  const std::vector<std::vector<uint32_t>>& out_b = b.out;
  std::vector<Tap>& taps_a = a.taps;
  std::vector<Tap>& taps_b = b.taps;
  const std::vector<LineFormat>& formats = a.formats;
  WorkerStats stats{};
  p.ProcessFrame(input, 7, rows_a, taps_a.data(), static_cast<int>(taps_a.size()), &stats, nullptr);
  if (rows_b < 1) rows_b = 1;
  for (int y = 0, k = 0; y < h; y += rows_b, ++k)
    p.ProcessStrip(input, 7, y, y + rows_b, k & 1, taps_b.data(), static_cast<int>(taps_b.size()), nullptr,
                   nullptr);
  for (size_t i = 0; i < out_a.size(); ++i) {
    const uint32_t max = DomainMax(formats[i].domain, config.geometry.adc_bits);
    for (size_t j = 0; j < out_a[i].size(); ++j) {
      FUZZ_CHECK(out_a[i][j] == out_b[i][j],
                 "stage %zu (%s) sample %zu differs between strip heights %d and %d: %u vs %u", i,
                 DomainName(formats[i].domain), j, rows_a, rows_b, out_a[i][j], out_b[i][j]);
      FUZZ_CHECK(out_a[i][j] <= max, "stage %zu (%s) sample %zu = %u > %u", i, DomainName(formats[i].domain), j,
                 out_a[i][j], max);
    }
  }
  return true;
}

}  // namespace camsim::fuzz
