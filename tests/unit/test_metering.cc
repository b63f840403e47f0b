// Metering weights and the weighted brightness auto exposure measures.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "core/control/metering.h"
#include "core/control/metering_ref.h"

namespace camsim {
namespace {

TEST(Metering, WeightsFollowTheirShapes) {
  constexpr int kW = 101, kH = 81;
  // Centre: 1 at the centre, falling with r^2, 1/16 at the corners.
  EXPECT_EQ(MeteringWeight(Metering::kCentre, 50, 40, kW, kH), 65536u);  // the centre pixel: r = 0
  EXPECT_EQ(MeteringWeight(Metering::kCentre, 0, 0, kW, kH), 4096u);
  EXPECT_GT(MeteringWeight(Metering::kCentre, 40, 40, kW, kH), MeteringWeight(Metering::kCentre, 20, 40, kW, kH));
  // Spot: the disc r < 0.1 of the half-diagonal (64.5 px here: radius ~6.4 px).
  EXPECT_EQ(MeteringWeight(Metering::kSpot, 50, 40, kW, kH), 65536u);
  EXPECT_EQ(MeteringWeight(Metering::kSpot, 56, 40, kW, kH), 65536u);
  EXPECT_EQ(MeteringWeight(Metering::kSpot, 58, 40, kW, kH), 0u);
  EXPECT_EQ(MeteringWeight(Metering::kUniform, 0, 0, kW, kH), 65536u);
}

TEST(Metering, SpotSeesOnlyTheCentreAndUniformSeesTheMean) {
  constexpr int kW = 64, kH = 48, kBlack = 64, kMax = 4095;
  // Dark frame with a bright centre patch (12 x 12 at 1000 DN above black).
  std::vector<uint16_t> raw(kW * kH, kBlack);
  for (int y = 18; y < 30; ++y)
    for (int x = 26; x < 38; ++x) raw[y * kW + x] = kBlack + 1000;
  const double range = kMax - kBlack;
  EXPECT_NEAR(WeightedBrightness(raw.data(), kW, kH, kW, 1, kBlack, kMax, Metering::kSpot, nullptr), 1000 / range, 1e-12);
  EXPECT_NEAR(WeightedBrightness(raw.data(), kW, kH, kW, 1, kBlack, kMax, Metering::kUniform, nullptr),
              1000 / range * 144 / (kW * kH), 1e-12);
  const double centre = WeightedBrightness(raw.data(), kW, kH, kW, 1, kBlack, kMax, Metering::kCentre, nullptr);
  EXPECT_GT(centre, 1000 / range * 144 / (kW * kH));
  EXPECT_LT(centre, 1000 / range);
  // Image weights: only the left half counts.
  std::vector<uint16_t> w(kW * kH, 0);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW / 2; ++x) w[y * kW + x] = 65535;
  EXPECT_NEAR(WeightedBrightness(raw.data(), kW, kH, kW, 1, kBlack, kMax, Metering::kImage, w.data()),
              1000 / range * (6 * 12) / (kW / 2 * kH), 1e-12);
  // Below black counts as 0, never negative.
  std::vector<uint16_t> low(kW * kH, 10);
  EXPECT_EQ(WeightedBrightness(low.data(), kW, kH, kW, 1, kBlack, kMax, Metering::kUniform, nullptr), 0.0);
}

// On a small frame the r < 0.1 disc holds no pixel centre; the spot still
// meters the pixels nearest the centre instead of reading the frame as black.
TEST(Metering, SpotOnASmallFrameMetersTheCentrePixels) {
  constexpr int kBlack = 64, kMax = 4095;
  for (int size : {10, 11}) {
    std::vector<uint16_t> raw(size * size, kBlack + 500);
    const double got = WeightedBrightness(raw.data(), size, size, size, 1, kBlack, kMax, Metering::kSpot, nullptr);
    EXPECT_NEAR(got, 500.0 / (kMax - kBlack), 1e-12) << size;
    int spot = 0;
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) spot += MeteringWeight(Metering::kSpot, x, y, size, size) != 0;
    EXPECT_EQ(spot, size % 2 ? 1 : 4) << size;
  }
}

// A sensor without a CFA gives 3 interleaved samples per pixel: all three
// count, each pixel weighs as one, and the stride is in samples.
TEST(Metering, InterleavedRgbAveragesItsChannels) {
  constexpr int kW = 6, kH = 4, kBlack = 10, kMax = 1033, kStride = 3 * kW + 3;  // a padded row
  std::vector<uint16_t> raw(kStride * kH, 0xFFFF);  // padding would show
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      raw[y * kStride + 3 * x + 0] = kBlack + 100;
      raw[y * kStride + 3 * x + 1] = kBlack + (x < 3 ? 400 : 0);
      raw[y * kStride + 3 * x + 2] = kBlack + 700;
    }
  const double range = kMax - kBlack;
  // Uniform: (100 + 200 + 700) / 3 on average.
  EXPECT_NEAR(WeightedBrightness(raw.data(), kW, kH, kStride, 3, kBlack, kMax, Metering::kUniform, nullptr),
              (100.0 + 200.0 + 700.0) / 3 / range, 1e-12);
  // Image weights on the left half only: (100 + 400 + 700) / 3.
  std::vector<uint16_t> w(kW * kH, 0);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < 3; ++x) w[y * kW + x] = 65535;
  EXPECT_NEAR(WeightedBrightness(raw.data(), kW, kH, kStride, 3, kBlack, kMax, Metering::kImage, w.data()),
              (100.0 + 400.0 + 700.0) / 3 / range, 1e-12);
  // All-zero weights: 0, which the controller reads as black (the host refuses such an image).
  std::vector<uint16_t> none(kW * kH, 0);
  EXPECT_EQ(WeightedBrightness(raw.data(), kW, kH, kStride, 3, kBlack, kMax, Metering::kImage, none.data()), 0.0);
}

// Against the double reference, on a frame of pseudo-random values: the
// fixed-point weights' truncation moves the mean by under 2 x 2^-12 of the
// range (metering_ref.h); spot and uniform weights are exact.
TEST(Metering, WithinItsWeightsRoundingOfTheDoubleReference) {
  constexpr int kW = 97, kH = 61, kBlack = 64, kMax = 4095;
  std::vector<uint16_t> raw(kW * kH * 3);
  uint32_t state = 12345;
  for (uint16_t& v : raw) {
    state = state * 1664525u + 1013904223u;
    v = static_cast<uint16_t>((state >> 8) % 4096);
  }
  std::vector<uint16_t> image(kW * kH);
  std::vector<double> image_ref(kW * kH);
  for (size_t i = 0; i < image.size(); ++i) {
    image[i] = static_cast<uint16_t>((i * 7919) % 65536);
    image_ref[i] = image[i] / 65536.0;
  }
  for (int channels : {1, 3})
    for (Metering m : {Metering::kUniform, Metering::kCentre, Metering::kSpot, Metering::kImage}) {
      const double got = WeightedBrightness(raw.data(), kW, kH, kW * channels, channels, kBlack, kMax, m, image.data());
      const double want =
          ref::RefWeightedBrightness(raw.data(), kW, kH, kW * channels, channels, kBlack, kMax, m, image_ref.data());
      const double bound = m == Metering::kCentre ? 2.0 / 4096 : 1e-12;
      EXPECT_LE(std::fabs(got - want), bound) << static_cast<int>(m) << " channels " << channels;
      EXPECT_GT(want, 0.3);  // a frame of real signal
    }
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      EXPECT_EQ(MeteringWeight(Metering::kSpot, x, y, kW, kH) / 65536.0, ref::RefMeteringWeight(Metering::kSpot, x, y, kW, kH));
}

}  // namespace
}  // namespace camsim
