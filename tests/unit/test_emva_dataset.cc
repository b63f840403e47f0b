// `camsim emva --dataset`: the photon-transfer analysis of recorded frames.
// A synthetic camera with known K, QE, dark noise, saturation, DSNU and PRNU
// is written as an EMVA 1288 dataset (descriptor + 16-bit PNGs, the format of
// the public EMVA 1288 reference datasets) and measured back; malformed
// datasets fail with the file and line or the image named. camsim's own
// sensor, written as a dataset with dark pairs at several exposure times,
// gives its configured dark current non-uniformity back.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/aperture/exposure.h"
#include "core/pipeline/pipeline.h"
#include "host_tools/emva_dataset.h"
#include "host_tools/emva_measure.h"
#include "host_tools/io/image_write.h"
#include "tests/support/fixtures.h"
#include "tests/support/test_support.h"

namespace camsim::host {
namespace {

// The synthetic camera (mono, 12 bits) and its per-pixel fixed patterns.
struct Camera {
  static constexpr int kW = 128, kH = 128, kBits = 12;
  double gain = 0.25, qe = 0.5, dark_e = 8.0, black_dn = 20.0, dsnu_e = 3.0, prnu = 0.01, well_e = 14000.0;
  std::vector<double> offset_e, response;  // DSNU and PRNU patterns
  std::mt19937_64 rng{12345};

  Camera() {
    std::normal_distribution<double> n(0.0, 1.0);
    for (int i = 0; i < kW * kH; ++i) {
      offset_e.push_back(dsnu_e * n(rng));
      response.push_back(1.0 + prnu * n(rng));
    }
  }
  std::vector<uint16_t> Frame(double photons) {
    std::normal_distribution<double> read(0.0, dark_e);
    std::vector<uint16_t> f(kW * kH);
    for (int i = 0; i < kW * kH; ++i) {
      const double mean_e = photons * qe * response[i];
      double e = mean_e > 0 ? static_cast<double>(std::poisson_distribution<long>(mean_e)(rng)) : 0.0;
      e = std::min(e, well_e) + offset_e[i] + read(rng);
      const double dn = std::round(black_dn + gain * e);
      f[i] = static_cast<uint16_t>(std::clamp(dn, 0.0, (1 << kBits) - 1.0));
    }
    return f;
  }
};

std::string TempDir(const char* name) {
  const std::string d = testing::TempDir() + name + std::to_string(getpid());
  std::filesystem::create_directories(d + "/images");
  return d;
}

// Writes `frames` frames at `photons` as images/NAME_K.png; returns the "i" lines.
std::string WriteSeries(Camera& cam, const std::string& dir, const std::string& name, double photons, int frames) {
  std::string lines;
  for (int k = 0; k < frames; ++k) {
    const std::vector<uint16_t> f = cam.Frame(photons);
    const std::string rel = "images\\" + name + "_" + std::to_string(k) + ".png";  // Windows separators, as the public sets
    std::string error;
    EXPECT_TRUE(io::WritePng(dir + "/images/" + name + "_" + std::to_string(k) + ".png", f.data(), Camera::kW,
                             Camera::kH, 1, 16, Camera::kW, &error))
        << error;
    lines += "i " + rel + "\n";
  }
  return lines;
}

TEST(EmvaDataset, RecoversTheSyntheticCamera) {
  Camera cam;
  const std::string dir = TempDir("emva_dataset_");
  std::string d = "# synthetic camera\nv 3.0\nn 12 128 128\n";
  const double exposure = 1000.0;
  d += "d 1000\n" + WriteSeries(cam, dir, "d", 0, 2);
  // Saturation: the ADC clips at (4095 - 20) / 0.25 = 16300 e-, the well at
  // 14000 e- first, i.e. at 28000 photons; levels to 1.3 times that.
  const double p_sat = cam.well_e / cam.qe;
  constexpr int kLevels = 40;
  for (int i = 1; i <= kLevels; ++i) {
    const double p = 1.3 * p_sat * i / kLevels;
    d += "b " + std::to_string(exposure) + " " + std::to_string(p) + "\n" +
         WriteSeries(cam, dir, std::string("b") + std::to_string(i), p, 2);
  }
  constexpr int kStack = 16;
  d += "d 1000\n" + WriteSeries(cam, dir, "ds", 0, kStack);
  d += "b 1000 " + std::to_string(0.5 * p_sat) + "\n" + WriteSeries(cam, dir, "bs", 0.5 * p_sat, kStack);
  std::ofstream(dir + "/data.txt") << d;

  EmvaDatasetReport r;
  std::string error;
  ASSERT_TRUE(MeasureEmvaDataset(dir + "/data.txt", &r, &error)) << error;
  EXPECT_EQ(r.levels, kLevels);
  EXPECT_EQ(r.bits, 12);
  EXPECT_NEAR(r.fit.system_gain, cam.gain, 0.02 * cam.gain);
  EXPECT_NEAR(r.fit.responsivity / r.fit.system_gain, cam.qe, 0.02 * cam.qe);
  // sigma_d: read noise and DSNU-free temporal noise; 16384 px give ~1 % on the variance.
  EXPECT_NEAR(r.fit.dark_noise_e, cam.dark_e, 0.04 * cam.dark_e);
  EXPECT_NEAR(r.dark_mean_dn, cam.black_dn, 0.1);
  // EMVA's saturation (variance maximum) lies a few sigma below the well.
  EXPECT_LT(r.fit.saturation_e, cam.well_e);
  EXPECT_GT(r.fit.saturation_e, 0.9 * cam.well_e);
  ASSERT_TRUE(r.has_nonuniformity);
  EXPECT_NEAR(r.dsnu_e, cam.dsnu_e, 0.08 * cam.dsnu_e);
  EXPECT_NEAR(r.prnu_percent, 100 * cam.prnu, 0.08 * 100 * cam.prnu);
  // The report carries the figures as preset keys.
  const std::string text = FormatEmvaDatasetReport("data.txt", r);
  EXPECT_NE(text.find("system_gain_dn_per_e = 0.2"), std::string::npos) << text;
  // One dark exposure time: no growth to take the DCNU from.
  EXPECT_FALSE(r.dcnu.measured);
  EXPECT_NE(text.find("DCNU: not measurable: the dark pairs are at 1 exposure time"), std::string::npos) << text;
  EXPECT_EQ(text.find("dcnu_percent ="), std::string::npos) << text;
}

// camsim's sensor (exposure -> cfa -> sensor, mono 256 x 256, 12 bit, K 0.5
// DN/e-, black 100 DN, read noise 5 e-, DSNU 5 e-, shot noise, 1e5 e-/s of
// dark current: 100 e- at 1 ms, 1000 e- at 10 ms) written as an EMVA 1288
// dataset: dark pairs at 1, 2, 4, 6, 8 and 10 ms (written in us), bright
// pairs at 1 ms for K (10 levels up to 5200 e-, below the 7790 e- clip).
constexpr int kSide = 256;
constexpr double kDarkCurrent = 1e5;  // e-/s

EmvaDatasetReport MeasureEmulated(double dcnu_percent, double dark_current, const char* name) {
  PipelineConfig c = test::MonoSensorPath(kSide, kSide);
  c.sensor.system_gain_dn_per_e = 0.5;
  c.sensor.black_level_dn = 100.0;
  c.sensor.dark_noise_e = 5.0;
  c.sensor.dsnu_e = 5.0;
  c.sensor.dark_current_e_per_s = dark_current;
  c.sensor.dcnu_percent = dcnu_percent;
  c.seed = 7;
  const std::string dir = TempDir(name);
  uint32_t frame = 0;  // every frame its own temporal noise; the fixed patterns follow the seed
  int image = 0;
  // A pair at exposure_us of a flat field of `radiance`; returns its "i" lines.
  const auto pair = [&](double exposure_us, double radiance) {
    c.exposure.exposure_time_us = exposure_us;
    const auto built = test::Build(c);
    EXPECT_TRUE(built->status.ok()) << built->status.message();
    std::string lines;
    for (int k = 0; k < 2; ++k) {
      const std::vector<uint32_t> dn =
          test::RunFrame(*built, test::FlatScene(kSide, kSide, radiance, radiance, radiance), frame++, kSide);
      const std::vector<uint16_t> px(dn.begin(), dn.end());
      const std::string file = "images/f" + std::to_string(image++) + ".png";
      std::string error;
      EXPECT_TRUE(io::WritePng(dir + "/" + file, px.data(), kSide, kSide, 1, 16, kSide, &error)) << error;
      lines += "i " + file + "\n";
    }
    return lines;
  };
  std::string d = "n 12 256 256\n";
  for (double ms : {1.0, 2.0, 4.0, 6.0, 8.0, 10.0}) d += "d " + std::to_string(ms * 1000) + "\n" + pair(ms * 1000, 0);
  c.exposure.exposure_time_us = 1000.0;
  const double photons_per_radiance = ExposurePhotonsPerRadiance(c.exposure);  // 100 at 1 ms
  for (int i = 1; i <= 10; ++i) {
    const double radiance = 8.0 * i;  // exact in Q16.16: 800 .. 8000 photons, QE 0.65
    d += "b 1000 " + std::to_string(radiance * photons_per_radiance) + "\n" + pair(1000.0, radiance);
  }
  std::ofstream(dir + "/data.txt") << d;
  EmvaDatasetReport r;
  std::string error;
  EXPECT_TRUE(MeasureEmvaDataset(dir + "/data.txt", &r, &error)) << error;
  return r;
}

// The estimate's scatter is the pixels': the sample rms of 65 536 DCNU gains
// is within 1 / sqrt(2 N) = 0.28 % of the model's, their mean within
// s / sqrt(N) (0.12 % at 30 %), so the ratio's standard error is ~0.3 %
// of it (0.09 points at 30 %). The temporal variance's share (at most 512
// e-^2 against 90 000 e-^2 of DCNU at 10 ms) and the DSNU's chance
// correlation with the DCNU (2 x 5 / (30 x 256): 0.13 % at 1 ms) add less.
// 0.4 points is over 4 standard errors. K divides both the spread and the
// mean; the spread in e- also depends on K's fit (6 levels of 65 536 pixels:
// it reads 0.4 % high), so 2 % on it. (They read 29.92 and 59.75.)
TEST(EmvaDataset, EmulatedSensorsDcnuIsMeasured) {
  for (const double dcnu : {30.0, 60.0}) {
    SCOPED_TRACE(dcnu);
    const EmvaDatasetReport r = MeasureEmulated(dcnu, kDarkCurrent, "emva_dcnu_");
    ASSERT_TRUE(r.dcnu.measured) << r.dcnu.not_measurable;
    ASSERT_EQ(r.dcnu.points.size(), 6u);
    EXPECT_NEAR(r.fit.system_gain, 0.5, 0.01);
    // The model's pixel dark currents: mean and rms factors of the clipped normal.
    const double s = dcnu / 100.0, a = 1.0 / s;
    const double cdf = 0.5 * std::erfc(-a / std::sqrt(2.0));
    const double pdf = std::exp(-0.5 * a * a) / std::sqrt(2.0 * std::acos(-1.0));
    const double mean = cdf + s * pdf;
    const double rms = std::sqrt((1.0 + s * s) * cdf + s * pdf - mean * mean);
    const double per_us = kDarkCurrent * 1e-6;  // the descriptor's unit
    EXPECT_NEAR(r.dark_current_e, per_us * mean, 0.02 * per_us);
    EXPECT_NEAR(r.dcnu.spread_e, per_us * rms, 0.02 * per_us * rms);
    // At 60 % the clamp at 0 shows: the spread over the mean is 56.8 %, and
    // dcnu_percent is the model's 60 again (DcnuPercentForSpreadRatio).
    EXPECT_NEAR(r.dcnu.ratio_percent, 100.0 * rms / mean, dcnu / 75);
    EXPECT_NEAR(r.dcnu.dcnu_percent, dcnu, dcnu / 75);
    const std::string text = FormatEmvaDatasetReport("data.txt", r);
    EXPECT_NE(text.find("DCNU (% of the dark current)"), std::string::npos) << text;
    const size_t key = text.find("\ndcnu_percent = ");  // the [sensor] block's
    ASSERT_NE(key, std::string::npos) << text;
    EXPECT_NEAR(std::stod(text.substr(key + 16)), dcnu, dcnu / 75) << text;
  }
  // Small ratios are the percentage itself; past 100 %'s ratio (80 %) the model has none higher.
  EXPECT_NEAR(DcnuPercentForSpreadRatio(10.0), 10.0, 1e-6);
  EXPECT_EQ(DcnuPercentForSpreadRatio(90.0), 100.0);
}

// Without DCNU the spread grows only by the temporal noise, which the
// estimate removes: what is left is the sampling of the averaged pair's
// variance (~520 e-^2 at 10 ms, known to sqrt(2 / N) = 0.55 %: ~3 e-^2), a
// spread of ~2 e- on 1000 e-, ~0.2 % (it reads 0.09 %). 0.5 % is 25 e-^2 at
// 10 ms, 8 of those standard errors; leaving the temporal share in reads
// 2.1 %. With no dark current there is nothing to measure.
TEST(EmvaDataset, EmulatedSensorWithoutDcnuReadsNone) {
  const EmvaDatasetReport r = MeasureEmulated(0.0, kDarkCurrent, "emva_nodcnu_");
  ASSERT_TRUE(r.dcnu.measured) << r.dcnu.not_measurable;
  EXPECT_LT(r.dcnu.dcnu_percent, 0.5);
  EXPECT_NEAR(r.dark_current_e, kDarkCurrent * 1e-6, 0.02 * kDarkCurrent * 1e-6);
  const EmvaDatasetReport none = MeasureEmulated(30.0, 0.0, "emva_nodark_");
  EXPECT_FALSE(none.dcnu.measured);
  const std::string text = FormatEmvaDatasetReport("data.txt", none);
  EXPECT_NE(text.find("DCNU: not measurable: the mean dark signal grows by"), std::string::npos) << text;
  EXPECT_EQ(text.find("dcnu_percent ="), std::string::npos) << text;
}

std::string MeasureError(const std::string& descriptor_text, const std::string& dir) {
  std::ofstream(dir + "/bad.txt") << descriptor_text;
  EmvaDatasetReport r;
  std::string error;
  EXPECT_FALSE(MeasureEmvaDataset(dir + "/bad.txt", &r, &error));
  return error;
}

TEST(EmvaDataset, MalformedDatasetsNameTheFileAndLine) {
  Camera cam;
  const std::string dir = TempDir("emva_bad_");
  const std::string pair = WriteSeries(cam, dir, "p", 100, 2);
  EXPECT_NE(MeasureError("n 12 128 128\nq 1\n", dir).find("bad.txt:2: unknown line 'q'"), std::string::npos);
  EXPECT_NE(MeasureError("n 12 128\n", dir).find("bad.txt:1: expected 'n BITS WIDTH HEIGHT'"), std::string::npos);
  EXPECT_NE(MeasureError("n 12abc 128 128\n", dir).find("bad.txt:1: expected 'n BITS WIDTH HEIGHT'"), std::string::npos);
  EXPECT_NE(MeasureError("n 12 128 128.5\n", dir).find("bad.txt:1: expected 'n BITS WIDTH HEIGHT'"), std::string::npos);
  EXPECT_NE(MeasureError("n 12 128 128\nb 10 nan\n" + pair, dir).find("bad.txt:2: expected 'b EXPOSURE PHOTONS'"),
            std::string::npos);
  EXPECT_NE(MeasureError("n 12 128 128\nd 10\ni images/p_0.png\n", dir).find("bad.txt:2: a series needs at least 2"),
            std::string::npos);
  EXPECT_NE(MeasureError("i images/p_0.png\n", dir).find("bad.txt:1: an image before"), std::string::npos);
  // A bright pair without a dark pair at its exposure time.
  EXPECT_NE(MeasureError("n 12 128 128\nd 10\n" + pair + "b 20 100\n" + pair, dir).find("bad.txt:5: no dark pair"),
            std::string::npos);
  // The images must match the descriptor's size and bit depth.
  EXPECT_NE(MeasureError("n 12 64 64\nd 10\n" + pair, dir).find("is 128x128, the descriptor says 64x64"),
            std::string::npos);
  EXPECT_NE(MeasureError("n 4 128 128\nd 10\n" + pair, dir).find("above the descriptor's 4-bit range"),
            std::string::npos);
  EXPECT_NE(MeasureError("n 12 128 128\nd 10\ni images/missing.png\ni images/p_0.png\n", dir).find("missing.png"),
            std::string::npos);
  EXPECT_EQ(MeasureError("", dir + "/nowhere"),
            dir + "/nowhere/bad.txt: cannot read the EMVA 1288 descriptor: No such file or directory");
}

// EMVA 1288: at most 0.5 % of the dark pixels may read 0. With no offset the
// dark signal is clipped at 0 and its noise and DSNU read low; such a dark
// pair is refused, naming its line.
TEST(EmvaDataset, DarkPairClippedAtZeroIsRefused) {
  Camera cam;
  cam.black_dn = 0.0;
  const std::string dir = TempDir("emva_zero_");
  const std::string error = MeasureError("n 12 128 128\nd 1000\n" + WriteSeries(cam, dir, "z", 0, 2), dir);
  EXPECT_NE(error.find("bad.txt:2: "), std::string::npos) << error;
  EXPECT_NE(error.find("% of the dark pixels read 0, more than the 0.5 % EMVA 1288 allows"), std::string::npos)
      << error;
}

// A directory opens as a file on Linux and reads as nothing, and a read error
// used to end the text early: both are refused, with the file and the reason.
TEST(EmvaDataset, DirectoryAndReadErrorAreRefused) {
  EmvaDatasetReport r;
  std::string error;
  const std::string dir = TempDir("emva_dir_");
  EXPECT_FALSE(MeasureEmvaDataset(dir, &r, &error));
  EXPECT_EQ(error, dir + ": cannot read the EMVA 1288 descriptor: is a directory, not a file");
  EXPECT_FALSE(MeasureEmvaDataset("/proc/self/mem", &r, &error));  // reading offset 0 fails (EIO)
  EXPECT_EQ(error.rfind("/proc/self/mem: cannot read the EMVA 1288 descriptor: read failed: ", 0), 0u) << error;
}

// Data without a photon transfer is refused with the reason, not measured as
// NaN or 0: a noiseless series, a series whose signal does not grow with
// the photons, stacks without light between them.
TEST(EmvaDataset, DegenerateDataIsRefusedWithTheReason) {
  std::vector<TransferLevel> flat, dark;
  for (int i = 0; i < 8; ++i) {
    TransferLevel l;
    l.photons = 100.0 * (i + 1);
    l.mean = 64.0 + 10.0 * i;  // a noiseless sensor: the signal grows, the variance does not
    l.dark_mean = 64.0;
    flat.push_back(l);
    l.mean = 64.0;  // no signal at all, only read noise
    l.var = l.dark_var = 4.0;
    dark.push_back(l);
  }
  TransferFit fit;
  std::string error;
  EXPECT_FALSE(FitPhotonTransfer(flat, 0.0, &fit, &error));
  EXPECT_NE(error.find("the temporal variance never rises above the dark variance"), std::string::npos) << error;
  EXPECT_FALSE(FitPhotonTransfer(dark, 4.0, &fit, &error));
  EXPECT_NE(error.find("the temporal variance never rises above the dark variance"), std::string::npos) << error;
  std::vector<TransferLevel> no_photons = dark;  // the variance grows, the photon column is 0
  for (size_t i = 0; i < no_photons.size(); ++i) {
    no_photons[i].photons = 0.0;
    no_photons[i].mean = 64.0 + 10.0 * static_cast<double>(i);
    no_photons[i].var = 4.0 + 4.0 * static_cast<double>(i);
  }
  no_photons.back().var = 1000.0;  // saturation: the variance peaks at the last level
  EXPECT_FALSE(FitPhotonTransfer(no_photons, 4.0, &fit, &error));
  EXPECT_NE(error.find("the signal does not grow with the photon count"), std::string::npos) << error;
  const FrameStack bright{100.0, 9.0, 4.0, 16}, same{100.0, 5.0, 4.0, 16};
  double dsnu = 0.0, prnu = 0.0;
  EXPECT_FALSE(NonUniformity(same, bright, 0.4, &dsnu, &prnu, &error));
  EXPECT_NE(error.find("is not above the dark stack's"), std::string::npos) << error;
  const FrameStack darker{64.0, 5.0, 4.0, 16};
  ASSERT_TRUE(NonUniformity(darker, bright, 0.4, &dsnu, &prnu, &error)) << error;
  EXPECT_TRUE(std::isfinite(prnu) && prnu > 0.0);
}

}  // namespace
}  // namespace camsim::host
