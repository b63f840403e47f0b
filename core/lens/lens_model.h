// Lens geometry models with OpenCV's conventions, in double precision, for
// configure-time table building (IEEE + - * / and sqrt plus core/base/detmath.h
// only, so the results are the same on every platform).
//
// Pixel (u, v) has its centre at integer coordinates; the camera matrix maps
// normalised image coordinates (x, y) = (X/Z, Y/Z) to pixels:
//   u = fx * xd + cx,  v = fy * yd + cy   (no skew)
// where (xd, yd) is the distorted point:
//
// Brown-Conrady (OpenCV "plumb_bob" k1 k2 p1 p2 k3, "rational_polynomial"
// adds k4 k5 k6), r2 = x^2 + y^2:
//   f  = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
//   xd = x f + 2 p1 x y + p2 (r2 + 2 x^2)
//   yd = y f + p1 (r2 + 2 y^2) + 2 p2 x y
// Equidistant fisheye (cv::fisheye, ROS "equidistant", Kannala-Brandt k1-k4):
//   r = sqrt(x^2 + y^2), theta = atan(r),
//   theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//   (xd, yd) = (theta_d / r) (x, y)
//
// The inverse (distorted -> undistorted) is what a simulator needs: for each
// output pixel, where the ideal pinhole image (same camera matrix) is sampled.
// It is solved on the branch where the radial function increases from the
// centre: the radius is found by bisection (robust, no starting guess), then
// the tangential terms are removed by a few Newton steps in 2-D.
#pragma once

#include <cstdint>

namespace camsim {

enum class DistortionModel : uint8_t { kOff, kBrown, kFisheye };

struct LensModel {
  DistortionModel model = DistortionModel::kOff;
  double fx = 0.0, fy = 0.0;  // focal lengths, pixels
  double cx = 0.0, cy = 0.0;  // principal point, pixels (0-based pixel centres)
  // Brown: k1, k2, k3, k4, k5, k6 (k4..k6: rational denominator).
  // Fisheye: k1..k4 in k[0..3]; k[4], k[5] must be 0.
  double k[6] = {};
  double p1 = 0.0, p2 = 0.0;  // Brown tangential
};

// The monotone branch of the radial function, found by LensAnalyse.
struct LensBranch {
  // Undistorted radius (Brown: normalised r; fisheye: theta, radians) up to
  // which the radial function still increases, and the distorted radius there.
  double r_max = 0.0;
  double rd_max = 0.0;
  bool folds = false;  // true when the function stops increasing at r_max
};

// Forward model: undistorted normalised (x, y) -> distorted normalised.
void LensDistort(const LensModel& lens, double x, double y, double* xd, double* yd);

// Radial function: distorted radius for undistorted radius r (Brown: r f(r^2);
// fisheye: theta_d(theta) with r = theta), and its derivative.
double LensRadial(const LensModel& lens, double r, double* derivative);

// Scans the radial function from the centre until its distorted radius exceeds
// rd_needed or it stops increasing (a fold). The fisheye branch ends before
// theta = pi/2 (points behind the camera plane have no pinhole image).
LensBranch LensAnalyse(const LensModel& lens, double rd_needed);

// Inverse: distorted normalised (xd, yd) -> undistorted (x, y). False when
// the point lies beyond the branch (no source: beyond a fold, or outside the
// fisheye's half-sphere) or the 2-D Newton polish does not converge.
bool LensUndistort(const LensModel& lens, const LensBranch& branch, double xd, double yd, double* x, double* y);

}  // namespace camsim
