#include "host_tools/presets.h"

#include <cstdio>
#include <cstdlib>
#include <string>

#include "host_tools/emva_measure.h"

namespace camsim::host {
namespace {

// Each preset sets only [sensor] keys (and the CFA). The frame size and pixel
// pitch are left to the scene (the bundled scenes assume a 36 mm wide sensor);
// the native resolution is given as a comment. Values marked "assumption" are
// not in the cited source: they are typical of the sensor class and stated so
// that `camsim emva` can measure them back like the cited ones.
//
// A source's EMVA 1288 saturation capacity is not the well: EMVA takes the
// mean at the peak of the temporal variance, about 3 sigma below the clip
// (emva_measure.cc). Such a preset cites the capacity (saturation_e) and
// writes kWell for full_well_e; Presets() puts in the well whose configured
// EMVA saturation (FullWellForEmvaSaturation) is the cited capacity, rounded
// to 1 e- (`camsim config --preset NAME` prints it).
constexpr char kWell[] = "@WELL@";

const Preset kSources[] = {
    {"basler_emva_ref001_vga_ccd",
     "A Basler VGA CCD camera, 12-bit, mono: measured here from its public EMVA 1288 dataset",
     R"(# A Basler 640 x 480 interline CCD camera, monochrome, 12-bit output: the
# camera recorded in the EMVA 1288 reference dataset 001 (Basler AG, Marco
# Grimm, 2011, CC BY-SA 3.0; EMVA 1288 Release 3.0 measurement: 50 flat-field
# pairs, dark pairs at every exposure, 50-frame dark and bright stacks),
#   https://github.com/EMVA1288/datasets  EMVA1288_ReferenceSet_001_CCD_12Bit
# Source: first-hand, the dataset's raw frames measured with
#   camsim emva --dataset EMVA1288_ReferenceSet_001_CCD_12Bit/EMVA1288_Data.txt
# which gives K 0.2801 DN/e-, QE 45.25 %, temporal dark noise 10.93 e-,
# saturation capacity 14 010 e- (QE x 30 957 photons), dark level 14.7 DN,
# DSNU 0.55 e-, PRNU 0.43 %, dark signal 2.85e-8 e- per unit of exposure.
# The EMVA 1288 reference implementation's published results for the same
# dataset: K 0.2808, QE 45.14 %, sigma_d 10.90 e-, 13 973 e- at 30 957 photons.
# The reference implementation's DSNU 0.5518 e-, PRNU 0.4327 % and dark current
# 28.41 e-/s (doc/datasets/datasets_results.rst of github.com/EMVA1288/emva1288)
# agree with these.
# A VGA CCD like the seed paper's camera; a 7.4 um pixel is typical of the class.
[sensor]
cfa = "Mono"
adc_bits = 12
quantum_efficiency = [0.4525, 0.4525, 0.4525]  # source (the wavelength is not in the dataset)
dark_noise_e = 10.93                           # source
full_well_e = @WELL@                            # derived from the source's 14 010 e- saturation capacity
system_gain_dn_per_e = 0.2801                  # source
black_level_dn = 14.7                          # source (dark level at the shortest exposure)
dsnu_e = 0.55                                  # source
prnu_percent = 0.43                            # source
dark_current_e_per_s = 28.5                    # source: the exposure unit is ns (2.85e-8 e-/ns; the reference implementation reads 28.41 e-/s)
)",
     14010.0},
    {"basler_pia2400_17gm", "Basler piA2400-17gm: Sony ICX625 interline CCD, 5 MP, mono",
     R"(# Basler piA2400-17gm: Sony ICX625 interline-transfer CCD, 2448 x 2050 px,
# 3.45 um pixels, global shutter (CCD), monochrome, 12-bit output.
# Source: Basler's EMVA 1288 data for the piA2400-17gm, as tabulated next to
# Point Grey's GS3-PGE-50S5M (same sensor) at
#   https://mengineer.hatenablog.com/entry/2016/05/02/212822
# (Basler column: QE 47 % at 545 nm, temporal dark noise 13 e-,
# saturation capacity 7000 e-; Point Grey measured 57 % / 8.28 e- / 5903 e-).
[sensor]
cfa = "Mono"
adc_bits = 12
quantum_efficiency = [0.47, 0.47, 0.47]  # source (mono: G is used)
dark_noise_e = 13.0                      # source
full_well_e = @WELL@                       # derived from the source's 7000 e- saturation capacity
system_gain_dn_per_e = 0.55              # assumption: saturation at ~3900 of 4095 DN
black_level_dn = 64.0                    # assumption
dsnu_e = 3.0                             # assumption (CCD class)
prnu_percent = 0.6                       # assumption (CCD class)
dark_current_e_per_s = 10.0              # assumption
)",
     7000.0},
    {"rpi_hq_imx477", "Raspberry Pi HQ Camera: Sony IMX477 rolling-shutter CMOS, 12 MP, Bayer",
     R"(# Raspberry Pi High Quality Camera: Sony IMX477, 4056 x 3040 px, 1.55 um
# pixels, rolling shutter, BayerBG, 12-bit raw.
# Source: photon-transfer measurement (the EMVA 1288 method, not a vendor
# sheet), "Pi HQ Cam Sensor Performance" on strollswithmydog.com,
#   https://www.strollswithmydog.com/pi-hq-cam-sensor-performance/
# summary table at analog gain 1: black level 256 DN, white level 4095 DN,
# read noise 3 e-, clipping (full well) 8180 e-, system gain 0.47 DN/e-.
# The source's full well is where the raw data clips: (4095 - 256) / 0.47 =
# 8168 e-, so here too the ADC clips just before the well is full. The source
# gives this clip, not an EMVA saturation capacity, so the well is its value
# (camsim emva reports the saturation ~3 sigma below it).
# CFA phase: BGGR per https://github.com/aaronwmorris/indi-allsky/wiki/Camera-Information
[sensor]
cfa = "BayerBG"
adc_bits = 12
quantum_efficiency = [0.45, 0.60, 0.50]  # assumption (BSI colour CMOS class)
dark_noise_e = 3.0                       # source
full_well_e = 8180.0                     # source
system_gain_dn_per_e = 0.47              # source
black_level_dn = 256.0                   # source
dsnu_e = 1.0                             # assumption
prnu_percent = 0.8                       # assumption
dark_current_e_per_s = 5.0               # assumption
)",
     0.0},
    {"flir_bfs_u3_200s6m", "FLIR Blackfly S BFS-U3-200S6M: Sony IMX183 rolling-shutter CMOS, 20 MP, mono",
     R"(# FLIR Blackfly S BFS-U3-200S6M: Sony IMX183, 5472 x 3648 px, 2.4 um pixels,
# rolling shutter, monochrome, 12-bit ADC.
# Source: FLIR's EMVA 1288 data for the camera as quoted at
#   https://www.uniquephoto.com/community/qa/why-doesnt-full-well-capacity-match-the-adc-range-on-my-flir-blackfly-sensor
# (Photography Stack Exchange, CC BY-SA 4.0): system gain 0.24 (listed as
# e-/ADU; the quoted 4096 / 0.24 = 17067 e- only holds for 0.24 DN/e-),
# 12-bit ADC, saturation capacity 14837 e-, dynamic range 11.93 bit.
# Dark noise derived from the dynamic range as EMVA 1288 defines it, DR =
# mu_p.sat / mu_p.min with mu_p.min = (sigma_y.dark / K + 1/2) / QE (the QE
# cancels): sigma_y.dark / K = 14837 / 2^11.93 - 1/2 = 3.302 e-, which holds
# the quantisation noise, so sigma_d = sqrt(3.302^2 - 1 / (12 K^2)) = 3.076 e-
# (3.061-3.090 for 11.925-11.935 bit); less the dark current's 0.03 e-^2 of
# shot noise, 3.07 e- of read noise. (Not 14837 / 2^11.93 = 3.80 e-: that
# leaves out the quantisation noise and the 1/2.)
[sensor]
cfa = "Mono"
adc_bits = 12
quantum_efficiency = [0.53, 0.53, 0.53]  # assumption (FSI CMOS class at 525 nm)
dark_noise_e = 3.07                      # derived from the source's dynamic range (above)
full_well_e = @WELL@                      # derived from the source's 14837 e- saturation capacity
system_gain_dn_per_e = 0.24              # source
black_level_dn = 64.0                    # assumption
dsnu_e = 1.5                             # assumption
prnu_percent = 0.5                       # assumption
dark_current_e_per_s = 3.0               # assumption
)",
     14837.0},
};

// The preset's TOML with kWell replaced by the well derived from its cited
// saturation capacity.
std::string WithDerivedWell(const Preset& p) {
  std::string text = p.toml;
  if (p.saturation_e == 0) return text;
  const size_t at = text.find(kWell);
  RunConfig rc;
  Origins origins;
  std::string error = "no full_well_e = @WELL@ line";
  double well = 0;
  bool ok = at != std::string::npos;
  if (ok) {
    std::string draft = text;
    draft.replace(at, sizeof kWell - 1, "1.0");  // a stand-in: the solver sets the well
    ok = ParseConfig(draft, std::string("preset ") + p.name, &rc, &origins, &error) &&
         FullWellForEmvaSaturation(rc, p.saturation_e, &well, &error);
  }
  if (!ok) {  // the table above is wrong: a bug, which the unit tests catch
    std::fprintf(stderr, "camsim: preset %s: %s\n", p.name, error.c_str());
    std::abort();
  }
  char number[32];
  std::snprintf(number, sizeof number, "%.0f", well);
  return text.replace(at, sizeof kWell - 1, number);
}

}  // namespace

const std::vector<Preset>& Presets() {
  static const std::vector<std::string> texts = [] {
    std::vector<std::string> t;
    for (const Preset& p : kSources) t.push_back(WithDerivedWell(p));
    return t;
  }();
  static const std::vector<Preset> presets = [] {
    std::vector<Preset> v;
    for (size_t i = 0; i < texts.size(); ++i)
      v.push_back({kSources[i].name, kSources[i].summary, texts[i].c_str(), kSources[i].saturation_e});
    return v;
  }();
  return presets;
}

const Preset* FindPreset(const std::string& name) {
  for (const Preset& p : Presets())
    if (name == p.name) return &p;
  return nullptr;
}

bool ApplyPreset(const std::string& name, RunConfig* config, Origins* origins, std::string* error) {
  const Preset* p = FindPreset(name);
  if (p == nullptr) {
    *error = "unknown preset '" + name + "'; presets:";
    for (const Preset& q : Presets()) *error += std::string(" ") + q.name;
    return false;
  }
  return ParseConfig(p->toml, std::string("preset ") + name, config, origins, error);
}

}  // namespace camsim::host
