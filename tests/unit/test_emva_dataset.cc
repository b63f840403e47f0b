// `camsim emva --dataset`: the photon-transfer analysis of recorded frames.
// A synthetic camera with known K, QE, dark noise, saturation, DSNU and PRNU
// is written as an EMVA 1288 dataset (descriptor + 16-bit PNGs, the format of
// the public EMVA 1288 reference datasets) and measured back; malformed
// datasets fail with the file and line or the image named.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "host_tools/emva_dataset.h"
#include "host_tools/emva_measure.h"
#include "host_tools/io/image_write.h"

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
