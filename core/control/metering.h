// Metering for auto exposure (paper eq. 8): the weighted mean brightness of a
// frame. Weights per pixel, Q1.16 (1 = 65536, the largest):
//   uniform  1 everywhere (the free case: `camsim run` then uses the sensor
//            stage's StageStats sums, gathered while rows are hot);
//   centre   1 - r^2, at least 1/16, with r^2 = ((2x+1-w)^2 + (2y+1-h)^2) /
//            (w^2 + h^2) the squared distance from the centre, 1 at the corners
//            (vignetting's normalisation);
//   spot     1 where r < 0.1 (the central 1 % of the half-diagonal's disc area)
//            and at the 1, 2 or 4 pixels nearest the centre, else 0;
//   image    the caller's weight map (e.g. a PNG), sensor-sized.
// Integer sums (uint64), one division at the end.
#pragma once

#include <cstddef>
#include <cstdint>

namespace camsim {

enum class Metering : uint8_t { kUniform, kCentre, kSpot, kImage };

// Weight of pixel (x, y) of a width x height frame, Q1.16 (kImage: not used, returns 65536).
uint32_t MeteringWeight(Metering m, int x, int y, int width, int height);

// Weighted mean of (raw - black) / (max_dn - black) over a raw frame of
// `channels` interleaved samples per pixel (all averaged), clamped below at 0.
// weights: kImage only, width * height Q0.16 values. Returns 0 for an all-zero weight.
double WeightedBrightness(const uint16_t* raw, int width, int height, ptrdiff_t stride, int channels,
                          int black_dn, int max_dn, Metering m, const uint16_t* weights);

}  // namespace camsim
