#include "host_tools/presets.h"

namespace camsim::host {

// Each preset sets only [sensor] keys (and the CFA). The frame size and pixel
// pitch are left to the scene (the bundled scenes assume a 36 mm wide sensor);
// the native resolution is given as a comment. Values marked "assumption" are
// not in the cited source: they are typical of the sensor class and stated so
// that `camsim emva` can measure them back like the cited ones.
const std::vector<Preset>& Presets() {
  static const std::vector<Preset> presets = {
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
# A VGA CCD like the seed paper's camera; a 7.4 um pixel is typical of the class.
[sensor]
cfa = "Mono"
adc_bits = 12
quantum_efficiency = [0.4525, 0.4525, 0.4525]  # source (the wavelength is not in the dataset)
dark_noise_e = 10.93                           # source
full_well_e = 14200.0                          # near the source: camsim emva measures 13 660 e- with it, 2.5 % below the dataset's 14 010 (the variance peak lies ~2.5 sigma below the clip)
system_gain_dn_per_e = 0.2801                  # source
black_level_dn = 14.7                          # source (dark level at the shortest exposure)
dsnu_e = 0.55                                  # source
prnu_percent = 0.43                            # source
dark_current_e_per_s = 28.5                    # source, assuming the dataset's exposure unit is ns (2.85e-8 e-/ns)
)"},
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
full_well_e = 7000.0                     # the source's saturation capacity as the well: camsim emva measures 6782 e-
system_gain_dn_per_e = 0.55              # assumption: saturation at ~3900 of 4095 DN
black_level_dn = 64.0                    # assumption
dsnu_e = 3.0                             # assumption (CCD class)
prnu_percent = 0.6                       # assumption (CCD class)
dark_current_e_per_s = 10.0              # assumption
)"},
      {"rpi_hq_imx477", "Raspberry Pi HQ Camera: Sony IMX477 rolling-shutter CMOS, 12 MP, Bayer",
       R"(# Raspberry Pi High Quality Camera: Sony IMX477, 4056 x 3040 px, 1.55 um
# pixels, rolling shutter, BayerBG, 12-bit raw.
# Source: photon-transfer measurement (the EMVA 1288 method, not a vendor
# sheet), "Pi HQ Cam Sensor Performance" on strollswithmydog.com,
#   https://www.strollswithmydog.com/pi-hq-cam-sensor-performance/
# summary table at analog gain 1: black level 256 DN, white level 4095 DN,
# read noise 3 e-, clipping (full well) 8180 e-, system gain 0.47 DN/e-.
# The source's full well is where the raw data clips: (4095 - 256) / 0.47 =
# 8168 e-, so here too the ADC clips just before the well is full.
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
)"},
      {"flir_bfs_u3_200s6m", "FLIR Blackfly S BFS-U3-200S6M: Sony IMX183 rolling-shutter CMOS, 20 MP, mono",
       R"(# FLIR Blackfly S BFS-U3-200S6M: Sony IMX183, 5472 x 3648 px, 2.4 um pixels,
# rolling shutter, monochrome, 12-bit ADC.
# Source: FLIR's EMVA 1288 data for the camera as quoted at
#   https://www.uniquephoto.com/community/qa/why-doesnt-full-well-capacity-match-the-adc-range-on-my-flir-blackfly-sensor
# (Photography Stack Exchange, CC BY-SA 4.0): system gain 0.24 (listed as
# e-/ADU; the quoted 4096 / 0.24 = 17067 e- only holds for 0.24 DN/e-),
# 12-bit ADC, saturation capacity 14837 e-, dynamic range 11.93 bit. Dark
# noise derived from the dynamic range as mu_e.sat / sigma_d: 14837 / 2^11.93
# = 3.80 e- (EMVA 1288's DR = mu_p.sat / mu_p.min also counts the
# quantisation noise and would give about 3.05 e-; the source does not say
# which it used).
[sensor]
cfa = "Mono"
adc_bits = 12
quantum_efficiency = [0.53, 0.53, 0.53]  # assumption (FSI CMOS class at 525 nm)
dark_noise_e = 3.8                       # derived from the source's dynamic range
full_well_e = 14837.0                    # source (camsim emva measures 14 250 e- with it)
system_gain_dn_per_e = 0.24              # source
black_level_dn = 64.0                    # assumption
dsnu_e = 1.5                             # assumption
prnu_percent = 0.5                       # assumption
dark_current_e_per_s = 3.0               # assumption
)"},
  };
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
