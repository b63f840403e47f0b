// EMVA 1288 measurement of a recorded dataset: a real camera's flat-field
// frames as a test lab takes them, analysed with the same photon-transfer code
// as `camsim emva` uses on the emulated sensor (emva_measure.h). This is how
// a preset's parameters can come first-hand from a real camera.
//
// Input: an EMVA 1288 descriptor file (the format of the EMVA 1288 reference
// implementation and its public reference datasets):
//   # comment
//   v 3.0                       version
//   n BITS WIDTH HEIGHT         once, before any images
//   b EXPOSURE PHOTONS          a bright series: mean photons per pixel mu_p
//   d EXPOSURE                  a dark series
//   i PATH                      the series' images, 2 (a temporal pair) or more
//                               (a spatial stack); PATH relative to the
//                               descriptor, '\' or '/' separators
// Images: PNG, gray, 8 or 16 bits, holding the raw values (0 .. 2^BITS - 1).
// Every bright pair needs a dark pair at the same exposure time; DSNU and
// PRNU need one dark and one bright stack (else they are not reported); the
// dark current and its non-uniformity (DCNU) need dark pairs at 2 or more
// exposure times (else they are not measurable, and the report says why). A
// dark pair with more than 0.5 % of its pixels at 0 is refused (EMVA 1288:
// the offset was too low, the dark signal is clipped).
// Errors name the file and line (descriptor) or the image.
#pragma once

#include <string>
#include <vector>

#include "host_tools/emva_measure.h"

namespace camsim::host {

// Dark current non-uniformity from the dark pairs: each pair's spatial
// variance (of the pair's average, less its temporal variance / 2, as EMVA
// 1288 takes the DSNU) is fitted as a + b t^2 over the exposure times t: the
// DSNU stays, the dark current's spread adds (K sigma_dc t)^2. The variance
// against t^2 is linear; the spread against t is sqrt(a + b t^2), a line only
// without DSNU.
struct DcnuPoint {
  double exposure = 0;         // as written
  double spatial_var_dn2 = 0;  // temporal share removed
  double temporal_var_dn2 = 0;
};
struct DcnuEstimate {
  bool measured = false;
  std::string not_measurable;       // why, when not measured
  double intercept_dn2 = 0, slope_dn2 = 0;  // spatial variance = intercept + slope t^2
  double spread_e = 0;       // the dark current's spatial rms, e- per unit of exposure as written
  double ratio_percent = 0;  // 100 spread_e / dark_current_e
  double dcnu_percent = 0;   // the sensor.dcnu_percent with that ratio (DcnuPercentForSpreadRatio)
  std::vector<DcnuPoint> points;  // by exposure
};

struct EmvaDatasetReport {
  int bits = 0, width = 0, height = 0;
  int levels = 0;                 // bright pairs
  double dark_mean_dn = 0;        // mu_y.dark at the shortest exposure (the black level)
  double exposure_min = 0, exposure_max = 0;  // as written in the descriptor
  // Dark signal growth, electrons per unit of the descriptor's exposure time
  // (least squares over the dark pairs; 0 with fewer than 2 exposure times).
  double dark_current_e = 0;
  DcnuEstimate dcnu;
  TransferFit fit;
  bool has_nonuniformity = false;  // a dark and a bright stack were present
  double dsnu_e = 0, prnu_percent = 0;
  double stack_photons = 0;        // mu_p of the bright stack
};

bool MeasureEmvaDataset(const std::string& descriptor, EmvaDatasetReport* report, std::string* error);

// The measured figures as text, with a [sensor] block a preset can start from.
std::string FormatEmvaDatasetReport(const std::string& descriptor, const EmvaDatasetReport& report);

}  // namespace camsim::host
