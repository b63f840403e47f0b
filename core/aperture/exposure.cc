#include "core/aperture/exposure.h"

#include "core/base/simd.h"

namespace camsim {
namespace {

// f.Apply(v) for 1 <= f.shift <= 63, bit for bit, in a form compilers
// vectorise: the saturation is tested on the 32-bit high half (a 64-bit
// compare does not vectorise on every target, e.g. x86-64 without SSE4.2).
inline uint32_t ScaleInRange(uint32_t mant, int shift, uint32_t v) {
  const uint64_t p = uint64_t{v} * mant;
  const uint64_t r = (p >> shift) + ((p >> (shift - 1)) & 1);  // RoundShiftU(p, shift)
  const uint32_t high = static_cast<uint32_t>(r >> 32), low = static_cast<uint32_t>(r);
  return low | (0u - static_cast<uint32_t>(high != 0));  // SatU32(r)
}

// Apply's own special cases (factor >= 2^31 or < 2^-32) are left to Apply.
bool InRange(UScale f) { return f.shift >= 1 && f.shift <= 63; }

// dst[x] = f.Apply(src[x]) for a row, bit for bit (the shift is checked once
// per row).
CAMSIM_CPU_CLONES
void ScaleRow(UScale f, const uint32_t* __restrict src, uint32_t* __restrict dst, int width) {
  if (!InRange(f)) {
    for (int x = 0; x < width; ++x) dst[x] = f.Apply(src[x]);
    return;
  }
  const uint32_t mant = f.mant;
  const int shift = f.shift;
  for (int x = 0; x < width; ++x) dst[x] = ScaleInRange(mant, shift, src[x]);
}

// Site-only row (see exposure.h): colour A's sites are the even columns,
// colour B's the odd ones; each pixel scales only its site's sample (one
// multiply instead of three) and writes 0 to the other channels. Blocks of
// kBlock columns with the even-column mask in a table, as core/isp/demosaic.cc
// does, so that the loop vectorises; the tail takes the mask from x.
constexpr int kBlock = 16;  // one AVX-512 vector; even, so that every block starts at an even column

inline void ScaleSitePixel(uint32_t mant, int shift, const uint32_t* __restrict in_a,
                           const uint32_t* __restrict in_b, int x, uint32_t at_a, uint32_t* __restrict out_a,
                           uint32_t* __restrict out_b, uint32_t* __restrict out_c) {
  const uint32_t site = (in_a[x] & at_a) | (in_b[x] & ~at_a);
  const uint32_t v = ScaleInRange(mant, shift, site);
  out_a[x] = v & at_a;
  out_b[x] = v & ~at_a;
  out_c[x] = 0;
}

inline uint32_t EvenMask(int x) { return 0u - static_cast<uint32_t>((x & 1) == 0); }

CAMSIM_CPU_CLONES
void ScaleSiteRow(UScale f, const uint32_t* __restrict in_a, const uint32_t* __restrict in_b,
                  uint32_t* __restrict out_a, uint32_t* __restrict out_b, uint32_t* __restrict out_c, int width) {
  if (!InRange(f)) {
    for (int x = 0; x < width; ++x) {
      const bool at_a = (x & 1) == 0;
      const uint32_t v = f.Apply(at_a ? in_a[x] : in_b[x]);
      out_a[x] = at_a ? v : 0;
      out_b[x] = at_a ? 0 : v;
      out_c[x] = 0;
    }
    return;
  }
  const uint32_t mant = f.mant;
  const int shift = f.shift;
  uint32_t mask[kBlock];
  for (int k = 0; k < kBlock; ++k) mask[k] = EvenMask(k);
  int x0 = 0;
  for (; x0 + kBlock <= width; x0 += kBlock)
    for (int k = 0; k < kBlock; ++k) ScaleSitePixel(mant, shift, in_a, in_b, x0 + k, mask[k], out_a, out_b, out_c);
  for (int x = x0; x < width; ++x) ScaleSitePixel(mant, shift, in_a, in_b, x, EvenMask(x), out_a, out_b, out_c);
}

}  // namespace

double ExposurePhotonsPerRadiance(const ExposureConfig& c) {
  return c.photons_per_radiance_ms * (c.exposure_time_us / 1000.0) / (c.f_number * c.f_number);
}

double ReferenceExposure(const ExposureConfig& config, double radiance) {
  return radiance * ExposurePhotonsPerRadiance(config);
}

Status ExposureStage::Configure(const ExposureConfig& c) {
  // Limits: 1 us .. 100 s; f/0.5 .. f/128 (wider than any real lens).
  if (!(c.exposure_time_us >= 1.0 && c.exposure_time_us <= 1e8))
    return InvalidArgument("exposure.exposure_time_us", "must be in [1, 1e8] microseconds");
  if (!(c.f_number >= 0.5 && c.f_number <= 128.0))
    return InvalidArgument("exposure.f_number", "must be in [0.5, 128]");
  if (!(c.photons_per_radiance_ms > 0.0 && c.photons_per_radiance_ms <= 1e9))
    return InvalidArgument("exposure.photons_per_radiance_ms", "must be in (0, 1e9]");
  // Q16.16 in, Q24.8 out: the raw factor is the physical one times 2^-8.
  Result<UScale> f = UScale::FromDouble(ExposurePhotonsPerRadiance(c) / 256.0,
                                        "exposure.photons_per_radiance_ms");
  if (!f.ok()) return f.status();
  factor_ = f.value();
  site_cfa_ = Cfa::kMono;
  return Status::Ok();
}

Result<LineFormat> ExposureStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kRadiance || in.channels != 3)
    return InvalidArgument("exposure", "needs RGB radiance input");
  return LineFormat{Domain::kPhotons, 3, false};
}

void ExposureStage::ProcessRow(const RowArgs& a) const {
  if (site_cfa_ != Cfa::kMono) {
    const Colour even = CfaColour(site_cfa_, 0, a.y), odd = CfaColour(site_cfa_, 1, a.y);
    const Colour third = static_cast<Colour>(3 - even - odd);  // the colour this row has no site of
    ScaleSiteRow(factor_, a.rows[0].ch[even], a.rows[0].ch[odd], a.out[even], a.out[odd], a.out[third], a.width);
    return;
  }
  for (int c = 0; c < 3; ++c) ScaleRow(factor_, a.rows[0].ch[c], a.out[c], a.width);
}

}  // namespace camsim
