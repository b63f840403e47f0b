// An EMVA 1288 (Release 4, linear) photon-transfer measurement of the emulated
// sensor: the camera is treated as a black box that is fed flat fields of a
// known photon count and whose raw DN output is analysed exactly as a test lab
// would analyse a real camera's. It shares no code with the sensor model; it
// only knows photons per pixel (the exposure stage's double reference).
//
// Procedure (per colour channel; the sensor runs without a CFA, one sensor per
// colour, so R, G and B are three independent planes; K, noise, saturation,
// DSNU and PRNU are reported for G, which mono sensors use):
//   1. Dark pair: mu_y.dark and sigma^2_y.dark (variance of the difference / 2);
//      refused when more than 0.5 % of its pixels read 0 (the offset is too low).
//   2. Find a photon level past saturation by doubling until the signal stops
//      doubling (refused past the exposure stage's 16.7 M photons); bisect
//      for the photons at half that clipped signal; then `levels` equally
//      spaced levels from 0 to 2.4 times it (1.2 times the clip, 1.2-1.35
//      times saturation), a frame pair each: mean mu_y and temporal variance
//      sigma^2_y.
//   3. Saturation: the level of maximum temporal variance (EMVA 1288 4.0).
//   4. K: least-squares slope through the origin of sigma^2_y - sigma^2_y.dark
//      against mu_y - mu_y.dark, over points below 70 % of the saturation
//      signal; responsivity R: the same of mu_y - mu_y.dark against mu_p;
//      QE = R / K.
//   5. Dark noise sigma_d = sqrt(sigma^2_y.dark - 1/12) / K (quantisation
//      noise removed), with sigma^2_y.dark at least 0.24 DN^2: below that the
//      figure is only an upper limit (EMVA 1288 4.0), and says so; saturation
//      capacity mu_e.sat = QE * mu_p.sat. Each colour's QE is fitted over its
//      own levels below 70 % of its own saturation.
//   6. DSNU, PRNU: `average_frames` frames averaged, dark and at 50 % of the
//      saturation photon count; spatial variance of the average minus the
//      temporal variance / L; DSNU = s_y.dark / K (electrons),
//      PRNU = sqrt(s^2_y.50 - s^2_y.dark) / (mu_y.50 - mu_y.dark).
#pragma once

#include <string>
#include <vector>

#include "host_tools/config.h"

namespace camsim::host {

// EMVA 1288: the offset must keep the dark signal off 0; at most this share
// of the dark pixels may read 0. A dark signal clipped at 0 shows too little
// noise and DSNU, so both measurements refuse darker data.
inline constexpr double kEmvaMaxDarkZeroShare = 0.005;

struct EmvaOptions {
  int size = 256;           // frame side, pixels (256 x 256 = 65536 per estimate)
  int levels = 100;         // photon levels between dark and past saturation
  int average_frames = 16;  // L, frames averaged for DSNU and PRNU
};

// The EMVA 1288 quantities, measured or as configured.
struct EmvaFigures {
  double system_gain = 0;      // K, DN per electron (with the analog gain)
  double qe[3] = {};           // R, G, B quantum efficiency, 0..1
  double dark_noise_e = 0;     // temporal dark noise, electrons
  bool dark_noise_upper_limit = false;  // measured only: the dark variance was below 0.24 DN^2
  double saturation_e = 0;     // saturation capacity (EMVA: at the variance maximum), electrons
  double dynamic_range_bits = 0;  // DR = mu_p.sat / mu_p.min (below), log2
  double snr_max = 0;             // sqrt(saturation_e)
  double full_well_e = 0;      // configured only: the clip (well, or the ADC if it ends first)
  double dsnu_e = 0;           // dark signal non-uniformity, electrons
  double prnu_percent = 0;     // photo response non-uniformity, %
};

struct EmvaReport {
  EmvaFigures measured;
  EmvaFigures configured;  // what the configuration says the measurement should give
  double saturation_photons = 0;  // mu_p.sat (G)
  double top_photons = 0;         // the highest level's mu_p
  int fit_points = 0;             // levels used for K and R
};

// What an EMVA 1288 measurement of this configuration should give: the
// sensor's parameters with the effects the standard folds in (dark-current
// shot noise in the temporal dark noise; the ADC clipping before the well is
// full; dark charge taking part of the well).
EmvaFigures ConfiguredEmva(const RunConfig& config);

// The sensor.full_well_e that gives this configuration an EMVA saturation
// capacity (as ConfiguredEmva computes it) of saturation_e: how a preset turns
// a datasheet's saturation capacity into the well the sensor clips at. False
// (and *error says why) when that well would reach the ADC's clip.
// Deterministic: the same well on every platform.
bool FullWellForEmvaSaturation(const RunConfig& config, double saturation_e, double* full_well_e,
                               std::string* error);

// Measures the configuration's sensor (its [sensor] and [exposure] settings;
// frame size, CFA and every other stage are replaced by the set-up above).
// Range errors name the key's origin (file:line or --set).
bool MeasureEmva(const RunConfig& config, const Origins& origins, const EmvaOptions& options, EmvaReport* report,
                 std::string* error);

// The analysis shared by the emulated measurement and recorded datasets
// (camsim emva --dataset), for one channel.
//
// One photon level: the mean and temporal variance of its frame pair, with
// the dark pair at the same exposure time.
struct TransferLevel {
  double photons = 0;  // mu_p, mean photons per pixel
  double mean = 0, var = 0;
  double dark_mean = 0, dark_var = 0;
};
// An L-frame stack: mean, spatial variance of the averaged image, and the
// temporal variance (per pixel over the frames, averaged over pixels).
struct FrameStack {
  double mean = 0, spatial_var = 0, temporal_var = 0;
  int frames = 0;
};
struct TransferFit {
  double system_gain = 0;    // K, DN/e-
  double responsivity = 0;   // R, DN/photon
  double dark_noise_e = 0;   // from dark_var
  bool dark_noise_upper_limit = false;  // dark_var below 0.24 DN^2: dark_noise_e is an upper limit
  double saturation_e = 0;   // QE * mu_p.sat = R / K * mu_p.sat
  double saturation_photons = 0;
  double dynamic_range_bits = 0;  // log2 of DR = mu_p.sat / mu_p.min (EmvaDynamicRangeBits)
  double snr_max = 0;             // sqrt(saturation_e)
  int fit_points = 0;
};
// Steps 3-5 of the procedure above on levels in ascending photons; dark_var
// is the temporal dark variance for sigma_d. Fails (naming why) with fewer
// than 5 levels below 70 % of saturation.
bool FitPhotonTransfer(const std::vector<TransferLevel>& levels, double dark_var, TransferFit* fit,
                       std::string* error);
// EMVA 1288's dynamic range in bits: log2(mu_p.sat / mu_p.min) with the
// absolute sensitivity threshold mu_p.min = (sigma_y.dark / K + 1/2) / QE, so
// log2(mu_e.sat / (sigma_y.dark / K + 1/2)). sigma^2_y.dark (DN^2) includes
// the quantisation noise, and is taken as at least 0.24 DN^2 as for sigma_d
// (the DR is then a lower limit).
double EmvaDynamicRangeBits(double saturation_e, double dark_var_dn2, double system_gain);
// Step 6: DSNU (e-) and PRNU (%) from a dark and a bright stack. Fails
// (naming why) when the bright stack is not brighter than the dark one.
bool NonUniformity(const FrameStack& dark, const FrameStack& bright, double system_gain, double* dsnu_e,
                   double* prnu_percent, std::string* error);

// DCNU in the clipped-normal model (core/sensor/emva.h): the
// sensor.dcnu_percent whose pixels' dark currents have this rms over their
// mean (%); the same below ~30 %, above it the clamp at 0 lifts the mean and
// trims the spread (80 % reads as 70 %). 100 when the ratio is at or beyond
// 100 %'s (80 %), the most the model has.
double DcnuPercentForSpreadRatio(double ratio_percent);

// The measured-versus-configured table as text.
std::string FormatEmvaReport(const std::string& title, const EmvaReport& report);

}  // namespace camsim::host
