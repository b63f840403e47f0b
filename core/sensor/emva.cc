#include "core/sensor/emva.h"

#include <cmath>
#include <cstring>

#include "core/base/check.h"
#include "core/base/detmath.h"
#include "core/base/simd.h"
#include "core/pipeline/pipeline.h"  // FrameInput (smear)

namespace camsim {
namespace {

constexpr double kMaxFullWell = 1e6;  // keeps v * K inside int64 (see header)
constexpr uint32_t kDefectBand = uint32_t{1} << 26;  // each defect class's band of u (emva.h)

// Dark charge per exposure of a dark current (e-/s at the reference temperature).
double DarkElectrons(const SensorConfig& c, double exposure_time_us, double e_per_s) {
  const double doublings = (c.temperature_c - c.dark_current_ref_c) / c.dark_current_doubling_c;
  return e_per_s * (exposure_time_us * 1e-6) * detmath::Exp2(doublings);
}
double DarkElectrons(const SensorConfig& c, double exposure_time_us) {
  return DarkElectrons(c, exposure_time_us, c.dark_current_e_per_s);
}

double SystemGain(const SensorConfig& c) {
  return c.system_gain_dn_per_e * detmath::Pow(10.0, c.gain_db / 20.0);
}

bool InRange(double v, double lo, double hi) { return v >= lo && v <= hi; }  // false for NaN

// The readout's integers: SensorStage::Configure's, and SensorSaturationDn's.
struct Readout {
  UScale k;                   // K
  uint64_t full_well_q8 = 0;  // Q24.8 electrons
  int64_t black = 0;          // floor of the black level
  int64_t black_round = 0;    // 2^(k_shift - 1) + the black level's fraction * 2^k_shift
};
Result<Readout> MakeReadout(const SensorConfig& c) {
  Result<UScale> k = UScale::FromDouble(SystemGain(c), "sensor.system_gain_dn_per_e");
  if (!k.ok()) return k.status();
  Readout r;
  r.k = k.value();
  r.full_well_q8 = Q<24, 8>::FromDouble(c.full_well_e).raw;
  // round(K v + BL) = floor((v K_mant + 2^(s-1) + frac(BL) 2^s) / 2^s) + floor(BL), s = K.shift + 8: the
  // fraction joins the rounding constant (exact: frac(BL) 2^s is a double scaled by a power of two, < 2^49).
  const double whole_black = std::floor(c.black_level_dn);
  r.black = static_cast<int64_t>(whole_black);
  r.black_round = (int64_t{1} << (r.k.shift + 7)) + std::llround(std::ldexp(c.black_level_dn - whole_black, r.k.shift + 8));
  return r;
}

}  // namespace

double SensorSaturationDn(const SensorConfig& c, const SensorGeometry& g) {
  const double max_dn = (1 << g.adc_bits) - 1;
  const Result<Readout> r = MakeReadout(c);
  if (!r.ok() || !InRange(c.full_well_e, 0.0, kMaxFullWell)) return max_dn;  // the sensor stage refuses these
  // A full well without noise, read out as the stage reads it (ProcessRow):
  // full_well_q8 < 2^28 and the mantissa < 2^32, so the product fits.
  const Readout& o = r.value();
  const int64_t dn =
      ((static_cast<int64_t>(o.full_well_q8) * o.k.mant + o.black_round) >> (o.k.shift + 8)) + o.black;
  const double level = static_cast<double>(dn);  // exact: below 2^53
  return level > max_dn ? max_dn : level;
}

namespace {

// The moments of max(0, 1 + s z) over z standard normal (emva.h, ReferenceDarkChargeMean):
// with a = 1 / s, the mean Phi(a) + s phi(a) and the second moment (1 + s^2) Phi(a) + s phi(a).
struct DcnuMoments {
  double mean = 1.0, second = 1.0;
};
DcnuMoments DcnuFactorMoments(double s) {
  DcnuMoments m;
  if (!(s > 0)) return m;
  const double a = 1.0 / s;
  const double cdf = detmath::NormalCdf(a);
  const double pdf = detmath::Exp(-0.5 * a * a) * 0.39894228040143267794;  // 1 / sqrt(2 pi)
  m.mean = cdf + s * pdf;
  m.second = (1.0 + s * s) * cdf + s * pdf;
  return m;
}

}  // namespace

namespace {

// Fills t with one entry per pixel of each of `channels` planes, rows in
// order, as ProcessRow draws them: pixel x of row y, channel ch, is
// entry(b, x & 1) of b = DrawBits(seed, stream, 0, x >> 1, y, ch), one call
// serving a pixel pair (emva.h, "Random words").
template <typename T, typename Entry>
void FillPixelTable(T* t, uint64_t seed, uint32_t stream, const SensorGeometry& g, int channels, Entry entry) {
  for (int ch = 0; ch < channels; ++ch)
    for (int y = 0; y < g.height; ++y)
      for (int x = 0; x < g.width; x += 2) {
        const RandomBits b =
            DrawBits(seed, stream, 0, static_cast<uint32_t>(x) >> 1, static_cast<uint32_t>(y), static_cast<uint32_t>(ch));
        *t++ = entry(b, 0);
        if (x + 1 < g.width) *t++ = entry(b, 1);
      }
}

}  // namespace

double ReferenceDarkChargeMean(const SensorConfig& c, double exposure_time_us) {
  const double dark = DarkElectrons(c, exposure_time_us);
  return c.dcnu_percent > 0 ? dark * DcnuFactorMoments(c.dcnu_percent / 100.0).mean : dark;
}

double ReferenceDarkChargeRms(const SensorConfig& c, double exposure_time_us) {
  const DcnuMoments m = DcnuFactorMoments(c.dcnu_percent / 100.0);
  const double var = m.second - m.mean * m.mean;
  return DarkElectrons(c, exposure_time_us) * std::sqrt(var > 0 ? var : 0.0);
}

double ReferenceSensorMeanDn(const SensorConfig& c, const SensorGeometry& g, double exposure_time_us,
                             Colour colour, double photons) {
  const int qe_index = g.cfa == Cfa::kMono ? kGreen : colour;
  double e = photons * c.quantum_efficiency[qe_index] + ReferenceDarkChargeMean(c, exposure_time_us);
  if (e > c.full_well_e) e = c.full_well_e;
  const double dn = SystemGain(c) * e + c.black_level_dn;
  const double max_dn = (1 << g.adc_bits) - 1;
  return dn < 0 ? 0 : (dn > max_dn ? max_dn : dn);
}

Status SensorStage::Configure(const SensorConfig& c, const SensorGeometry& g, double exposure_time_us,
                              uint64_t seed) {
  for (double qe : c.quantum_efficiency)
    if (!InRange(qe, 0.0, 1.0)) return InvalidArgument("sensor.quantum_efficiency", "must be in [0, 1]");
  if (!InRange(c.full_well_e, 1.0, kMaxFullWell))
    return InvalidArgument("sensor.full_well_e", "must be in [1, 1e6] electrons");
  if (!InRange(c.system_gain_dn_per_e, 1e-3, 1e3))
    return InvalidArgument("sensor.system_gain_dn_per_e", "must be in [0.001, 1000] DN/e-");
  if (!InRange(c.gain_db, 0.0, 48.0)) return InvalidArgument("sensor.gain_db", "must be in [0, 48] dB");
  if (!InRange(c.dark_noise_e, 0.0, 1000.0))
    return InvalidArgument("sensor.dark_noise_e", "must be in [0, 1000] electrons");
  if (!InRange(c.dark_current_e_per_s, 0.0, 1e6))
    return InvalidArgument("sensor.dark_current_e_per_s", "must be in [0, 1e6] e-/s");
  if (!InRange(c.temperature_c, -100.0, 150.0))
    return InvalidArgument("sensor.temperature_c", "must be in [-100, 150] degrees C");
  if (!InRange(c.dark_current_ref_c, -100.0, 150.0))
    return InvalidArgument("sensor.dark_current_ref_c", "must be in [-100, 150] degrees C");
  if (!InRange(c.dark_current_doubling_c, 1.0, 100.0))
    return InvalidArgument("sensor.dark_current_doubling_c", "must be in [1, 100] kelvin");
  if (!InRange(c.dsnu_e, 0.0, 1000.0)) return InvalidArgument("sensor.dsnu_e", "must be in [0, 1000] electrons");
  if (!InRange(c.prnu_percent, 0.0, 50.0)) return InvalidArgument("sensor.prnu_percent", "must be in [0, 50] %");
  if (!InRange(c.dcnu_percent, 0.0, 100.0)) return InvalidArgument("sensor.dcnu_percent", "must be in [0, 100] %");
  if (!InRange(c.row_fpn_e, 0.0, 1000.0)) return InvalidArgument("sensor.row_fpn_e", "must be in [0, 1000] electrons");
  if (!InRange(c.column_fpn_e, 0.0, 1000.0))
    return InvalidArgument("sensor.column_fpn_e", "must be in [0, 1000] electrons");
  if (!InRange(c.hot_pixel_fraction, 0.0, 0.01))
    return InvalidArgument("sensor.hot_pixel_fraction", "must be in [0, 0.01]");
  if (!InRange(c.dead_pixel_fraction, 0.0, 0.01))
    return InvalidArgument("sensor.dead_pixel_fraction", "must be in [0, 0.01]");
  if (!InRange(c.stuck_pixel_fraction, 0.0, 0.01))
    return InvalidArgument("sensor.stuck_pixel_fraction", "must be in [0, 0.01]");
  if (!InRange(c.hot_pixel_dark_e_per_s, 0.0, 1e7))
    return InvalidArgument("sensor.hot_pixel_dark_e_per_s", "must be in [0, 1e7] e-/s");
  if (!InRange(c.smear_row_transfer_us, 0.0, 1000.0))
    return InvalidArgument("sensor.smear_row_transfer_us", "must be in [0, 1000] us");
  if (!InRange(c.smear_leak, 0.0, 1.0)) return InvalidArgument("sensor.smear_leak", "must be in [0, 1]");
  if (c.smear_row_transfer_us > 0 && c.smear_row_transfer_us * c.smear_leak > exposure_time_us)
    return InvalidArgument("sensor.smear_row_transfer_us", "leak * row transfer time must not exceed the exposure time");
  if (g.adc_bits < 8 || g.adc_bits > 16) return InvalidArgument("sensor.adc_bits", "must be 8 to 16");
  max_dn_ = (1 << g.adc_bits) - 1;
  if (!InRange(c.black_level_dn, 0.0, max_dn_ - 1.0))
    return InvalidArgument("sensor.black_level_dn", "must be in [0, 2^adc_bits - 2]");

  config_ = c;
  geometry_ = g;
  seed_ = seed;
  k_ = SystemGain(c);
  dark_e_ = DarkElectrons(c, exposure_time_us);
  if (!InRange(dark_e_, 0.0, kMaxFullWell))
    return InvalidArgument("sensor.dark_current_e_per_s", "dark charge per exposure exceeds 1e6 electrons");
  Result<Readout> readout = MakeReadout(c);
  if (!readout.ok()) return readout.status();
  k_scale_ = readout.value().k;
  for (int i = 0; i < 3; ++i) qe_q16_[i] = Q<1, 16>::FromDouble(c.quantum_efficiency[i]).raw;
  prnu_q16_ = Q<15, 16>::FromDouble(c.prnu_percent / 100.0).raw;
  dcnu_q16_ = Q<15, 16>::FromDouble(c.dcnu_percent / 100.0).raw;  // <= 65536
  dsnu_q8_ = Q<23, 8>::FromDouble(c.dsnu_e).raw;
  read_q8_ = Q<23, 8>::FromDouble(c.dark_noise_e).raw;
  dark_q8_ = Q<24, 8>::FromDouble(dark_e_).raw;
  full_well_q8_ = readout.value().full_well_q8;
  black_ = readout.value().black;
  black_round_ = readout.value().black_round;
  smear_ = c.smear_row_transfer_us > 0 && c.smear_leak > 0;
  row_fpn_q8_ = Q<23, 8>::FromDouble(c.row_fpn_e).raw;
  col_fpn_q8_ = Q<23, 8>::FromDouble(c.column_fpn_e).raw;
  // One band of the uniform 32-bit word u per class (emva.h); each fraction
  // <= 0.01 < 1/64, so no band reaches the next.
  const auto width = [](double fraction) { return static_cast<uint32_t>(fraction * 4294967296.0); };
  const uint32_t hot = width(c.hot_pixel_fraction), dead = width(c.dead_pixel_fraction),
                 stuck = width(c.stuck_pixel_fraction);
  hot_width_ = hot;
  dead_width_ = dead;
  stuck_width_ = stuck;
  defects_on_ = (hot | dead | stuck) != 0;
  const double hot_e = DarkElectrons(c, exposure_time_us, c.hot_pixel_dark_e_per_s);
  if (!InRange(hot_e, 0.0, kMaxFullWell))
    return InvalidArgument("sensor.hot_pixel_dark_e_per_s", "hot-pixel charge per exposure exceeds 1e6 electrons");
  hot_q8_ = Q<24, 8>::FromDouble(hot_e).raw;
  exposure_time_us_ = exposure_time_us;
  if (c.defect_count < 0 || c.defect_count > kMaxListedDefects || (c.defect_count > 0 && c.defects == nullptr))
    return InvalidArgument("sensor.defects_file", "at most 1048576 listed defects");
  for (int i = 0; i < c.defect_count; ++i) {
    const DefectPixel& d = c.defects[i];
    if (d.x < 0 || d.y < 0 || d.x >= g.width || d.y >= g.height)
      return InvalidArgument("sensor.defects_file", "listed defect outside the frame");
    if (i > 0 && (d.y < c.defects[i - 1].y || (d.y == c.defects[i - 1].y && d.x <= c.defects[i - 1].x)))
      return InvalidArgument("sensor.defects_file", "listed defects must be sorted by (y, x) without duplicates");
    if (d.value != d.value)  // a negative value asks for the default; NaN is none
      return InvalidArgument("sensor.defects_file", "a listed defect's value is NaN");
    if (d.kind == DefectKind::kHot && d.value >= 0 &&
        !InRange(DarkElectrons(c, exposure_time_us, d.value), 0.0, kMaxFullWell))
      return InvalidArgument("sensor.defects_file", "hot-pixel charge per exposure exceeds 1e6 electrons");
    if (d.kind == DefectKind::kStuck && d.value >= 0 && !(d.value <= max_dn_ && d.value == static_cast<int>(d.value)))
      return InvalidArgument("sensor.defects_file", "stuck value must be an integer DN in [0, 2^adc_bits - 1]");
    if (d.kind != DefectKind::kHot && d.kind != DefectKind::kDead && d.kind != DefectKind::kStuck)
      return InvalidArgument("sensor.defects_file", "unknown defect kind");
  }
  return Status::Ok();
}

Result<LineFormat> SensorStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kPhotons) return InvalidArgument("sensor", "needs photons input");
  return LineFormat{Domain::kDigital, in.channels, in.mosaic};
}

void SensorStage::CountTables(WorkspaceCounter& counter) const {
  counter.Add<int32_t>(GaussianTable::kEntries);
  counter.Add<uint32_t>(PoissonTable::kEntries);
  if (col_fpn_q8_ != 0) counter.Add<int32_t>(static_cast<size_t>(ColumnTableEntries()));
  if (UsesPatternTable()) counter.Add<PatternEntry>(PatternEntries());
  if (UsesDarkGainTable()) counter.Add<uint32_t>(PatternEntries());
  if (config_.defect_count > 0) {
    counter.Add<ListedDefect>(static_cast<size_t>(config_.defect_count));
    counter.Add<uint32_t>(static_cast<size_t>(geometry_.height) + 1);
  }
}

Status SensorStage::Init(Arena& tables) {
  int copied = 0;
  return Build(tables, nullptr, &copied);
}

Status SensorStage::InitFrom(Arena& tables, const Stage& previous, int* copied) {
  const SensorStage& p = static_cast<const SensorStage&>(previous);  // the same class (Stage::InitFrom)
  return Build(tables, &p != this && p.gauss_.built() ? &p : nullptr, copied);
}

Status SensorStage::Build(Arena& tables, const SensorStage* previous, int* copied) {
  *copied = 0;
  int32_t* g = tables.Take<int32_t>(GaussianTable::kEntries);
  uint32_t* p = tables.Take<uint32_t>(PoissonTable::kEntries);
  if (g == nullptr || p == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for sensor tables");
  if (previous != nullptr) {  // constants
    CAMSIM_TRY(gauss_.CopyFrom(previous->gauss_, Span<int32_t>{g, GaussianTable::kEntries}));
    CAMSIM_TRY(poisson_.CopyFrom(previous->poisson_, Span<uint32_t>{p, PoissonTable::kEntries}));
    *copied += 2;
  } else {
    CAMSIM_TRY(gauss_.Build(Span<int32_t>{g, GaussianTable::kEntries}));
    CAMSIM_TRY(poisson_.Build(Span<uint32_t>{p, PoissonTable::kEntries}));
  }
  avx2_ = CpuHasAvx2();
  avx512_ = CpuHasAvx512();
  listed_ = nullptr;
  listed_row_ = nullptr;
  if (config_.defect_count > 0) {
    const size_t n = static_cast<size_t>(config_.defect_count);
    ListedDefect* l = tables.Take<ListedDefect>(n);
    uint32_t* row = tables.Take<uint32_t>(static_cast<size_t>(geometry_.height) + 1);
    if (l == nullptr || row == nullptr)
      return Status(StatusCode::kResourceExhausted, "workspace too small for sensor tables");
    int next = 0;  // the list is sorted by (y, x) (Configure checked)
    for (int y = 0; y <= geometry_.height; ++y) {
      while (next < config_.defect_count && config_.defects[next].y < y) ++next;
      row[y] = static_cast<uint32_t>(next);
    }
    for (size_t i = 0; i < n; ++i) {
      const DefectPixel& d = config_.defects[i];
      l[i].x = static_cast<uint32_t>(d.x);
      l[i].kind = d.kind;
      l[i].value = 0;
      if (d.kind == DefectKind::kHot)
        l[i].value = d.value < 0 ? hot_q8_
                                 : Q<24, 8>::FromDouble(DarkElectrons(config_, exposure_time_us_, d.value)).raw;
      if (d.kind == DefectKind::kStuck) l[i].value = d.value < 0 ? static_cast<uint32_t>(max_dn_)
                                                                 : static_cast<uint32_t>(d.value);
    }
    listed_ = l;
    listed_row_ = row;
  }
  // The fixed pattern (per pixel) and the column offsets (per column): draws
  // keyed by the seed, scaled by their sigmas.
  const bool same_columns =
      previous != nullptr && previous->seed_ == seed_ && previous->geometry_.width == geometry_.width;
  const bool same_pixels = same_columns && previous->geometry_.height == geometry_.height;
  pattern_ = nullptr;
  if (UsesPatternTable()) {
    // The words ProcessRow would draw: pixel x of channel ch, row y takes words
    // 2 (x & 1) and 2 (x & 1) + 1 of the fixed-pattern call for pair x >> 1.
    PatternEntry* t = tables.Take<PatternEntry>(PatternEntries());
    if (t == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for the sensor's fixed pattern");
    pattern_ = t;
    if (same_pixels && previous->pattern_ != nullptr && previous->input_channels_ == input_channels_ &&
        previous->prnu_q16_ == prnu_q16_ && previous->dsnu_q8_ == dsnu_q8_) {
      std::memcpy(t, previous->pattern_, PatternEntries() * sizeof(PatternEntry));
      ++*copied;
    } else {
      FillPixelTable(t, seed_, kStreamSensorFixedPattern, geometry_, input_channels_,
                     [&](const RandomBits& b, int odd) {
                       return Pattern(gauss_.Sample(b.v[2 * odd]), gauss_.Sample(b.v[2 * odd + 1]));
                     });
    }
  }
  dark_gain_ = nullptr;
  if (UsesDarkGainTable()) {
    // The dark-current gains ProcessRow would draw: pixel x takes word 2 (x & 1)
    // of the dark-current call for pair x >> 1.
    uint32_t* t = tables.Take<uint32_t>(PatternEntries());
    if (t == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for the sensor's fixed pattern");
    dark_gain_ = t;
    if (same_pixels && previous->dark_gain_ != nullptr && previous->input_channels_ == input_channels_ &&
        previous->dcnu_q16_ == dcnu_q16_) {
      std::memcpy(t, previous->dark_gain_, PatternEntries() * sizeof(uint32_t));
      ++*copied;
    } else {
      FillPixelTable(t, seed_, kStreamSensorDarkCurrent, geometry_, input_channels_,
                     [&](const RandomBits& b, int odd) { return DarkGain(gauss_.Sample(b.v[2 * odd])); });
    }
  }
  column_offset_ = nullptr;
  if (col_fpn_q8_ != 0) {
    // Column c of channel ch: z from DrawBits(seed, row/column stream, 0, x, 0, 2 * ch).
    int32_t* t = tables.Take<int32_t>(static_cast<size_t>(ColumnTableEntries()));
    if (t == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for sensor tables");
    if (same_columns && previous->column_offset_ != nullptr && previous->col_fpn_q8_ == col_fpn_q8_) {
      std::memcpy(t, previous->column_offset_, static_cast<size_t>(ColumnTableEntries()) * sizeof(int32_t));
      ++*copied;
    } else {
      for (int ch = 0; ch < kMaxChannels; ++ch)
        for (int x = 0; x < geometry_.width; ++x) {
          const RandomBits b = DrawBits(seed_, kStreamSensorRowColumn, 0, static_cast<uint32_t>(x), 0,
                                        static_cast<uint32_t>(2 * ch));
          t[ch * geometry_.width + x] = static_cast<int32_t>(RoundShift(col_fpn_q8_ * gauss_.Sample(b.v[0]), 16));
        }
    }
    column_offset_ = t;
  }
  return Status::Ok();
}

SensorStage::PatternEntry SensorStage::Pattern(int32_t z_prnu, int32_t z_dsnu) const {
  // |prnu_q16_ * z| >> 16 <= 0.5 * 2^16 * |z| and |dsnu_q8_ * z| >> 16 <= 2.6e5 * |z|
  // (Configure's ranges; |z| <= GaussianTable's largest sample): both fit int32.
  const int64_t gain = 65536 + RoundShift(prnu_q16_ * z_prnu, 16);  // Q3.16 (< 4.2)
  return PatternEntry{static_cast<int32_t>(gain < 0 ? 0 : gain),
                      static_cast<int32_t>(RoundShift(dsnu_q8_ * z_dsnu, 16))};
}

uint32_t SensorStage::DarkGain(int32_t z) const {
  // |dcnu_q16_ * z| <= 2^16 * 415364 < 2^35; the gain < 7.34 * 2^16 < 2^19 (emva.h, Formats).
  const int64_t gain = 65536 + RoundShift(dcnu_q16_ * z, 16);
  return static_cast<uint32_t>(gain < 0 ? 0 : gain);
}

#ifdef CAMSIM_X86_AVX2
// Passes 1 and 3 of ProcessRow for rows without defects, in AVX2: four
// pixels i .. i + 3 (i a multiple of 4) in four 64-bit lanes, step for step
// the integers of the portable passes (below), so the bytes are the same.
// Where a value fits int32, it is kept in the low half of its lane.
namespace sensor_lanes {

using Words = uint32_t[RandomLanes::kLanes];
using Normals = int32_t[RandomLanes::kLanes];

// Word w of pixels i .. i + 3 (i even): an even pixel takes word w of lane
// i / 2, an odd one word w + 2 of the same lane (emva.h, "Random words").
template <typename T>
CAMSIM_AVX2_TARGET inline __m128i PixelWords(const T (*v)[RandomLanes::kLanes], int w, int i) {
  const __m128i even = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(&v[w][i / 2]));
  const __m128i odd = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(&v[w + 2][i / 2]));
  return _mm_unpacklo_epi32(even, odd);
}
// RoundShift(p, 16) of signed lanes whose results fit int32, in the low
// halves: a logical shift gives the arithmetic shift's low 32 bits.
CAMSIM_AVX2_TARGET inline __m256i RoundShift16Low(__m256i p) {
  return _mm256_srli_epi64(_mm256_add_epi64(p, _mm256_set1_epi64x(1 << 15)), 16);
}
// a where mask is all ones, else b (64-bit lanes).
CAMSIM_AVX2_TARGET inline __m256i Pick(__m256i mask, __m256i a, __m256i b) { return _mm256_blendv_epi8(b, a, mask); }

// Pass 1's inputs for one block (pointers at the block's first pixel).
struct MeanIn {
  const uint32_t* in;               // photons, Q24.8
  uint32_t qe[2];                   // Q1.16, even and odd columns
  const Normals* fz;                // fixed-pattern normals, or null
  const int32_t* pattern;           // the pattern table's (gain, DSNU) pairs, or null
  int64_t prnu_q16, dsnu_q8;
  int32_t row_offset;               // Q.8 electrons
  const int32_t* column;            // column FPN, or null
  const uint32_t* smear;            // smear charge, or null
  uint32_t dark_q8;
  const Normals* dz;                // DCNU normals (words 0 and 2), or null
  const uint32_t* dark_gain;        // the DCNU table's gains (Q3.16), or null
  int64_t dcnu_q16;                 // <= 2^16
};

// Pass 1 for pixels [0, count), count a multiple of 4.
CAMSIM_AVX2_TARGET void MeanCharge(const MeanIn& b, int count, uint32_t* mean_q8, int32_t* offset_q8) {
  const __m256i qe = _mm256_setr_epi64x(b.qe[0], b.qe[1], b.qe[0], b.qe[1]);
  const __m256i half16 = _mm256_set1_epi64x(1 << 15);
  const __m256i u32_max = _mm256_set1_epi64x(0xFFFFFFFF);
  const __m256i prnu = _mm256_set1_epi64x(b.prnu_q16);  // <= 2^15: a signed 32-bit factor
  const __m256i dsnu = _mm256_set1_epi64x(b.dsnu_q8);   // <= 2^18
  const __m256i dcnu = _mm256_set1_epi64x(b.dcnu_q16);  // <= 2^16
  const bool patterns = b.fz != nullptr || b.pattern != nullptr;
  const bool dark_pattern = b.dz != nullptr || b.dark_gain != nullptr;  // DCNU
  for (int i = 0; i < count; i += 4) {
    // mu = RoundShiftU(in * qe, 16) < 2^32.
    __m256i mu = _mm256_srli_epi64(_mm256_add_epi64(_mm256_mul_epu32(avx2::LoadU32x4(b.in + i), qe), half16), 16);
    __m128i offset = _mm_set1_epi32(b.row_offset);
    if (patterns) {
      __m256i gain, dsnu_low;  // Q3.16 >= 0 and Q.8 electrons, in the low halves
      if (b.pattern != nullptr) {
        gain = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b.pattern + 2 * i));
        dsnu_low = _mm256_srli_epi64(gain, 32);
      } else {
        const __m256i z1 = _mm256_cvtepi32_epi64(PixelWords(b.fz, 0, i));
        const __m256i z2 = _mm256_cvtepi32_epi64(PixelWords(b.fz, 1, i));
        gain = _mm256_add_epi32(RoundShift16Low(_mm256_mul_epi32(prnu, z1)), _mm256_set1_epi64x(65536));
        gain = _mm256_max_epi32(gain, _mm256_setzero_si256());
        dsnu_low = RoundShift16Low(_mm256_mul_epi32(dsnu, z2));
      }
      mu = _mm256_srli_epi64(_mm256_add_epi64(_mm256_mul_epu32(mu, gain), half16), 16);  // < 2^35
      offset = _mm_add_epi32(offset, avx2::Low32x4(dsnu_low));
    }
    if (b.column != nullptr) offset = _mm_add_epi32(offset, _mm_loadu_si128(reinterpret_cast<const __m128i*>(b.column + i)));
    // The portable pass saturates dark + smear at 2^32 - 1 first (a uint32);
    // in 64 bits that changes nothing, as the sum saturates there too.
    __m256i dark = _mm256_set1_epi64x(b.dark_q8);
    if (dark_pattern) {
      // DarkGain (Q3.16 < 2^19, in the low halves), then RoundShiftU(dark * gain, 16) < 2^31.
      __m256i gain;
      if (b.dark_gain != nullptr) {
        gain = avx2::LoadU32x4(b.dark_gain + i);
      } else {
        const __m256i z4 = _mm256_cvtepi32_epi64(PixelWords(b.dz, 0, i));
        gain = _mm256_add_epi32(RoundShift16Low(_mm256_mul_epi32(dcnu, z4)), _mm256_set1_epi64x(65536));
        gain = _mm256_max_epi32(gain, _mm256_setzero_si256());
      }
      dark = _mm256_srli_epi64(_mm256_add_epi64(_mm256_mul_epu32(dark, gain), half16), 16);
    }
    if (b.smear != nullptr) dark = _mm256_add_epi64(dark, avx2::LoadU32x4(b.smear + i));
    __m256i mean = _mm256_add_epi64(mu, dark);
    mean = Pick(_mm256_cmpgt_epi64(mean, u32_max), u32_max, mean);
    avx2::StoreLow32x4(mean, mean_q8 + i);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(offset_q8 + i), offset);
  }
}

// Pass 3's inputs for one block.
struct ReadoutIn {
  const uint32_t* mean_q8;
  const int32_t* offset_q8;
  const uint32_t* sigma_q16;
  const Words* t;                   // temporal words
  const Normals* tz;                // their normals
  const PoissonTable* poisson;      // null without shot noise
  uint64_t full_well_q8;
  int64_t read_q8;                  // <= 2^18
  uint32_t k_mant;                  // K = k_mant * 2^-(k_shift - 8), k_mant in [2^31, 2^32)
  int k_shift;                      // 22 .. 49
  int64_t k_round;                  // SensorStage::black_round_, < 2^50
  int64_t black;
  int max_dn;
};

constexpr int kMaxPixels = 2 * RandomLanes::kLanes;  // a block

// The small-mean Poisson draws of a block's pixels [0, count) into
// small_count[i], for the pixels whose mean is below kSmallQ8 (0 for the
// others; nothing is written when the block has none): gathered into a dense
// list, drawn in lanes, put back.
CAMSIM_AVX2_TARGET void SmallDraws(const ReadoutIn& b, int count, uint64_t* small_count) {
  const __m128i last_small = _mm_set1_epi32(PoissonTable::kSmallQ8 - 1);
  __m128i any = _mm_setzero_si128();
  for (int i = 0; i < count; i += 4) {  // mean <= kSmallQ8 - 1, unsigned
    const __m128i mean = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b.mean_q8 + i));
    any = _mm_or_si128(any, _mm_cmpeq_epi32(_mm_min_epu32(mean, last_small), mean));
  }
  if (_mm_testz_si128(any, any)) return;
  for (int i = 0; i < count; i += 4)
    _mm256_store_si256(reinterpret_cast<__m256i*>(small_count + i), _mm256_setzero_si256());
  // Zeroed only so that GCC sees them written before the call (it cannot see
  // that SampleSmallLanes reads [0, n) alone).
  uint32_t lambda[kMaxPixels] = {}, u[kMaxPixels] = {}, drawn[kMaxPixels];
  int index[kMaxPixels], n = 0;
  for (int i = 0; i < count; ++i) {  // branch-free: every pixel is written, only small ones advance n
    lambda[n] = b.mean_q8[i];
    u[n] = b.t[2 * (i & 1)][i / 2];
    index[n] = i;
    n += b.mean_q8[i] < PoissonTable::kSmallQ8;
  }
  b.poisson->SampleSmallLanes(lambda, u, drawn, n);
  for (int j = 0; j < n; ++j) small_count[index[j]] = drawn[j];
}

// Pass 3 for pixels [0, count), count a multiple of 4; adds the collected
// charge of even and odd columns to electrons[0] and [1].
//   Poisson above 12 e-: n = lambda + sigma z + (z^2 - 1) / 6 in Q32 with C++'s
//   truncating division, done on |z^2 - 2^32| < 2^38 (z is a GaussianTable
//   sample, |z| < 2^19) with FloorDiv6 and the sign put back. Pixels below
//   12 e- take the exact inverse transform: where a block has any, they are
//   gathered first and drawn together (PoissonTable::SampleSmallLanes).
//   Readout: |v| < 2^29 (emva.h) fits int32; v * K = v (k_mant - 2^31) + v 2^31
//   in signed 64-bit products; the arithmetic shift by k_shift is a logical one
//   of the sum plus 2^62 (a multiple of 2^k_shift; |v * K| + k_round < 2^62), minus 2^(62 - k_shift).
CAMSIM_AVX2_TARGET void Readout(const ReadoutIn& b, int count, uint32_t* out, int64_t electrons[2]) {
  const __m256i zero = _mm256_setzero_si256();
  const __m256i small_q8 = _mm256_set1_epi64x(PoissonTable::kSmallQ8);
  const __m256i full_well = _mm256_set1_epi64x(static_cast<int64_t>(b.full_well_q8));
  const __m256i read = _mm256_set1_epi64x(b.read_q8);
  const __m256i k_low = _mm256_set1_epi64x(static_cast<int64_t>(b.k_mant) - (int64_t{1} << 31));
  const __m256i k_bias = _mm256_set1_epi64x(b.k_round + (int64_t{1} << 62));
  const __m128i k_shift = _mm_cvtsi32_si128(b.k_shift);
  const __m256i unbias = _mm256_set1_epi64x((int64_t{1} << (62 - b.k_shift)) - b.black);
  const __m256i max_dn = _mm256_set1_epi64x(b.max_dn);
  __m256i sum = zero;  // lanes 0 and 2: even columns, 1 and 3: odd
  CAMSIM_DCHECK(count <= kMaxPixels);
  alignas(32) uint64_t small_count[kMaxPixels];  // read only for groups with a small mean
  if (b.poisson != nullptr) SmallDraws(b, count, small_count);
  for (int i = 0; i < count; i += 4) {
    const __m256i m = avx2::LoadU32x4(b.mean_q8 + i);
    __m256i n_q8 = m;
    if (b.poisson != nullptr) {
      const __m256i z = _mm256_cvtepi32_epi64(PixelWords(b.tz, 0, i));
      const __m256i sigma_z = _mm256_mul_epi32(avx2::LoadU32x4(b.sigma_q16 + i), z);  // sigma < 2^28
      const __m256i skew = _mm256_sub_epi64(_mm256_mul_epi32(z, z), _mm256_set1_epi64x(int64_t{1} << 32));
      const __m256i negative = _mm256_cmpgt_epi64(zero, skew);
      const __m256i magnitude = _mm256_sub_epi64(_mm256_xor_si256(skew, negative), negative);
      const __m256i skew6 = _mm256_sub_epi64(_mm256_xor_si256(avx2::FloorDiv6(magnitude), negative), negative);
      const __m256i n_q32 = _mm256_add_epi64(_mm256_add_epi64(_mm256_slli_epi64(m, 24), sigma_z), skew6);
      // SatU32(RoundShift(n, 32)): n < 2^57, so the high half, as int32, clamped at 0.
      __m256i drawn = _mm256_max_epi32(
          _mm256_srli_epi64(_mm256_add_epi64(n_q32, _mm256_set1_epi64x(int64_t{1} << 31)), 32), zero);
      const __m256i small = _mm256_cmpgt_epi64(small_q8, m);
      if (!_mm256_testz_si256(small, small))  // then SmallDraws wrote small_count
        drawn = Pick(small, _mm256_load_si256(reinterpret_cast<const __m256i*>(small_count + i)), drawn);
      n_q8 = _mm256_slli_epi64(drawn, 8);
    }
    n_q8 = Pick(_mm256_cmpgt_epi64(n_q8, full_well), full_well, n_q8);  // <= 1e6 * 2^8 < 2^28
    sum = _mm256_add_epi64(sum, n_q8);
    const __m256i noise = RoundShift16Low(_mm256_mul_epi32(read, _mm256_cvtepi32_epi64(PixelWords(b.tz, 1, i))));
    const __m128i v32 = _mm_add_epi32(_mm_add_epi32(avx2::Low32x4(n_q8), avx2::Low32x4(noise)),
                                      _mm_loadu_si128(reinterpret_cast<const __m128i*>(b.offset_q8 + i)));
    const __m256i v = _mm256_cvtepi32_epi64(v32);
    const __m256i vk = _mm256_add_epi64(_mm256_mul_epi32(v, k_low), _mm256_slli_epi64(v, 31));
    __m256i dn = _mm256_sub_epi64(_mm256_srl_epi64(_mm256_add_epi64(vk, k_bias), k_shift), unbias);
    dn = Pick(_mm256_cmpgt_epi64(zero, dn), zero, dn);
    dn = Pick(_mm256_cmpgt_epi64(dn, max_dn), max_dn, dn);
    avx2::StoreLow32x4(dn, out + i);
  }
  alignas(32) int64_t lanes[4];
  _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), sum);
  electrons[0] += lanes[0] + lanes[2];
  electrons[1] += lanes[1] + lanes[3];
}

#ifdef CAMSIM_X86_AVX512
// PixelWords for pixels i .. i + 7 (i a multiple of 8, so the loads stay in
// the lanes' 16 words).
template <typename T>
CAMSIM_AVX512_TARGET inline __m256i PixelWords8(const T (*v)[RandomLanes::kLanes], int w, int i) {
  const __m128i even = _mm_loadu_si128(reinterpret_cast<const __m128i*>(&v[w][i / 2]));
  const __m128i odd = _mm_loadu_si128(reinterpret_cast<const __m128i*>(&v[w + 2][i / 2]));
  return _mm256_inserti128_si256(_mm256_castsi128_si256(_mm_unpacklo_epi32(even, odd)),
                                 _mm_unpackhi_epi32(even, odd), 1);
}

// MeanCharge in eight lanes; count a multiple of 4, so a last group of four
// is masked. Each value the AVX2 version keeps in the low half of a lane is
// here the whole 64-bit lane, computed with the arithmetic shift and the
// 64-bit max and min: they fit int32 (see there), so the low halves are the
// same.
CAMSIM_AVX512_TARGET void MeanChargeAvx512(const MeanIn& b, int count, uint32_t* mean_q8, int32_t* offset_q8) {
  const __m512i qe = _mm512_setr_epi64(b.qe[0], b.qe[1], b.qe[0], b.qe[1], b.qe[0], b.qe[1], b.qe[0], b.qe[1]);
  const __m512i zero = _mm512_setzero_si512();
  const __m512i half16 = _mm512_set1_epi64(1 << 15);
  const __m512i prnu = _mm512_set1_epi64(b.prnu_q16), dsnu = _mm512_set1_epi64(b.dsnu_q8);
  const __m512i dcnu = _mm512_set1_epi64(b.dcnu_q16);
  const __m512i low32 = _mm512_set1_epi64(0xFFFFFFFF);
  const bool patterns = b.fz != nullptr || b.pattern != nullptr;
  const bool dark_pattern = b.dz != nullptr || b.dark_gain != nullptr;  // DCNU
  CAMSIM_DCHECK(count % 4 == 0);
  for (int i = 0; i < count; i += 8) {
    const __mmask8 live = count - i >= 8 ? 0xFF : 0x0F;
    const __m512i in = _mm512_cvtepu32_epi64(_mm256_maskz_loadu_epi32(live, b.in + i));
    __m512i mu = _mm512_srli_epi64(_mm512_add_epi64(_mm512_mul_epu32(in, qe), half16), 16);
    __m512i offset = _mm512_set1_epi64(b.row_offset);
    if (patterns) {
      __m512i gain, dsnu_q8;  // Q3.16 >= 0 and Q.8 electrons
      if (b.pattern != nullptr) {
        const __m512i pair = _mm512_maskz_loadu_epi32(live == 0xFF ? 0xFFFF : 0x00FF, b.pattern + 2 * i);
        gain = _mm512_and_si512(pair, low32);
        dsnu_q8 = _mm512_srai_epi64(pair, 32);
      } else {
        const __m512i z1 = _mm512_cvtepi32_epi64(PixelWords8(b.fz, 0, i));
        const __m512i z2 = _mm512_cvtepi32_epi64(PixelWords8(b.fz, 1, i));
        gain = _mm512_srai_epi64(_mm512_add_epi64(_mm512_mul_epi32(prnu, z1), half16), 16);
        gain = _mm512_max_epi64(_mm512_add_epi64(gain, _mm512_set1_epi64(65536)), zero);
        dsnu_q8 = _mm512_srai_epi64(_mm512_add_epi64(_mm512_mul_epi32(dsnu, z2), half16), 16);
      }
      mu = _mm512_srli_epi64(_mm512_add_epi64(_mm512_mul_epu32(mu, gain), half16), 16);  // < 2^35
      offset = _mm512_add_epi64(offset, dsnu_q8);
    }
    if (b.column != nullptr)
      offset = _mm512_add_epi64(offset, _mm512_cvtepi32_epi64(_mm256_maskz_loadu_epi32(live, b.column + i)));
    __m512i dark = _mm512_set1_epi64(b.dark_q8);
    if (dark_pattern) {
      __m512i gain;  // DarkGain, Q3.16 >= 0
      if (b.dark_gain != nullptr) {
        gain = _mm512_cvtepu32_epi64(_mm256_maskz_loadu_epi32(live, b.dark_gain + i));
      } else {
        const __m512i z4 = _mm512_cvtepi32_epi64(PixelWords8(b.dz, 0, i));
        gain = _mm512_srai_epi64(_mm512_add_epi64(_mm512_mul_epi32(dcnu, z4), half16), 16);
        gain = _mm512_max_epi64(_mm512_add_epi64(gain, _mm512_set1_epi64(65536)), zero);
      }
      dark = _mm512_srli_epi64(_mm512_add_epi64(_mm512_mul_epu32(dark, gain), half16), 16);
    }
    if (b.smear != nullptr)
      dark = _mm512_add_epi64(dark, _mm512_cvtepu32_epi64(_mm256_maskz_loadu_epi32(live, b.smear + i)));
    _mm512_mask_cvtepi64_storeu_epi32(mean_q8 + i, live, _mm512_min_epu64(_mm512_add_epi64(mu, dark), low32));
    _mm512_mask_cvtepi64_storeu_epi32(offset_q8 + i, live, offset);
  }
}

// Readout in eight lanes; count a multiple of 4, so a last group of four is
// masked. AVX-512's 64-bit product, arithmetic shift, min and max replace the
// AVX2 version's constructions of them, with the same results within the
// bounds stated there: v * K (mod 2^64) is vpmullq, the biased logical shift
// is vpsraq, the high half clamped at 0 is vpsraq and vpmaxsq, and v is the
// sum in 64 bits (it fits int32, so the AVX2 version's 32-bit sum is the same).
CAMSIM_AVX512_TARGET void ReadoutAvx512(const ReadoutIn& b, int count, uint32_t* out, int64_t electrons[2]) {
  const __m512i zero = _mm512_setzero_si512();
  const __m512i small_q8 = _mm512_set1_epi64(PoissonTable::kSmallQ8);
  const __m512i full_well = _mm512_set1_epi64(static_cast<int64_t>(b.full_well_q8));
  const __m512i read = _mm512_set1_epi64(b.read_q8);
  const __m512i k_mant = _mm512_set1_epi64(b.k_mant);
  const __m512i k_round = _mm512_set1_epi64(b.k_round);
  const __m128i k_shift = _mm_cvtsi32_si128(b.k_shift);
  const __m512i black = _mm512_set1_epi64(b.black);
  const __m512i max_dn = _mm512_set1_epi64(b.max_dn);
  const __m512i half16 = _mm512_set1_epi64(1 << 15), half32 = _mm512_set1_epi64(int64_t{1} << 31);
  __m512i sum = zero;  // even lanes: even columns, odd lanes: odd
  CAMSIM_DCHECK(count <= kMaxPixels && count % 4 == 0);
  alignas(64) uint64_t small_count[kMaxPixels];  // read only for groups with a small mean
  if (b.poisson != nullptr) SmallDraws(b, count, small_count);
  for (int i = 0; i < count; i += 8) {
    const __mmask8 live = count - i >= 8 ? 0xFF : 0x0F;
    const __m512i m = _mm512_cvtepu32_epi64(_mm256_maskz_loadu_epi32(live, b.mean_q8 + i));
    __m512i n_q8 = m;
    if (b.poisson != nullptr) {
      const __m512i z = _mm512_cvtepi32_epi64(PixelWords8(b.tz, 0, i));
      const __m512i sigma = _mm512_cvtepu32_epi64(_mm256_maskz_loadu_epi32(live, b.sigma_q16 + i));
      const __m512i sigma_z = _mm512_mul_epi32(sigma, z);  // sigma < 2^28
      const __m512i skew = _mm512_sub_epi64(_mm512_mul_epi32(z, z), _mm512_set1_epi64(int64_t{1} << 32));
      const __mmask8 negative = _mm512_cmplt_epi64_mask(skew, zero);
      const __m512i skew_div6 = avx512::FloorDiv6(_mm512_abs_epi64(skew));
      const __m512i skew6 = _mm512_mask_sub_epi64(skew_div6, negative, zero, skew_div6);  // truncated
      const __m512i n_q32 = _mm512_add_epi64(_mm512_add_epi64(_mm512_slli_epi64(m, 24), sigma_z), skew6);
      __m512i drawn = _mm512_max_epi64(_mm512_srai_epi64(_mm512_add_epi64(n_q32, half32), 32), zero);
      const __mmask8 small = _mm512_cmplt_epi64_mask(m, small_q8) & live;
      if (small != 0)  // then SmallDraws wrote small_count
        drawn = _mm512_mask_loadu_epi64(drawn, small, small_count + i);
      n_q8 = _mm512_slli_epi64(drawn, 8);
    }
    n_q8 = _mm512_min_epi64(n_q8, full_well);  // <= 1e6 * 2^8 < 2^28
    sum = _mm512_mask_add_epi64(sum, live, sum, n_q8);
    const __m512i z_read = _mm512_cvtepi32_epi64(PixelWords8(b.tz, 1, i));
    const __m512i noise = _mm512_srai_epi64(_mm512_add_epi64(_mm512_mul_epi32(read, z_read), half16), 16);
    const __m512i offset = _mm512_cvtepi32_epi64(_mm256_maskz_loadu_epi32(live, b.offset_q8 + i));
    const __m512i v = _mm512_add_epi64(_mm512_add_epi64(n_q8, noise), offset);
    __m512i dn = _mm512_add_epi64(_mm512_sra_epi64(_mm512_add_epi64(_mm512_mullo_epi64(v, k_mant), k_round), k_shift),
                                  black);
    dn = _mm512_min_epi64(_mm512_max_epi64(dn, zero), max_dn);
    _mm512_mask_cvtepi64_storeu_epi32(out + i, live, dn);
  }
  alignas(64) int64_t lanes[8];
  _mm512_store_si512(lanes, sum);
  electrons[0] += lanes[0] + lanes[2] + lanes[4] + lanes[6];
  electrons[1] += lanes[1] + lanes[3] + lanes[5] + lanes[7];
}
#endif

}  // namespace sensor_lanes
#endif

// Pixels go in blocks of kBlock = 2 * RandomLanes::kLanes: one Philox4x32
// call (4 words) serves two neighbouring pixels, x using words 2 (x & 1) and
// 2 (x & 1) + 1 of the call with counter x >> 1 (emva.h, "Random words").
// The words of a whole block and their normals G(word) are drawn first
// (DrawBitsLanes, GaussianTable::SampleLanes: in SIMD lanes), then the
// pixels consume them in three passes: each pixel's mean charge; the Poisson
// draw's sigma for the whole block (PoissonTable::SigmaLanes, in lanes);
// each pixel's draw and readout (G(p) is only used above 12 e-). In a row
// without listed defects, passes 1 and 3 take the block's whole groups of
// four pixels before its first seeded defect in AVX2 lanes where the CPU
// has them (sensor_lanes, above; 37 -> 30 ms for a 1080p frame; pass 3 in
// AVX-512 lanes where it has those) and the portable loops the rest. Lanes of a
// last, partial block beyond the row's end are drawn and never used (every
// word is a pure function of its key, so that changes nothing). Even and odd
// columns have one CFA colour each (x0 is a multiple of kBlock, so column
// parity is the parity of i): qe and the electron sums are indexed by
// parity. The arithmetic is bit for bit the model in emva.h; without
// patterns, z1 = z2 = 0 makes the PRNU gain exactly 1 (mu * 65536 < 2^49
// rounds back to mu) and the DSNU term 0, so both are skipped; likewise
// without DCNU every pixel's dark charge is dark_q8_ itself (no dark-current
// draw, no product). The three switches are tested per pixel but never
// change within a row, so the branches cost nothing (specialised copies of
// the loop measured no faster).
bool SensorStage::InDead(uint32_t u) const { return u - kDefectBand < dead_width_; }
bool SensorStage::InStuck(uint32_t u) const { return u - 2 * kDefectBand < stuck_width_; }

void SensorStage::ProcessRow(const RowArgs& a) const {
  constexpr int kBlock = 2 * RandomLanes::kLanes;
  constexpr int kWords = 4 * RandomLanes::kLanes;
  using Normals = int32_t[4][RandomLanes::kLanes];  // G(word) for the words of a RandomLanes
  static_assert(kBlock % 2 == 0, "blocks start on even columns: the parity of i is column parity");
  const int channels = a.out[1] != nullptr ? 3 : 1;
  const bool defects = defects_on_;
  const bool patterns = prnu_q16_ != 0 || dsnu_q8_ != 0;
  const bool draw_patterns = patterns && pattern_ == nullptr;
  const bool dcnu = dcnu_q16_ != 0;  // off: every pixel's dark charge is dark_q8_ (no draw, no product)
  const bool draw_dcnu = dcnu && dark_gain_ == nullptr;
  CAMSIM_DCHECK(dark_gain_ == nullptr || channels == input_channels_);
  CAMSIM_DCHECK(pattern_ == nullptr || channels == input_channels_);  // the planner's SetInputChannels
  const bool shot_noise = config_.shot_noise;
  const uint32_t y = static_cast<uint32_t>(a.y);
  // round(K v + BL) = ((v * K.mant + black_round_) >> (K.shift + 8)) + floor(BL):
  // K in [1e-3, 2.6e5] (Configure's ranges) keeps K.shift + 8 in [22, 49].
  const int k_shift = k_scale_.shift + 8;
  const int64_t k_half = black_round_;  // with the black level's fraction
  const int64_t k_mant = static_cast<int64_t>(k_scale_.mant);
  for (int c = 0; c < channels; ++c) {
    const uint32_t channel = static_cast<uint32_t>(c);
    // The colours of even and odd columns of this row.
    const Colour colour[2] = {channels == 3 ? static_cast<Colour>(c) : CfaColour(geometry_.cfa, 0, a.y),
                              channels == 3 ? static_cast<Colour>(c) : CfaColour(geometry_.cfa, 1, a.y)};
    const uint32_t qe[2] = {qe_q16_[colour[0]], qe_q16_[colour[1]]};
    // Row FPN: one offset for the whole row (Q.8 electrons).
    int64_t row_offset = 0;
    if (row_fpn_q8_ != 0)
      row_offset = RoundShift(
          row_fpn_q8_ * gauss_.Sample(DrawBits(seed_, kStreamSensorRowColumn, 0, 0, y, 2 * channel + 1).v[0]), 16);
    const int32_t* column_offset = column_offset_ != nullptr ? column_offset_ + c * geometry_.width : nullptr;
    // Smear charge per column (CheckInput makes sure it is there when on).
    const uint32_t* smear = smear_ && a.input != nullptr && a.input->smear_e != nullptr
                                ? a.input->smear_e + c * geometry_.width : nullptr;
    // Listed defects of this row: none costs the one compare begin != end.
    const ListedDefect* next = listed_ != nullptr ? listed_ + listed_row_[a.y] : nullptr;
    const ListedDefect* const listed_end = listed_ != nullptr ? listed_ + listed_row_[a.y + 1] : nullptr;
    const bool row_listed = next != listed_end;
    const PatternEntry* pattern_row =
        pattern_ != nullptr ? pattern_ + (static_cast<size_t>(c) * geometry_.height + y) * geometry_.width : nullptr;
    const uint32_t* dark_gain_row =
        dark_gain_ != nullptr ? dark_gain_ + (static_cast<size_t>(c) * geometry_.height + y) * geometry_.width : nullptr;
    int64_t electrons[2] = {};
    for (int x0 = 0; x0 < a.width; x0 += kBlock) {
      const int n = a.width - x0 < kBlock ? a.width - x0 : kBlock;
      const uint32_t pair0 = static_cast<uint32_t>(x0) >> 1;  // counter of the block's first pixel pair
      RandomLanes t;  // temporal: Poisson word, read noise z
      DrawBitsLanes(seed_, kStreamSensorTemporal, a.frame, pair0, y, channel, &t);
      Normals tz;     // G of every temporal word
      gauss_.SampleLanes(&t.v[0][0], &tz[0][0], kWords);
      RandomLanes f;  // fixed pattern: PRNU z, DSNU z
      Normals fz;
      if (draw_patterns) {
        DrawBitsLanes(seed_, kStreamSensorFixedPattern, 0, pair0, y, channel, &f);
        gauss_.SampleLanes(&f.v[0][0], &fz[0][0], kWords);
      }
      RandomLanes dc;  // dark current: DCNU z (words 0 and 2; 1 and 3 unused)
      Normals dz;
      if (draw_dcnu) {
        DrawBitsLanes(seed_, kStreamSensorDarkCurrent, 0, pair0, y, channel, &dc);
        gauss_.SampleLanes(dc.v[0], dz[0], RandomLanes::kLanes);
        gauss_.SampleLanes(dc.v[2], dz[2], RandomLanes::kLanes);
      }
      RandomLanes d;  // defects: class u, hot-pixel strength u'
      if (defects) DrawBitsLanes(seed_, kStreamSensorDefects, 0, pair0, y, channel, &d);
      const uint32_t* in = a.rows[0].ch[c] + x0;
      uint32_t* out = a.out[c] + x0;
      // Pass 1, per pixel: the mean charge and the offsets. Pixel pairs are
      // unrolled over the parity, so that each copy has its words (w, w + 1)
      // and its colour's QE fixed.
      uint32_t mean_q8[kBlock];   // mu + dark charge, Q.8 electrons
      int32_t offset_q8[kBlock];  // row, column and DSNU offsets, Q.8 electrons (each < 2^21)
      bool decided[kBlock];       // stuck: out[i] is already written
      // Pixels [0, lanes) take passes 1 and 3 in AVX2 lanes, the rest the
      // portable loops (which start at an even pixel, lane lanes / 2).
      int lanes = 0;
#ifdef CAMSIM_X86_AVX2
      if (avx2_ && !force_portable_ && !row_listed) {
        lanes = n & ~3;
        // Seeded defects: the lanes stop before the group of four that holds
        // the block's first defect pixel (most blocks have none).
        for (int i = 0; defects && i < lanes; ++i)
          if (IsDefect(d.v[2 * (i & 1)][i >> 1])) lanes = i & ~3;
        static_assert(sizeof(PatternEntry) == 2 * sizeof(int32_t), "(gain, DSNU) pairs");
        const sensor_lanes::MeanIn m{in,
                                     {qe[0], qe[1]},
                                     draw_patterns ? fz : nullptr,
                                     pattern_row != nullptr ? &pattern_row[x0].gain_q16 : nullptr,
                                     prnu_q16_,
                                     dsnu_q8_,
                                     static_cast<int32_t>(row_offset),
                                     column_offset != nullptr ? column_offset + x0 : nullptr,
                                     smear != nullptr ? smear + x0 : nullptr,
                                     dark_q8_,
                                     draw_dcnu ? dz : nullptr,
                                     dark_gain_row != nullptr ? dark_gain_row + x0 : nullptr,
                                     dcnu_q16_};
#ifdef CAMSIM_X86_AVX512
        if (avx512_ && !force_avx2_) {
          sensor_lanes::MeanChargeAvx512(m, lanes, mean_q8, offset_q8);
        } else
#endif
        {
          sensor_lanes::MeanCharge(m, lanes, mean_q8, offset_q8);
        }
      }
#endif
      for (int lane = lanes / 2; 2 * lane < n; ++lane) {
#pragma GCC unroll 2
        for (int parity = 0; parity < 2; ++parity) {
          const int i = 2 * lane + parity;
          if (i >= n) break;
          const int w = parity * 2;  // this pixel's words: w and w + 1 of its lane
          mean_q8[i] = 0;
          decided[i] = true;
          const ListedDefect* hit = nullptr;
          if (row_listed && next != listed_end && next->x == static_cast<uint32_t>(x0 + i)) hit = next++;
          // Mean charge, Q24.8.
          uint64_t mu = RoundShiftU(static_cast<uint64_t>(in[i]) * qe[i & 1], 16);
          int64_t dsnu = row_offset;  // offset patterns, Q.8 electrons
          uint32_t dark = dark_q8_;
          if (dcnu) {  // < 2^28 * 7.34 < 2^31: no saturation needed
            const uint32_t gain = dark_gain_row != nullptr ? dark_gain_row[x0 + i] : DarkGain(dz[w][lane]);
            dark = static_cast<uint32_t>(RoundShiftU(uint64_t{dark_q8_} * gain, 16));
          }
          if (patterns) {
            const PatternEntry p = pattern_row != nullptr ? pattern_row[x0 + i] : Pattern(fz[w][lane], fz[w + 1][lane]);
            mu = RoundShiftU(mu * static_cast<uint64_t>(p.gain_q16), 16);
            dsnu += p.dsnu_q8;
          }
          if (defects && hit == nullptr && IsDefect(d.v[w][lane])) {
            const uint32_t u = d.v[w][lane];
            if (InHot(u)) {
              // Extra dark charge times (0.5 + u'), u' = word / 2^32: a factor in [0.5, 1.5) as Q.32.
              const uint64_t factor = (uint64_t{1} << 31) + d.v[w + 1][lane];
              dark = SatU32(dark + RoundShiftU(uint64_t{hot_q8_} * factor, 32));
            } else if (InDead(u)) {
              mu = 0;
              dark = 0;
            } else {
              out[i] = static_cast<uint32_t>(max_dn_);  // stuck
              continue;
            }
          }
          if (hit != nullptr) {  // a listed defect: wins over the seeded map
            if (hit->kind == DefectKind::kHot) {
              dark = SatU32(uint64_t{dark} + hit->value);
            } else if (hit->kind == DefectKind::kDead) {
              mu = 0;
              dark = 0;
            } else {
              out[i] = hit->value;  // stuck
              continue;
            }
          }
          if (column_offset != nullptr) dsnu += column_offset[x0 + i];
          if (smear != nullptr) dark = SatU32(uint64_t{dark} + smear[x0 + i]);
          mean_q8[i] = SatU32(mu + dark);
          offset_q8[i] = static_cast<int32_t>(dsnu);
          decided[i] = false;
        }
      }
      // Pass 2: the Poisson draw's sigma for the whole block, in lanes.
      uint32_t sigma_q16[kBlock];
      if (shot_noise) PoissonTable::SigmaLanes(mean_q8, sigma_q16, n);
      // Pass 3, per pixel: collected charge, Q.8, clipped at the full well,
      // then readout. One word drives the Poisson draw: as u below 12 e-
      // (inverse transform), as z = Gaussian(u) above (the normal approximation).
#ifdef CAMSIM_X86_AVX2
      if (lanes > 0) {
        const sensor_lanes::ReadoutIn r{mean_q8,      offset_q8,     sigma_q16,  t.v,          tz,
                                        shot_noise ? &poisson_ : nullptr,      full_well_q8_, read_q8_,
                                        k_scale_.mant, k_shift,      black_round_, black_, max_dn_};
#ifdef CAMSIM_X86_AVX512
        if (avx512_ && !force_avx2_) {
          sensor_lanes::ReadoutAvx512(r, lanes, out, electrons);
        } else
#endif
        {
          sensor_lanes::Readout(r, lanes, out, electrons);
        }
      }
#endif
      for (int lane = lanes / 2; 2 * lane < n; ++lane) {
#pragma GCC unroll 2
        for (int parity = 0; parity < 2; ++parity) {
          const int i = 2 * lane + parity;
          if (i >= n) break;
          if (decided[i]) continue;
          const int w = parity * 2;
          const uint32_t m = mean_q8[i];
          uint64_t n_q8 =
              shot_noise ? static_cast<uint64_t>(poisson_.Sample(m, t.v[w][lane], tz[w][lane], sigma_q16[i])) << 8 : m;
          if (n_q8 > full_well_q8_) n_q8 = full_well_q8_;
          electrons[i & 1] += static_cast<int64_t>(n_q8);

          // Readout: offset patterns and read noise (electrons, Q.8), then K and black level.
          const int64_t read = RoundShift(read_q8_ * tz[w + 1][lane], 16);
          const int64_t v = static_cast<int64_t>(n_q8) + offset_q8[i] + read;
          const int64_t dn = ((v * k_mant + k_half) >> k_shift) + black_;
          out[i] = static_cast<uint32_t>(Clamp64(dn, 0, max_dn_));
        }
      }
    }
    if (a.stats != nullptr) {
      a.stats->aux_sum[colour[0]] += electrons[0];
      a.stats->aux_sum[colour[1]] += electrons[1];
    }
  }
}

}  // namespace camsim
