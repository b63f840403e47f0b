// Deterministic elementary functions for configure-time table building.
//
// libm's exp/log/sin/... differ between C libraries and CPUs in the last bit;
// these do not. Every function is built from IEEE basic operations only
// (+ - * / and comparisons, integer bit manipulation), so with
// -ffp-contract=off the results are bit-identical on x86-64, aarch64 and armhf.
//
// Method: exact range reduction (powers of two, integer Payne-Hanek for sin/cos,
// exactly represented breakpoints for atan), then a Taylor/atanh series
// evaluated by Horner's rule in double-double arithmetic (~2^-70 relative),
// then one final rounding, so results are almost always correctly rounded.
// Measured against x86-64 80-bit long double libm (resolution ~2^-11 ulp),
// 10^6 arguments per range, over Exp [-745, 709.7], Exp2 [-1074, 1024),
// Log/Log2 [1e-300, 1e300] and subnormals, Sin/Cos [-10, 10] and up to 1e300,
// Atan up to 1e300, Atan2 and Pow (x in [e^-50, e^50], |y| <= 1000) with
// normal results: max error 0.5000 ulp for every function (no incorrectly
// rounded result found). Subnormal results of Exp/Exp2/Pow are rounded twice:
// measured max 0.75 ulp (bound 1 ulp of the subnormal).
// Results that are exactly representable come out exactly, e.g. Exp(0) == 1,
// Log(1) == 0, Exp2(k) == 2^k, Log2(2^k) == k, Pow(2, 10) == 1024, Pow(x, 1) == x.
//
// Speed (x86-64, -O2): 0.13-0.35 us per call, InvNormalCdf ~1 us. For
// configure time only (pixel code is integer only anyway).
#pragma once

namespace camsim::detmath {

// e^x. Overflows to +inf above ~709.78, underflows to +0 below ~-745.13. NaN -> NaN.
double Exp(double x);

// 2^x. +inf for x >= 1024, +0 for x <= -1075. NaN -> NaN.
double Exp2(double x);

// Natural logarithm. Log(+0) = -inf, Log(x < 0) = NaN, Log(+inf) = +inf, NaN -> NaN.
double Log(double x);

// Base-2 logarithm; same special values as Log.
double Log2(double x);

// x^y for x >= 0 (x < 0 gives NaN, whatever y). Special values follow C99 pow:
// Pow(x, +-0) = 1 and Pow(1, y) = 1 for any x, y (even NaN); Pow(0, y>0) = 0,
// Pow(0, y<0) = +inf; Pow(+inf, y>0) = +inf, Pow(+inf, y<0) = 0;
// Pow(x, +inf) = +inf for x > 1, 0 for x < 1; Pow(x, -inf) the reverse.
double Pow(double x, double y);

// x^y in plain double, for tables that round it far more coarsely than Pow's
// last bit: about 15x faster, relative error below kPowFastError against Pow
// (detmath.cc derives < 2^-43.6; the unit tests measure it). Not correctly
// rounded; deterministic like the rest. Where x is not in (0, +inf), y is
// not finite or |y ln x| > 64 it returns Pow(x, y).
inline constexpr double kPowFastError = 0x1p-40;
double PowFast(double x, double y);

// Sine and cosine of x in radians, accurate for every finite x (the reduction
// modulo pi/2 uses 1280 bits of 2/pi). Infinite or NaN x -> NaN.
double Sin(double x);
double Cos(double x);

// Arctangent in [-pi/2, pi/2]; Atan(+-inf) = +-pi/2 (rounded), NaN -> NaN.
double Atan(double x);

// Angle of the point (x, y) in [-pi, pi]; signed zeros and infinities as in C99 atan2.
double Atan2(double y, double x);

// Standard normal distribution function Phi(x) = erfc(-x / sqrt 2) / 2, from
// the same erf series and erfc continued fraction as InvNormalCdf's residual,
// with exp(-x^2 / 2) from the exact x^2. Measured against long double erfc at
// 200 000 x per range: max 0.53 ulp for x >= -2.12, 3.9 ulp below (the
// continued fraction is summed in plain double). Phi(0) == 0.5; 0 below -40
// (where Phi underflows), 1 above 40; NaN -> NaN.
double NormalCdf(double x);

// Standard normal quantile: the z with Phi(z) = p. InvNormalCdf(0) = -inf,
// InvNormalCdf(1) = +inf, p outside [0, 1] or NaN -> NaN. Exactly antisymmetric:
// InvNormalCdf(1 - p) == -InvNormalCdf(p) whenever 1 - p is exact (p >= 0.25).
// Acklam's rational approximation (relative error 1.15e-9) refined by one Halley
// step whose residual Phi(z) - p is computed from a double-double erf series
// and an erfc continued fraction. Measured relative error against 380-digit
// references at 9000 p from 5e-324 to 1 - 2^-40: max 3.4e-16 (~3 ulp).
double InvNormalCdf(double p);

}  // namespace camsim::detmath
