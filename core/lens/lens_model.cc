#include "core/lens/lens_model.h"

#include <cmath>  // std::sqrt only: an IEEE basic operation, correctly rounded everywhere

#include "core/base/detmath.h"

namespace camsim {
namespace {

// Fisheye: theta is kept below pi/2 by this much (tan() of it is ~1e6, a
// source a million focal lengths off axis: far outside any frame).
constexpr double kHalfPi = 1.57079632679489661923;
constexpr double kFisheyeThetaMax = kHalfPi - 1e-6;
// Brown: the scan gives up at this undistorted radius (89.9 degrees off axis).
constexpr double kBrownRMax = 600.0;
// Scan step: 1e-4 of the radius (at least 1e-4): a fold is found to ~1e-4
// relative, far finer than any calibration's accuracy.
constexpr double kScanStep = 1e-4;
// Root steps of the radial inverse (Newton kept inside a bracket): about 5
// from the initial guess; a bisection from [0, r_max] (r_max <= 600) reaches
// the last bit of a double within 64 steps + the exponent range it crosses,
// so 128 is never reached in practice, only a bound.
constexpr int kRootSteps = 128;
// Newton polish for the tangential terms: converged when the forward model
// reproduces the distorted point to 1e-12 (normalised; 1e-9 px at f = 1000).
constexpr int kNewtonSteps = 30;
constexpr double kNewtonTolerance = 1e-12;

double BrownFactor(const LensModel& m, double r2, double* dfdr2) {
  const double a = 1.0 + r2 * (m.k[0] + r2 * (m.k[1] + r2 * m.k[2]));
  const double da = m.k[0] + r2 * (2.0 * m.k[1] + r2 * 3.0 * m.k[2]);
  if (m.k[3] == 0.0 && m.k[4] == 0.0 && m.k[5] == 0.0) {
    // No denominator (plumb_bob): b = 1 and db = 0 exactly below, so its
    // quotients are a and da (up to the sign of a zero), without the two
    // divisions that were a third of a lens's configuration time.
    if (dfdr2 != nullptr) *dfdr2 = da;
    return a;
  }
  const double b = 1.0 + r2 * (m.k[3] + r2 * (m.k[4] + r2 * m.k[5]));
  const double db = m.k[3] + r2 * (2.0 * m.k[4] + r2 * 3.0 * m.k[5]);
  if (dfdr2 != nullptr) *dfdr2 = (da * b - a * db) / (b * b);
  return a / b;
}

double Tan(double t) { return detmath::Sin(t) / detmath::Cos(t); }

}  // namespace

void LensDistort(const LensModel& m, double x, double y, double* xd, double* yd) {
  if (m.model == DistortionModel::kFisheye) {
    const double r = std::sqrt(x * x + y * y);
    if (r == 0.0) {
      *xd = x;
      *yd = y;
      return;
    }
    const double theta_d = LensRadial(m, detmath::Atan(r), nullptr);
    *xd = x * (theta_d / r);
    *yd = y * (theta_d / r);
    return;
  }
  if (m.model == DistortionModel::kOff) {
    *xd = x;
    *yd = y;
    return;
  }
  const double r2 = x * x + y * y;
  const double f = BrownFactor(m, r2, nullptr);
  *xd = x * f + 2.0 * m.p1 * x * y + m.p2 * (r2 + 2.0 * x * x);
  *yd = y * f + m.p1 * (r2 + 2.0 * y * y) + 2.0 * m.p2 * x * y;
}

double LensRadial(const LensModel& m, double r, double* derivative) {
  if (m.model == DistortionModel::kFisheye) {
    const double t2 = r * r;
    const double poly = 1.0 + t2 * (m.k[0] + t2 * (m.k[1] + t2 * (m.k[2] + t2 * m.k[3])));
    const double dpoly = t2 * (2.0 * m.k[0] + t2 * (4.0 * m.k[1] + t2 * (6.0 * m.k[2] + t2 * 8.0 * m.k[3])));
    if (derivative != nullptr) *derivative = poly + dpoly;  // d(theta poly)/dtheta
    return r * poly;
  }
  if (m.model == DistortionModel::kOff) {
    if (derivative != nullptr) *derivative = 1.0;
    return r;
  }
  double dfdr2 = 0.0;
  const double f = BrownFactor(m, r * r, &dfdr2);
  if (derivative != nullptr) *derivative = f + 2.0 * r * r * dfdr2;  // d(r f(r^2))/dr
  return r * f;
}

LensBranch LensAnalyse(const LensModel& m, double rd_needed) {
  LensBranch b;
  const double limit = m.model == DistortionModel::kFisheye ? kFisheyeThetaMax : kBrownRMax;
  double r = 0.0, rd = 0.0;
  for (;;) {
    double step = kScanStep * (r > 1.0 ? r : 1.0);
    const double next = r + step > limit ? limit : r + step;
    double d = 0.0;
    const double rd_next = LensRadial(m, next, &d);
    // A fold: the distorted radius stops growing (also a NaN from a zero
    // rational denominator ends the branch here).
    if (!(rd_next > rd) || !(d > 0.0)) {
      b.folds = true;
      break;
    }
    r = next;
    rd = rd_next;
    if (rd > rd_needed || r >= limit) break;
  }
  b.r_max = r;
  b.rd_max = rd;
  return b;
}

bool LensUndistort(const LensModel& m, const LensBranch& b, double xd, double yd, double* x, double* y) {
  const double rd = std::sqrt(xd * xd + yd * yd);
  if (rd == 0.0) {
    *x = 0.0;
    *y = 0.0;
    return true;
  }
  if (m.model == DistortionModel::kOff) {
    *x = xd;
    *y = yd;
    return true;
  }
  if (!(rd <= b.rd_max)) return false;
  // Radius on the increasing branch: LensRadial(r) = rd, r in [0, r_max], by
  // Newton's method kept inside the bracket [lo, hi] around the root (a step
  // that leaves it, or a derivative of 0 or NaN, bisects instead). It stops
  // when the step no longer moves r, or the bracket's ends are neighbouring
  // doubles. (A plain bisection took 64 evaluations: 95 % of a 1080p
  // pipeline's configuration time, which the emulated camera pays on every
  // ExposureTime write.) Start: the distorted radius itself, exact without
  // distortion.
  double lo = 0.0, hi = b.r_max;
  double r = rd < hi ? rd : 0.5 * hi;
  for (int i = 0; i < kRootSteps; ++i) {
    double d = 0.0;
    const double g = LensRadial(m, r, &d) - rd;
    if (g == 0.0) break;
    if (g < 0.0) lo = r; else hi = r;
    double next = r - g / d;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (next == r || next == lo || next == hi) break;
    r = next;
  }
  if (m.model == DistortionModel::kFisheye) {
    const double ru = Tan(r);  // undistorted normalised radius
    *x = xd * (ru / rd);
    *y = yd * (ru / rd);
    return true;
  }
  double ux = xd * (r / rd), uy = yd * (r / rd);
  if (m.p1 == 0.0 && m.p2 == 0.0) {
    *x = ux;
    *y = uy;
    return true;
  }
  // Newton on the full 2-D model from the radial-only solution.
  for (int i = 0; i < kNewtonSteps; ++i) {
    const double r2 = ux * ux + uy * uy;
    double fp = 0.0;
    const double f = BrownFactor(m, r2, &fp);
    const double ex = ux * f + 2.0 * m.p1 * ux * uy + m.p2 * (r2 + 2.0 * ux * ux) - xd;
    const double ey = uy * f + m.p1 * (r2 + 2.0 * uy * uy) + 2.0 * m.p2 * ux * uy - yd;
    if (ex * ex + ey * ey <= kNewtonTolerance * kNewtonTolerance) {
      *x = ux;
      *y = uy;
      return true;
    }
    const double jxx = f + 2.0 * ux * ux * fp + 2.0 * m.p1 * uy + 6.0 * m.p2 * ux;
    const double jxy = 2.0 * ux * uy * fp + 2.0 * m.p1 * ux + 2.0 * m.p2 * uy;
    const double jyy = f + 2.0 * uy * uy * fp + 6.0 * m.p1 * uy + 2.0 * m.p2 * ux;
    const double det = jxx * jyy - jxy * jxy;
    if (!(det > 0.0)) return false;  // the model folds here (tangential terms)
    ux -= (jyy * ex - jxy * ey) / det;
    uy -= (jxx * ey - jxy * ex) / det;
    if (!(ux == ux) || !(uy == uy)) return false;
  }
  return false;
}

}  // namespace camsim
