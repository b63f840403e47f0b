// Calibration targets as radiance images (`camsim pattern`): a checkerboard
// (cv::findChessboardCorners), a dot grid (centroids), a slanted edge (MTF,
// ISO 12233 style, 5 degrees) and a Siemens star (36 spokes). Rendered as the
// ideal pinhole view of a flat target filling the frame, grey (R = G = B),
// each pixel the average of supersample^2 points (pixel centres at integer
// coordinates), so edges are anti-aliased and centroids unbiased.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace camsim::host {

enum class PatternKind { kCheckerboard, kDotGrid, kSlantedEdge, kSiemensStar };

struct PatternOptions {
  PatternKind kind = PatternKind::kCheckerboard;
  int width = 1920, height = 1080;
  double cell = 0.0;  // square / dot spacing in pixels; 0 = height / 12
  double low = 0.05, high = 0.9;  // radiance of dark and light parts
  int supersample = 8;
  double dot_radius = 0.0;  // dot grid: dot radius in pixels; 0 = cell / 4
};

bool PatternFromName(const std::string& name, PatternKind* kind);
// The cell size after defaults.
double PatternCell(const PatternOptions& o);
// The target's radiance at continuous image position (x, y) (one point).
double PatternAt(const PatternOptions& o, double x, double y);
// The image, width * height samples, row-major, area-averaged.
std::vector<float> RenderPattern(const PatternOptions& o);
// Geometry (pixels): dot centres of the dot grid, inner corners of the
// checkerboard (row-major, as cv::findChessboardCorners orders them for a
// fronto-parallel view), and the board's inner-corner counts.
std::vector<std::pair<double, double>> PatternDotCentres(const PatternOptions& o);
std::vector<std::pair<double, double>> PatternCorners(const PatternOptions& o, int* cols, int* rows);
// Dot radius in pixels.
double PatternDotRadius(const PatternOptions& o);

// `camsim pattern NAME --out FILE.exr [--width W] [--height H] [--cell PX]`.
int PatternCommand(int argc, char** argv);
// Its usage lines (part of `camsim --help`).
extern const char kPatternUsage[];

}  // namespace camsim::host
