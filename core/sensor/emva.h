// Sensor: the EMVA 1288 linear camera model (replaces the paper's eq. 17).
//
// Per pixel with CFA colour c, photons p (mean over the exposure):
//   mu_e  = p * QE[c] * (1 + prnu * z1) + dark_e * max(0, 1 + dcnu * z4)
//   dark_e = dark_current * t * 2^((T - T_ref) / T_double)    mean dark charge per exposure
//   n     = min(Poisson(mu_e), full_well)               shot noise, saturation
//   v     = n + dsnu * z2 + dark_noise * z3             offset pattern, read noise
//   DN    = clamp(round(K * v + black_level), 0, 2^bits - 1)   one rounding: the black level may be fractional
// z1, z2, z4: fixed-pattern normals keyed by (seed, x, y) only, the same every
// frame; z3 and the Poisson draw: keyed by (seed, frame, x, y).
// DCNU (dark current non-uniformity, SensorConfig::dcnu_percent): each
// pixel's dark current is the mean times its own factor max(0, 1 + dcnu z4),
// so its dark charge's spatial spread grows with the exposure time and the
// temperature as the mean does (EMVA 1288's dark signal non-uniformity at
// longer exposures; dsnu is the part that does not grow). The clamp at 0
// (z4 < -1 / dcnu: 16 % of the pixels at 100 %, none up to 15.7 %, as |z4|
// <= 6.34) lifts the mean over the pixels to dark_e (Phi(1 / dcnu) + dcnu
// phi(1 / dcnu)): 1.00003 dark_e at 30 %, 1.083 dark_e at 100 %
// (ReferenceDarkChargeMean), and trims the spread below dark_e dcnu.
//
// Random words: one Philox4x32 call (4 words) serves the pixel pair
// (2j, 2j + 1) of a row: pixel x takes words 2 (x & 1) and 2 (x & 1) + 1 of
// DrawBits(seed, stream, frame, x >> 1, y, channel), per stream:
//   temporal (frame):   Poisson word p, read noise z3 = G(next word);
//                       p is u of the exact inverse transform below 12 e-,
//                       and gives the normal approximation's z = G(p) above
//                       (one of the two is used, never both);
//   fixed pattern (0):  z1 = G(word), z2 = G(next word), drawn only when
//                       PRNU or DSNU is on (per frame, or once at Init into
//                       a table with SensorConfig::fixed_pattern_table);
//   defects (0):        class u, strength u' (below), drawn only when a
//                       defect fraction is on;
//   dark current (0):   z4 = G(word 2 (x & 1)), drawn only when DCNU is on
//                       (per frame, or once at Init into a table with
//                       fixed_pattern_table); word 2 (x & 1) + 1 is unused.
// G = GaussianTable::Sample. Sharing a call between two pixels halves the
// Philox work (the sensor's largest cost: docs/performance.md). K is the
// system gain at 0 dB times 10^(gain_db / 20) (the analog gain, which is eq.
// 7's "ISO" term). Quantisation noise (1/12 DN^2) comes from the rounding, so
// the temporal variance is sigma_y^2 = K^2 (sigma_d^2 + mu_e) + 1/12.
//
// Artefacts beyond the EMVA model (all off by default):
//   row / column FPN: offsets z_row(y) * row_fpn_e and z_col(x) * column_fpn_e
//     added to v like the DSNU (fixed: keyed by (seed, y, channel) and (seed,
//     x, channel) only; the column offsets are a table built at Init, one
//     int32 per channel and column).
//   defect pixels (a seeded map): the defect draw's first word u picks
//     hot   (u < h):           extra dark charge (on top of the pixel's own,
//                              DCNU included) hot_pixel_dark_e_per_s * t
//                              * 2^((T - T_ref) / T_double) * (0.5 + u'),
//                              u' uniform in [0, 1) from its second word (a
//                              spread of hot-pixel strengths), with shot noise;
//     dead  (B <= u < B + d):  no photo or dark charge (offsets and read noise remain);
//     stuck (2B <= u < 2B + s): output stuck at 2^bits - 1.
//   h, d, s = the configured fractions times 2^32 (rounded down); B = 2^26
//   (1/64 > the largest fraction, 0.01): each class has its own band of u,
//   so changing one fraction leaves the other classes' maps as they were,
//   and raising it keeps its earlier pixels (and adds some).
//   listed defects (SensorConfig::defects, from sensor.defects_file): at a
//     listed pixel the seeded class is ignored (the list wins) and
//     hot:   extra dark charge value * t * 2^((T - T_ref) / T_double) (value
//            in e-/s; default hot_pixel_dark_e_per_s), no strength spread,
//            with shot noise;
//     dead:  no photo or dark charge (offsets and read noise remain);
//     stuck: output stuck at value DN (default 2^bits - 1).
//     A 3-channel sensor gets the defect in every channel. The list is
//     copied at Init into the workspace with a row index (height + 1
//     offsets): a row without listed defects costs one pointer compare.
//   smear: FrameInput::smear_e[c * width + x] (Q24.8 electrons, from the
//     per-frame pre-pass ComputeSmear, core/sensor/smear.h) added to the mean
//     charge before shot noise.
//
// Formats: in  Photons Q24.8, 1 channel (mosaic / mono) or 3 (one sensor per colour)
//          out Digital DN integer, 1 or 3 channels
//          QE, PRNU gain: Q1.16 / Q3.16 (1.0 = 65536; the gain 1 + prnu z reaches
//          1 + 0.5 * 6.34 at 50 % PRNU; 64-bit products, rounded ties up)
//          DCNU gain 1 + dcnu z4: Q3.16 (dcnu <= 100 % as Q.16 <= 65536, times
//          z4 Q15.16, rounded ties up, clamped at 0; < 7.34 * 65536 < 2^19),
//          the pixel's dark charge RoundShiftU(dark_e Q24.8 * gain, 16)
//          (< 2^28 * 7.34 < 2^31, 64-bit product); with dcnu 0 the stage
//          uses dark_e as it is (no draw, no product)
//          mean and charge: Q24.8 electrons (uint32, saturating; full well <= 1e6 e-)
//          v: int64 Q.8; K as UScale, v * K in int64 (|v| < 2^29, mantissa < 2^32)
//          normals: Q15.16 from GaussianTable; Poisson: PoissonTable (exact
//          inverse transform below 12 e-, skew-corrected normal above).
#pragma once

#include "core/base/random.h"
#include "core/pipeline/stage.h"

namespace camsim {

enum class DefectKind : uint8_t { kHot, kDead, kStuck };

// One listed defect pixel. Lists must be sorted by (y, x) without duplicates
// (the host's defects-file reader sorts and checks them).
struct DefectPixel {
  int32_t x = 0, y = 0;
  DefectKind kind = DefectKind::kHot;
  double value = -1.0;  // hot: e-/s, stuck: DN; < 0: the default (see above); dead: unused
};

struct SensorConfig {
  // Defaults: a typical 1/2.9" global-shutter CMOS industrial camera (order of
  // magnitude of published EMVA 1288 sheets), 12-bit output.
  double quantum_efficiency[3] = {0.50, 0.65, 0.55};  // R, G, B (mono uses G), 0..1
  double full_well_e = 10500.0;         // saturation capacity, electrons
  double system_gain_dn_per_e = 0.375;  // K at 0 dB, DN per electron
  double gain_db = 0.0;                 // analog gain, dB (0..48)
  double dark_noise_e = 2.4;            // sigma_d, temporal dark noise, electrons rms
  double dark_current_e_per_s = 5.0;    // mean dark current at the reference temperature
  double temperature_c = 25.0;          // sensor temperature
  double dark_current_ref_c = 25.0;     // temperature the dark current is given at
  double dark_current_doubling_c = 7.0; // dark current doubles every this many kelvin
  double dsnu_e = 1.0;                  // dark signal non-uniformity, electrons rms
  double prnu_percent = 0.5;            // photo response non-uniformity, % rms
  double dcnu_percent = 0.0;            // dark current non-uniformity, % rms of the mean dark current (0 .. 100)
  double black_level_dn = 64.0;         // offset added to the output, DN
  bool shot_noise = true;               // Poisson photon/dark-current noise
  // Build the fixed pattern (PRNU gain, DSNU offset) once at Init, one entry
  // of 8 bytes per pixel and channel in the workspace's tables (16.6 MB for a
  // 1920x1080 Bayer sensor), instead of drawing it every frame; with DCNU on,
  // also its dark-current gain, 4 more bytes per pixel and channel. Same bytes
  // either way; only speed and memory differ.
  bool fixed_pattern_table = false;
  // Artefacts (off by default).
  double row_fpn_e = 0.0;               // row offset pattern, electrons rms
  double column_fpn_e = 0.0;            // column offset pattern, electrons rms
  double hot_pixel_fraction = 0.0;      // share of hot pixels, 0 .. 0.01
  double dead_pixel_fraction = 0.0;     // share of dead pixels, 0 .. 0.01
  double stuck_pixel_fraction = 0.0;    // share of pixels stuck at full scale, 0 .. 0.01
  double hot_pixel_dark_e_per_s = 2000.0;  // median hot-pixel dark current at the reference temperature
  const DefectPixel* defects = nullptr;    // listed defects (caller memory until Init), sorted by (y, x)
  int defect_count = 0;                    // 0 .. kMaxListedDefects
  // CCD smear (core/sensor/smear.h): off when the row transfer time is 0.
  double smear_row_transfer_us = 0.0;   // time a charge packet spends under each row during transfer
  double smear_leak = 1.0;              // share of that light reaching the register (1: frame transfer)
};

inline constexpr int kMaxListedDefects = 1 << 20;

// Randomness streams (the "channel" part of the counter key).
inline constexpr uint32_t kStreamSensorTemporal = 1;
inline constexpr uint32_t kStreamSensorFixedPattern = 2;
inline constexpr uint32_t kStreamSensorRowColumn = 3;  // row FPN at (0, y), column FPN at (x, 0)
inline constexpr uint32_t kStreamSensorDefects = 4;    // defect class and hot-pixel strength
inline constexpr uint32_t kStreamSensorDarkCurrent = 5;  // DCNU: the pixel's dark-current factor

class SensorStage final : public Stage {
 public:
  Status Configure(const SensorConfig& config, const SensorGeometry& geometry, double exposure_time_us,
                   uint64_t seed);
  const char* name() const override { return "sensor"; }
  Result<LineFormat> Plan(LineFormat in) const override;
  void CountTables(WorkspaceCounter& counter) const override;
  Status Init(Arena& tables) override;
  // Copies the noise's constant tables, and the fixed pattern and column
  // offsets when their inputs (seed, size, sigmas) are previous's.
  Status InitFrom(Arena& tables, const Stage& previous, int* copied) override;
  void ProcessRow(const RowArgs& args) const override;
  // Channels of the sensor's input lines (1: mosaic or mono, 3: one sensor
  // per colour): the pipeline's planner sets it; it sizes the fixed-pattern table.
  void SetInputChannels(int channels) { input_channels_ = channels; }

  // Derived values (for reports and tests).
  double system_gain() const { return k_; }            // K with analog gain, DN/e-
  double dark_electrons() const { return dark_e_; }    // mean dark charge per exposure
  int max_dn() const { return max_dn_; }
  // Tests only: run every pixel through the portable per-pixel passes even
  // where the AVX2 lanes would take them (the same bytes either way).
  void ForcePortablePathForTest(bool force) { force_portable_ = force; }
  // Tests only: take the AVX2 lanes even where the CPU has AVX-512 (no
  // effect without AVX-512, or with ForcePortablePathForTest).
  void ForceAvx2PathForTest(bool force) { force_avx2_ = force; }

 private:
  // Init; copies from `previous` (an initialised sensor stage) what it can.
  Status Build(Arena& tables, const SensorStage* previous, int* copied);
  int ColumnTableEntries() const { return kMaxChannels * geometry_.width; }
  SensorConfig config_;
  SensorGeometry geometry_;
  uint64_t seed_ = 0;
  double k_ = 0.0;
  double dark_e_ = 0.0;
  uint32_t qe_q16_[3] = {};
  int64_t prnu_q16_ = 0;     // PRNU sigma, Q.16 of gain
  int64_t dcnu_q16_ = 0;     // DCNU sigma, Q.16 of the dark current (<= 65536)
  int64_t dsnu_q8_ = 0;      // DSNU sigma, Q.8 electrons
  int64_t read_q8_ = 0;      // dark noise sigma, Q.8 electrons
  int64_t row_fpn_q8_ = 0;   // row FPN sigma, Q.8 electrons
  int64_t col_fpn_q8_ = 0;   // column FPN sigma, Q.8 electrons
  // Defect bands on u (emva.h, top): hot [0, hot_width_), dead [B, B +
  // dead_width_), stuck [2B, 2B + stuck_width_); the widths are the
  // fractions times 2^32.
  uint32_t hot_width_ = 0, dead_width_ = 0, stuck_width_ = 0;
  bool defects_on_ = false;
  // Whether u falls in a band: one unsigned compare each (u - start wraps
  // above the band for u below its start).
  bool InHot(uint32_t u) const { return u < hot_width_; }
  bool InDead(uint32_t u) const;
  bool InStuck(uint32_t u) const;
  bool IsDefect(uint32_t u) const { return InHot(u) || InDead(u) || InStuck(u); }
  uint32_t hot_q8_ = 0;      // median hot-pixel extra dark charge per exposure, Q24.8
  struct ListedDefect {
    uint32_t x;
    DefectKind kind;
    uint32_t value;  // hot: extra dark charge Q24.8; stuck: DN
  };
  const ListedDefect* listed_ = nullptr;      // defect_count entries, sorted by (y, x) (null when none)
  const uint32_t* listed_row_ = nullptr;      // height + 1 offsets into listed_: row y is [row[y], row[y + 1])
  double exposure_time_us_ = 0.0;
  const int32_t* column_offset_ = nullptr;  // column FPN, Q.8 electrons (width entries; null when off)
  // Fixed-pattern table: per channel, row and column the PRNU gain (Q3.16,
  // >= 0) and the DSNU offset (Q.8 electrons), exactly as drawn per frame.
  struct PatternEntry {
    int32_t gain_q16;
    int32_t dsnu_q8;
  };
  bool UsesPatternTable() const { return config_.fixed_pattern_table && (prnu_q16_ != 0 || dsnu_q8_ != 0); }
  size_t PatternEntries() const {
    return static_cast<size_t>(input_channels_) * geometry_.width * static_cast<size_t>(geometry_.height);
  }
  PatternEntry Pattern(int32_t z_prnu, int32_t z_dsnu) const;  // from the two normals
  const PatternEntry* pattern_ = nullptr;  // PatternEntries() entries, null when not used
  // DCNU: the dark-current gain max(0, 1 + dcnu z4), Q3.16, from the normal
  // z4; with fixed_pattern_table a table of it in the pattern's order
  // (PatternEntries() entries, only when DCNU is on; null otherwise).
  bool UsesDarkGainTable() const { return config_.fixed_pattern_table && dcnu_q16_ != 0; }
  uint32_t DarkGain(int32_t z) const;
  const uint32_t* dark_gain_ = nullptr;
  int input_channels_ = 1;
  uint32_t dark_q8_ = 0;     // mean dark charge, Q24.8
  uint64_t full_well_q8_ = 0;
  UScale k_scale_;           // K
  int64_t black_ = 0;        // floor(black level), whole DN
  int64_t black_round_ = 0;  // 2^(k_shift - 1) + its fraction * 2^k_shift: round(K v + black level) in one step
  int max_dn_ = 0;
  bool smear_ = false;
  GaussianTable gauss_;
  PoissonTable poisson_;
  bool avx2_ = false;           // passes 1 and 3 in AVX2 lanes where a row allows (chosen at Init)
  bool avx512_ = false;         // pass 3 in AVX-512 lanes instead (chosen at Init)
  bool force_portable_ = false;  // tests only
  bool force_avx2_ = false;      // tests only
};

// The DN of a full well without noise, min(round(K W + black level), 2^bits -
// 1), computed with the stage's integers (K's 32-bit mantissa, W in Q24.8), so
// it is the level a full pixel reads. The ISP's white balance clips
// highlights there (core/isp/white_balance.h).
double SensorSaturationDn(const SensorConfig& config, const SensorGeometry& g);

// Double reference: the mean DN for a mean photon count (no noise, no
// patterns; the dark charge is its mean over the pixels,
// ReferenceDarkChargeMean).
double ReferenceSensorMeanDn(const SensorConfig& config, const SensorGeometry& g, double exposure_time_us,
                             Colour colour, double photons);

// Double reference for the dark charge per exposure of the pixels that are
// not defects, electrons, over the DCNU pattern (z4 standard normal, the
// factor max(0, 1 + s z4), s = dcnu_percent / 100, a = 1 / s):
//   mean: dark_e (Phi(a) + s phi(a))   (dark_e exactly when s = 0)
//   rms:  dark_e sqrt((1 + s^2) Phi(a) + s phi(a) - (Phi(a) + s phi(a))^2)
//         (dark_e s to 3e-5 relative up to s = 0.25), the spatial standard
//         deviation DCNU adds to the dark signal (in quadrature with the DSNU).
double ReferenceDarkChargeMean(const SensorConfig& config, double exposure_time_us);
double ReferenceDarkChargeRms(const SensorConfig& config, double exposure_time_us);

}  // namespace camsim
