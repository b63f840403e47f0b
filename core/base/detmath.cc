#include "core/base/detmath.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace camsim::detmath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------
// Double-double arithmetic: a value is the unevaluated sum hi + lo.
// (Dekker / Knuth error-free transformations; exact with -ffp-contract=off.)

struct DD {
  double hi;
  double lo;
};

constexpr DD FastTwoSum(double a, double b) {  // needs |a| >= |b| or a == 0
  const double s = a + b;
  return {s, b - (s - a)};
}

constexpr DD TwoSum(double a, double b) {
  const double s = a + b;
  const double bb = s - a;
  return {s, (a - (s - bb)) + (b - bb)};
}

constexpr DD Split(double a) {       // Veltkamp: a = hi + lo with 26-bit halves (|a| < 2^995)
  const double c = 134217729.0 * a;  // 2^27 + 1
  const double hi = c - (c - a);
  return {hi, a - hi};
}

constexpr DD TwoProd(double a, double b) {  // a * b exactly (barring underflow)
  const double p = a * b;
  const DD x = Split(a);
  const DD y = Split(b);
  return {p, ((x.hi * y.hi - p) + x.hi * y.lo + x.lo * y.hi) + x.lo * y.lo};
}

constexpr DD Neg(DD a) { return {-a.hi, -a.lo}; }

constexpr DD Add(DD a, DD b) {
  DD s = TwoSum(a.hi, b.hi);
  const DD t = TwoSum(a.lo, b.lo);
  s = FastTwoSum(s.hi, s.lo + t.hi);
  return FastTwoSum(s.hi, s.lo + t.lo);
}

constexpr DD Mul(DD a, DD b) {
  const DD p = TwoProd(a.hi, b.hi);
  return FastTwoSum(p.hi, p.lo + (a.hi * b.lo + a.lo * b.hi));
}

constexpr DD Mul(DD a, double b) {
  const DD p = TwoProd(a.hi, b);
  return FastTwoSum(p.hi, p.lo + a.lo * b);
}

constexpr DD Div(DD a, DD b) {
  const double q1 = a.hi / b.hi;
  const DD r = Add(a, Neg(Mul(b, q1)));
  const double q2 = r.hi / b.hi;
  const DD r2 = Add(r, Neg(Mul(b, q2)));
  return Add(FastTwoSum(q1, q2), DD{r2.hi / b.hi, 0.0});
}

constexpr double Round(DD a) { return a.hi + a.lo; }

// Power series sum_i c[i] z^i.
template <int N>
struct Series {
  DD c[N];
};

// Horner's rule: the terms i >= kDD in plain double (each use picks kDD so
// that their rounding stays below 2^-70 of the result), then the first kDD
// terms in double-double.
template <int kDD, int N>
constexpr DD Horner(const Series<N>& s, DD z) {
  double tail = 0.0;
  for (int i = N - 1; i >= kDD; --i) tail = tail * z.hi + s.c[i].hi;
  DD acc{tail, 0.0};
  for (int i = kDD - 1; i >= 0; --i) acc = Add(Mul(acc, z), s.c[i]);
  return acc;
}

// 1/n! for n = 0 .. N-1, each from the previous by a double-double division.
template <int N>
constexpr Series<N> InverseFactorials() {
  Series<N> s{};
  DD f{1.0, 0.0};
  for (int n = 0; n < N; ++n) {
    s.c[n] = f;
    f = Div(f, DD{static_cast<double>(n + 1), 0.0});
  }
  return s;
}

// exp(r) = sum r^n/n!; 17 terms leave 2^-74 for |r| <= 0.35.
constexpr Series<17> kExpSeries = InverseFactorials<17>();

// log(m) = 2 atanh(s) = s * sum 2 s^(2j)/(2j+1); 15 terms leave 2^-75 for |s| <= 0.172.
constexpr Series<15> kAtanhSeries = [] {
  Series<15> s{};
  for (int j = 0; j < 15; ++j) s.c[j] = Div(DD{2.0, 0.0}, DD{2.0 * j + 1.0, 0.0});
  return s;
}();

// sin(r) = r * sum (-1)^j r^(2j)/(2j+1)!, cos(r) = sum (-1)^j r^(2j)/(2j)!;
// |r| <= pi/4 leaves < 2^-70.
constexpr Series<22> kFactorials = InverseFactorials<22>();
constexpr Series<10> kSinSeries = [] {
  Series<10> s{};
  for (int j = 0; j < 10; ++j)
    s.c[j] = (j % 2) ? Neg(kFactorials.c[2 * j + 1]) : kFactorials.c[2 * j + 1];
  return s;
}();
constexpr Series<11> kCosSeries = [] {
  Series<11> s{};
  for (int j = 0; j < 11; ++j) s.c[j] = (j % 2) ? Neg(kFactorials.c[2 * j]) : kFactorials.c[2 * j];
  return s;
}();

// atan(u) = u * sum (-1)^j u^(2j)/(2j+1); 27 terms leave 2^-70 for |u| <= 7/16.
constexpr Series<27> kAtanSeries = [] {
  Series<27> s{};
  for (int j = 0; j < 27; ++j) {
    const DD c = Div(DD{1.0, 0.0}, DD{2.0 * j + 1.0, 0.0});
    s.c[j] = (j % 2) ? Neg(c) : c;
  }
  return s;
}();

// erf(z) = 2/sqrt(pi) z sum (-1)^n z^(2n) / (n! (2n+1)); 32 terms leave < 1e-26 for |z| <= 1.5.
constexpr Series<32> kErfSeries = [] {
  const Series<32> f = InverseFactorials<32>();
  Series<32> s{};
  for (int n = 0; n < 32; ++n) {
    const DD c = Div(f.c[n], DD{2.0 * n + 1.0, 0.0});
    s.c[n] = (n % 2) ? Neg(c) : c;
  }
  return s;
}();

// Constants rounded to double-double (computed with 2000-bit arithmetic).
constexpr DD kLn2 = {0x1.62e42fefa39efp-1, 0x1.abc9e3b39803fp-56};
constexpr DD kInvLn2 = {0x1.71547652b82fep+0, 0x1.777d0ffda0d24p-56};
constexpr DD kPi = {0x1.921fb54442d18p+1, 0x1.1a62633145c07p-53};
constexpr DD kPiO2 = {0x1.921fb54442d18p+0, 0x1.1a62633145c07p-54};
constexpr DD kPiO4 = {0x1.921fb54442d18p-1, 0x1.1a62633145c07p-55};
constexpr DD kAtanHalf = {0x1.dac670561bb4fp-2, 0x1.a2b7f222f65e2p-56};         // atan(1/2)
constexpr DD kAtanThreeHalves = {0x1.f730bd281f69bp-1, 0x1.007887af0cbbdp-56};  // atan(3/2)
constexpr DD kTwoOverSqrtPi = {0x1.20dd750429b6dp+0, 0x1.1ae3a914fed80p-56};
constexpr double kSqrt2 = 0x1.6a09e667f3bcdp+0;
constexpr double kInvSqrt2 = 0x1.6a09e667f3bcdp-1;
constexpr DD kInvSqrt2DD = {kInvSqrt2, -0x1.bdd3413b26456p-55};
constexpr double kSqrt2Pi = 0x1.40d931ff62706p+1;    // sqrt(2 pi)
constexpr double kInvSqrtPi = 0x1.20dd750429b6dp-1;  // 1/sqrt(pi)

// 2^k for k in [-1022, 1023], built from its bits.
double Pow2(int k) { return std::bit_cast<double>(static_cast<uint64_t>(k + 1023) << 52); }

// y * 2^k (y < 2, k in [-1086, 1024]) with one rounding (two into the subnormal range).
double Scale(double y, int k) {
  if (k > 1023) return y * 0x1p1023 * Pow2(k - 1023);
  if (k < -1022) return y * Pow2(k + 64) * 0x1p-64;
  return y * Pow2(k);
}

bool SignBit(double x) { return (std::bit_cast<uint64_t>(x) >> 63) != 0; }

// Nearest integer of |x| < 2^31 (ties away from zero; which one is immaterial here).
int NearestInt(double x) { return static_cast<int>(x < 0 ? x - 0.5 : x + 0.5); }

// ---------------------------------------------------------------------------
// exp

// e^t for a double-double t.
double ExpDD(DD t) {
  if (t.hi != t.hi) return t.hi;
  if (t.hi > 710.0) return kInf;
  if (t.hi < -746.0) return 0.0;
  // t = k ln2 + r, |r| <= ln2/2 (+ rounding). t.hi - k*ln2.hi is exact (Sterbenz).
  const int k = NearestInt(t.hi * kInvLn2.hi);
  const double kd = static_cast<double>(k);
  const DD kl = TwoProd(kd, kLn2.hi);
  DD r = TwoSum(t.hi - kl.hi, t.lo);
  r = Add(r, DD{-kl.lo, -kd * kLn2.lo});
  return Scale(Round(Horner<6>(kExpSeries, r)), k);  // r^6/6! < 2^-18
}

// ---------------------------------------------------------------------------
// log

// x = 2^e * m with m in [sqrt(1/2), sqrt(2)], for positive finite x.
struct Mantissa {
  int e;
  double m;
};

Mantissa Decompose(double x) {
  int e = 0;
  if (x < 0x1p-1022) {  // subnormal: scale into the normal range
    x *= 0x1p54;
    e = -54;
  }
  const uint64_t bits = std::bit_cast<uint64_t>(x);
  e += static_cast<int>(bits >> 52) - 1023;
  double m = std::bit_cast<double>((bits & 0x000FFFFFFFFFFFFFull) | 0x3FF0000000000000ull);
  if (m > kSqrt2) {
    m *= 0.5;
    ++e;
  }
  return {e, m};
}

// log(m) for m in [sqrt(1/2), sqrt(2)]: 2 atanh(s) with s = (m-1)/(m+1).
DD LogMantissa(double m) {
  const double f = m - 1.0;  // exact (Sterbenz)
  const DD s = Div(DD{f, 0.0}, TwoSum(2.0, f));
  return Mul(s, Horner<4>(kAtanhSeries, Mul(s, s)));  // s^8/9 < 2^-23
}

// log(x) for positive finite x.
DD LogDD(double x) {
  const Mantissa d = Decompose(x);
  return Add(Mul(kLn2, static_cast<double>(d.e)), LogMantissa(d.m));
}

// ---------------------------------------------------------------------------
// sin / cos

// 2/pi in binary: bit i (i = 1, 2, ...) after the point is bit 31 - (i-1)%32
// of word (i-1)/32. Enough for the largest double plus a 192-bit window.
constexpr uint32_t kTwoOverPi[40] = {
    0xA2F9836E, 0x4E441529, 0xFC2757D1, 0xF534DDC0, 0xDB629599, 0x3C439041, 0xFE5163AB, 0xDEBBC561,
    0xB7246E3A, 0x424DD2E0, 0x06492EEA, 0x09D1921C, 0xFE1DEB1C, 0xB129A73E, 0xE88235F5, 0x2EBB4484,
    0xE99C7026, 0xB45F7E41, 0x3991D639, 0x835339F4, 0x9C845F8B, 0xBDF9283B, 0x1FF897FF, 0xDE05980F,
    0xEF2F118B, 0x5A0A6D1F, 0x6D367ECF, 0x27CB09B7, 0x4F463F66, 0x9E5FEA2D, 0x7527BAC7, 0xEBE5F17B,
    0x3D0739F7, 0x8A5292EA, 0x6BFB5FB1, 0x1F8D5D08, 0x56033046, 0xFC7B6BAB, 0xF0CFBC20, 0x9AF4361D};

// 64 bits of the little-endian limb array f starting at bit pos.
uint64_t Bits64(const uint32_t* f, int pos) {
  const int w = pos / 32;
  const int s = pos % 32;
  const uint64_t lo = f[w] | (static_cast<uint64_t>(f[w + 1]) << 32);
  return s == 0 ? lo : (lo >> s) | (static_cast<uint64_t>(f[w + 2]) << (64 - s));
}

struct Reduced {
  int q;  // quadrant, 0..3
  DD r;   // x - (multiple of 4 + q) * pi/2, |r| <= pi/4
};

// Payne-Hanek reduction of a finite ax > pi/4 in integer arithmetic.
// ax = M 2^E (M a 53-bit integer). Bits of 2/pi that would contribute a
// multiple of 4 to ax * 2/pi are skipped; the next 192 bits times M give the
// quadrant and 128 fraction bits with error < 2^-137. No double lies within
// 2^-62 of a multiple of pi/2, so at least 64 of those bits are significant.
Reduced ReduceLarge(double ax) {
  const uint64_t bits = std::bit_cast<uint64_t>(ax);
  const int e = static_cast<int>(bits >> 52) - 1075;
  const uint64_t m = (bits & 0x000FFFFFFFFFFFFFull) | (1ull << 52);
  const int first = e - 1 > 1 ? e - 1 : 1;  // first 2/pi bit that matters (1-based)

  uint32_t window[6];  // little-endian: window[5] holds bits first .. first+31
  for (int n = 0; n < 6; ++n) {
    const int start = first - 1 + 32 * n;
    const int w = start / 32;
    const int s = start % 32;
    const uint32_t hi = kTwoOverPi[w] << s;
    window[5 - n] = s == 0 ? hi : hi | (kTwoOverPi[w + 1] >> (32 - s));
  }

  uint32_t f[10] = {};  // M * window, 256 bits plus zero padding for Bits64
  const uint32_t mw[2] = {static_cast<uint32_t>(m), static_cast<uint32_t>(m >> 32)};
  for (int i = 0; i < 2; ++i) {
    uint64_t carry = 0;
    for (int j = 0; j < 6; ++j) {
      const uint64_t t = static_cast<uint64_t>(mw[i]) * window[j] + f[i + j] + carry;
      f[i + j] = static_cast<uint32_t>(t);
      carry = t >> 32;
    }
    f[i + 6] = static_cast<uint32_t>(carry);
  }

  const int point = first + 191 - e;  // fraction bits in f (190 .. 245)
  int q = static_cast<int>(Bits64(f, point) & 3);
  uint64_t fh = Bits64(f, point - 64);
  uint64_t fl = Bits64(f, point - 128);
  bool negative = false;
  if (fh >> 63) {  // fraction >= 1/2: round to the next quadrant, r = fraction - 1
    q = (q + 1) & 3;
    negative = true;
    fh = ~fh + (fl == 0 ? 1 : 0);
    fl = 0 - fl;
  }
  // Normalise the 128-bit magnitude (fh != 0, see above) and convert to DD.
  const int lz = std::countl_zero(fh);
  const uint64_t top = lz == 0 ? fh : (fh << lz) | (fl >> (64 - lz));
  const uint64_t rest = fl << lz;
  const DD frac =
      FastTwoSum(static_cast<double>(top & ~0x7FFull),
                 static_cast<double>(top & 0x7FF) + static_cast<double>(rest) * 0x1p-64);
  const double scale = 0x1p-64 * Pow2(-lz);
  DD r = Mul(DD{frac.hi * scale, frac.lo * scale}, kPiO2);
  return {q, negative ? Neg(r) : r};
}

Reduced ReducePiO2(double ax) {
  if (ax <= kPiO4.hi) return {0, DD{ax, 0.0}};
  return ReduceLarge(ax);
}

// Plain-double tails: r^8/9! < 2^-21 and r^10/10! < 2^-25.
double SinKernel(DD r) { return Round(Mul(r, Horner<4>(kSinSeries, Mul(r, r)))); }
double CosKernel(DD r) { return Round(Horner<5>(kCosSeries, Mul(r, r))); }

// ---------------------------------------------------------------------------
// atan

// atan(t) for t >= 0 (t.hi may be +inf), as a double-double. The argument is
// reduced to |u| <= 7/16 around the exact points 0, 1/2, 1, 3/2 and infinity.
DD AtanDD(DD t) {
  if (t.hi > 0x1p60) return Add(kPiO2, DD{-1.0 / t.hi, 0.0});  // atan(t) = pi/2 - 1/t
  const DD one{1.0, 0.0};
  DD base{0.0, 0.0};
  DD u = t;
  if (t.hi >= 39.0 / 16) {
    base = kPiO2;
    u = Div(DD{-1.0, 0.0}, t);
  } else if (t.hi >= 19.0 / 16) {
    base = kAtanThreeHalves;
    u = Div(Add(t, DD{-1.5, 0.0}), Add(one, Mul(t, 1.5)));
  } else if (t.hi >= 11.0 / 16) {
    base = kPiO4;
    u = Div(Add(t, DD{-1.0, 0.0}), Add(t, one));
  } else if (t.hi >= 7.0 / 16) {
    base = kAtanHalf;
    u = Div(Add(t, DD{-0.5, 0.0}), Add(one, Mul(t, 0.5)));
  }
  return Add(base, Mul(u, Horner<8>(kAtanSeries, Mul(u, u))));  // u^16/17 < 2^-23
}

// ---------------------------------------------------------------------------
// Normal distribution helpers

// erf(z) for |z| <= 1.5 by its Taylor series in double-double, so that
// 1 - erf(z) keeps full precision too.
DD ErfDD(double z) { return Mul(Mul(kTwoOverSqrtPi, z), Horner<32>(kErfSeries, TwoProd(z, z))); }

// erfcx(z) = exp(z^2) erfc(z) for z >= 0.45: 1 - erf below 1.5, else the even
// part of Laplace's continued fraction, 60 levels evaluated bottom-up
// (truncation < 1e-18 at z = 1.5).
double Erfcx(double z) {
  if (z < 1.5) return ExpDD(TwoProd(z, z)) * Round(Add(DD{1.0, 0.0}, Neg(ErfDD(z))));
  const double z2 = z * z;
  double t = 0.0;
  for (int n = 60; n >= 1; --n)
    t = ((2.0 * n - 1.0) * (2.0 * n) / 4.0) / (z2 + (4.0 * n + 1.0) / 2.0 - t);
  return kInvSqrtPi * z / (z2 + 0.5 - t);
}

// Acklam's rational approximation of the quantile for p in (0, 0.5].
double AcklamLower(double p) {
  constexpr double a[6] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                           1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  constexpr double b[5] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                           6.680131188771972e+01, -1.328068155288572e+01};
  constexpr double c[6] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                           -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  constexpr double d[4] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                           3.754408661907416e+00};
  if (p < 0.02425) {
    const double q = std::sqrt(-2.0 * Round(LogDD(p)));  // IEEE sqrt: correctly rounded
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  }
  const double q = p - 0.5;
  const double r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
}

// Quantile for p in (0, 0.5]: Acklam, then one Halley step
// x -= u / (1 + x u / 2) with u = (Phi(x) - p) / phi(x), evaluated without
// cancellation: near the centre from erf and the exact 0.5 - p, in the tail as
// sqrt(2 pi) (erfcx(-x/sqrt2)/2 - exp(x^2/2 + log p)).
double LowerQuantile(double p) {
  const double x = AcklamLower(p);
  const DD x2 = TwoProd(x, x);
  const DD t{0.5 * x2.hi, 0.5 * x2.lo};  // x^2 / 2, exact
  double u;
  if (p >= 0.25) {
    u = kSqrt2Pi * ExpDD(t) * (0.5 * Round(ErfDD(x * kInvSqrt2)) + (0.5 - p));
  } else {
    u = kSqrt2Pi * (0.5 * Erfcx(-x * kInvSqrt2) - ExpDD(Add(t, LogDD(p))));
  }
  return x - u / (1.0 + 0.5 * x * u);
}

}  // namespace

// ---------------------------------------------------------------------------

double Exp(double x) { return ExpDD(DD{x, 0.0}); }

double Exp2(double x) {
  if (x != x) return x;
  if (x >= 1024.0) return kInf;
  if (x <= -1075.0) return 0.0;
  const int k = NearestInt(x);
  const double r = x - static_cast<double>(k);  // exact, |r| <= 1/2
  return Scale(Round(Horner<6>(kExpSeries, Mul(kLn2, r))), k);
}

double Log(double x) {
  if (!(x > 0.0)) return x == 0.0 ? -kInf : kNaN;
  if (x == kInf) return x;
  return Round(LogDD(x));
}

double Log2(double x) {
  if (!(x > 0.0)) return x == 0.0 ? -kInf : kNaN;
  if (x == kInf) return x;
  const Mantissa d = Decompose(x);
  return Round(Add(DD{static_cast<double>(d.e), 0.0}, Mul(LogMantissa(d.m), kInvLn2)));
}

double Pow(double x, double y) {
  if (y == 0.0 || x == 1.0) return 1.0;
  if (x != x || y != y || x < 0.0) return kNaN;
  if (x == 0.0) return y > 0.0 ? 0.0 : kInf;
  if (x == kInf) return y > 0.0 ? kInf : 0.0;
  if (y == kInf) return x > 1.0 ? kInf : 0.0;
  if (y == -kInf) return x > 1.0 ? 0.0 : kInf;
  const DD l = LogDD(x);
  const double approx = y * l.hi;  // decides overflow before any split of a huge y
  if (approx > 710.0) return kInf;
  if (approx < -746.0) return 0.0;
  return ExpDD(Mul(l, y));
}

namespace {

// The error of PowFast, step by step (u = 2^-53):
//   log(m) = 2 s P(s^2), |s| <= 0.172: s = f / (2 + f) with f exact, two
//     roundings; 11 terms leave < 2^-57; Horner's rule in double < 3u: < 6u
//     relative, |log m| <= 0.347;
//   log(x) = e ln2_hi + (e ln2_lo + log m): e ln2_hi is exact (ln2_hi has 21
//     trailing zero bits, |e| <= 1074); where e != 0, |log x| >= 0.346, so
//     log m's error and the two roundings stay < 9u relative;
//   t = y log(x): one more rounding, < 10u |t| absolute;
//   e^t = 2^k e^r: k ln2_hi exact, t - k ln2_hi exact (Sterbenz), minus
//     k ln2_lo one rounding; 14 terms of e^r (|r| <= 0.35) leave < 2^-57;
//     Horner < 3u; the scaling by 2^k exact (normal results).
// Relative error < 10u |t| + 5u, below 2^-43.6 for |t| <= kPowFastMaxT.
constexpr double kLn2Hi = 0x1.62e42feep-1;  // ln 2's first 32 bits: k ln2_hi exact for |k| < 2^21
constexpr double kLn2Lo = 0x1.a39ef35793c76p-33;
constexpr int kPowFastLogTerms = 11, kPowFastExpTerms = 14;
constexpr double kPowFastMaxT = 64.0;  // |y ln x| beyond: Pow

double PowFastKernel(double x, double y) {
  const Mantissa d = Decompose(x);
  const double f = d.m - 1.0;  // exact (Sterbenz)
  const double s = f / (2.0 + f);
  const double s2 = s * s;
  double p = 0.0;
  for (int j = kPowFastLogTerms - 1; j >= 0; --j) p = p * s2 + kAtanhSeries.c[j].hi;
  const double e = static_cast<double>(d.e);
  const double log_x = e * kLn2Hi + (e * kLn2Lo + s * p);
  const double t = y * log_x;
  if (!(t >= -kPowFastMaxT && t <= kPowFastMaxT)) return Pow(x, y);
  const int k = NearestInt(t * kInvLn2.hi);
  const double kd = static_cast<double>(k);
  const double r = (t - kd * kLn2Hi) - kd * kLn2Lo;
  double q = 0.0;
  for (int n = kPowFastExpTerms - 1; n >= 0; --n) q = q * r + kExpSeries.c[n].hi;
  return q * Pow2(k);
}

}  // namespace

double PowFast(double x, double y) {
  if (!(x > 0.0 && x < kInf) || y - y != 0.0) return Pow(x, y);  // zero, negative, infinite, NaN
  return PowFastKernel(x, y);
}

double Sin(double x) {
  if (x - x != 0.0) return kNaN;  // infinite or NaN
  if (x == 0.0) return x;         // keeps the sign of zero
  const Reduced red = ReducePiO2(x < 0.0 ? -x : x);
  double s = 0.0;
  switch (red.q) {
    case 0:
      s = SinKernel(red.r);
      break;
    case 1:
      s = CosKernel(red.r);
      break;
    case 2:
      s = -SinKernel(red.r);
      break;
    default:
      s = -CosKernel(red.r);
      break;
  }
  return x < 0.0 ? -s : s;
}

double Cos(double x) {
  if (x - x != 0.0) return kNaN;
  const Reduced red = ReducePiO2(x < 0.0 ? -x : x);
  switch (red.q) {
    case 0:
      return CosKernel(red.r);
    case 1:
      return -SinKernel(red.r);
    case 2:
      return -CosKernel(red.r);
    default:
      return SinKernel(red.r);
  }
}

double Atan(double x) {
  if (x != x || x == 0.0) return x;
  const double a = Round(AtanDD(DD{x < 0.0 ? -x : x, 0.0}));
  return x < 0.0 ? -a : a;
}

double Atan2(double y, double x) {
  if (x != x || y != y) return kNaN;
  const bool neg_y = SignBit(y);
  const bool neg_x = SignBit(x);
  double a = neg_y ? -y : y;
  double b = neg_x ? -x : x;
  DD angle;  // atan(a / b) in [0, pi/2], then reflected for x < 0
  if (a == kInf && b == kInf) {
    angle = kPiO4;
  } else if (a == 0.0 || b == kInf) {
    angle = DD{0.0, 0.0};
  } else if (b == 0.0 || a == kInf) {
    angle = kPiO2;
  } else if (a > b * 0x1p60 || a < b * 0x1p-60) {
    angle = AtanDD(DD{a / b, 0.0});  // far from 1: the rounded ratio is enough
  } else {
    // Bring both into a range where the double-double division cannot overflow.
    if (a > 0x1p500 || b > 0x1p500) {
      a *= 0x1p-600;
      b *= 0x1p-600;
    } else if (a < 0x1p-500 || b < 0x1p-500) {
      a *= 0x1p600;
      b *= 0x1p600;
    }
    angle = AtanDD(Div(DD{a, 0.0}, DD{b, 0.0}));
  }
  if (neg_x) angle = Add(kPi, Neg(angle));
  const double r = Round(angle);
  return neg_y ? -r : r;
}

double NormalCdf(double x) {
  if (x != x) return x;
  if (x < -40.0) return 0.0;
  if (x > 40.0) return 1.0;
  const DD z = Mul(kInvSqrt2DD, x);  // x / sqrt 2; erf and erfc below take z.hi
  const DD x2 = TwoProd(x, x);
  const double g = ExpDD(DD{-0.5 * x2.hi, -0.5 * x2.lo});  // exp(-z^2), from the exact x^2 / 2
  if (z.hi >= -1.5 && z.hi <= 1.5) {
    // 1/2 + erf(z.hi) / 2, plus erf's slope times z.lo (the rounding of z).
    return Round(Add(Add(DD{0.5, 0.0}, Mul(ErfDD(z.hi), 0.5)), DD{kInvSqrtPi * g * z.lo, 0.0}));
  }
  const double tail = 0.5 * Erfcx(z.hi < 0 ? -z.hi : z.hi) * g;  // erfc(|z|) / 2
  return z.hi < 0 ? tail : 1.0 - tail;
}

double InvNormalCdf(double p) {
  if (!(p > 0.0 && p < 1.0)) {
    if (p == 0.0) return -kInf;
    return p == 1.0 ? kInf : kNaN;
  }
  return p > 0.5 ? -LowerQuantile(1.0 - p) : LowerQuantile(p);
}

}  // namespace camsim::detmath
