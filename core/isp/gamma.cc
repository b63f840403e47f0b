#include "core/isp/gamma.h"

#include <cstring>

#include "core/base/detmath.h"
#include "core/base/simd.h"

namespace camsim {
namespace {

constexpr double kFullScale = 65535.0;
constexpr uint32_t kMaxCode = 65535;

// IEC 61966-2-1 (sRGB) encoding constants.
constexpr double kSrgbLinearLimit = 0.0031308;
constexpr double kSrgbSlope = 12.92;
constexpr double kSrgbScale = 1.055;
constexpr double kSrgbOffset = 0.055;
constexpr double kSrgbExponent = 1.0 / 2.4;

// out[x] = table[min(in[x], kMaxCode)] for x < n. The AVX-512 and AVX2 loops
// gather 32 bits at byte offset 2 * code: the entry in the low half (x86 is
// little-endian) and its upper neighbour, which the mask drops (the table's
// spare entry keeps the last read inside it).
#ifdef CAMSIM_X86_AVX512
CAMSIM_AVX512_TARGET void LookUpAvx512(const uint16_t* table, const uint32_t* in, uint32_t* out, int n) {
  const __m512i max_code = _mm512_set1_epi32(kMaxCode);
  const __m512i low16 = _mm512_set1_epi32(0xFFFF);
  for (int x = 0; x < n; x += 16) {
    const __m512i code = _mm512_min_epu32(_mm512_loadu_si512(in + x), max_code);
    // A mask GCC cannot prove full: see ISqrt64x8 (core/base/fixed.cc).
    const __mmask16 all = _mm512_cmple_epu32_mask(code, max_code);
    const __m512i pair = _mm512_mask_i32gather_epi32(_mm512_setzero_si512(), all, code, table, 2);
    _mm512_storeu_si512(out + x, _mm512_and_si512(pair, low16));
  }
}
#endif
#ifdef CAMSIM_X86_AVX2
CAMSIM_AVX2_TARGET void LookUpAvx2(const uint16_t* table, const uint32_t* in, uint32_t* out, int n) {
  const __m256i max_code = _mm256_set1_epi32(kMaxCode);
  const __m256i low16 = _mm256_set1_epi32(0xFFFF);
  for (int x = 0; x < n; x += 8) {
    const __m256i code = _mm256_min_epu32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(in + x)), max_code);
    const __m256i all = _mm256_cmpeq_epi32(code, code);
    const __m256i pair = _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), reinterpret_cast<const int*>(table),
                                                     code, all, 2);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + x), _mm256_and_si256(pair, low16));
  }
}
#endif

}  // namespace

Status GammaStage::Configure(const GammaConfig& c, const SensorGeometry& /*geometry*/) {
  if (c.curve != GammaCurve::kLinear && c.curve != GammaCurve::kSrgb && c.curve != GammaCurve::kPower)
    return InvalidArgument("gamma.curve", "must be linear, srgb or power");
  if (!(c.gamma >= kMinGamma && c.gamma <= kMaxGamma))
    return InvalidArgument("gamma.gamma", "must be in [0.1, 10]");
  config_ = c;
  return Status::Ok();
}

Result<LineFormat> GammaStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kLinear) return InvalidArgument("gamma", "needs linear input");
  return LineFormat{Domain::kEncoded, in.channels, in.mosaic};
}

const char* GammaStage::IdentityReason() const {
  return config_.curve == GammaCurve::kLinear ? "gamma curve is linear" : nullptr;
}

double GammaStage::Curve(double v) const { return CurveWith(v, detmath::Pow); }

double GammaStage::CurveWith(double v, double (*pow)(double, double)) const {
  switch (config_.curve) {
    case GammaCurve::kLinear: return v;
    case GammaCurve::kSrgb:
      return v <= kSrgbLinearLimit ? kSrgbSlope * v : kSrgbScale * pow(v, kSrgbExponent) - kSrgbOffset;
    case GammaCurve::kPower: return pow(v, 1.0 / config_.gamma);
  }
  return v;
}

// One spare entry after the table: see LookUpAvx512.
void GammaStage::CountTables(WorkspaceCounter& counter) const { counter.Add<uint16_t>(kTableSize + 1); }

// Entry i is round(65535 Curve(i / 65535)), clamped, with Curve's Pow
// (double-double, ~0.3 us a call: 65536 calls were most of a 1080p demo
// pipeline's configuration). PowFast (relative error < kPowFastError) gives
// the same integer unless its value lies within kTieMargin of a rounding
// boundary (clamping does not widen the difference), and only those entries
// take Pow: none or a few per table.
constexpr double kTieMargin = 1e-6;
static_assert(kTieMargin > 4 * kFullScale * detmath::kPowFastError, "the margin covers PowFast's error");

Status GammaStage::Init(Arena& tables) {
  table_ = tables.Take<uint16_t>(kTableSize + 1);
  if (table_ == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for the gamma table");
  auto scaled = [this](double v, double (*pow)(double, double)) {
    const double t = CurveWith(v, pow) * kFullScale;
    return t < 0.0 ? 0.0 : (t > kFullScale ? kFullScale : t);
  };
  for (size_t i = 0; i < kTableSize; ++i) {
    const double v = static_cast<double>(i) / kFullScale;
    double t = scaled(v, detmath::PowFast);
    const double up = t + 0.5;  // in [0.5, 65535.5], as the rounding below sees it
    const double frac = up - static_cast<double>(static_cast<uint32_t>(up));
    if (frac < kTieMargin || frac > 1.0 - kTieMargin) t = scaled(v, detmath::Pow);
    table_[i] = static_cast<uint16_t>(t + 0.5);  // round to nearest, ties up
  }
  table_[kTableSize] = 0;
  avx2_ = CpuHasAvx2();
  avx512_ = CpuHasAvx512();
  return Status::Ok();
}

Status GammaStage::InitFrom(Arena& tables, const Stage& previous, int* copied) {
  const GammaStage& p = static_cast<const GammaStage&>(previous);  // the same class (Stage::InitFrom)
  *copied = 0;
  if (&p == this || p.table_ == nullptr || p.config_.curve != config_.curve ||
      !SameBits(p.config_.gamma, config_.gamma))
    return Init(tables);
  table_ = tables.Take<uint16_t>(kTableSize + 1);
  if (table_ == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for the gamma table");
  std::memcpy(table_, p.table_, (kTableSize + 1) * sizeof(uint16_t));
  avx2_ = p.avx2_;
  avx512_ = p.avx512_;
  *copied = 1;
  return Status::Ok();
}

void GammaStage::ProcessRow(const RowArgs& a) const {
  const int channels = a.out[1] != nullptr ? 3 : 1;
  // Locals: a store through out (uint32_t) could alias a.width (int), and
  // would make the compiler reload it every sample.
  const uint16_t* table = table_;
  const int width = a.width;
  for (int c = 0; c < channels; ++c) {
    const uint32_t* in = a.rows[0].ch[c];
    uint32_t* out = a.out[c];
    int x = 0;
#ifdef CAMSIM_X86_AVX512
    if (avx512_) {
      x = width & ~15;
      LookUpAvx512(table, in, out, x);
    } else
#endif
#ifdef CAMSIM_X86_AVX2
    if (avx2_) {
      x = width & ~7;
      LookUpAvx2(table, in, out, x);
    }
#endif
    for (; x < width; ++x) out[x] = table[in[x] < kMaxCode ? in[x] : kMaxCode];
  }
}

}  // namespace camsim
