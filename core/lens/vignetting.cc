#include "core/lens/vignetting.h"

#include "core/base/simd.h"
#include "core/pipeline/pipeline.h"

namespace camsim {
namespace {

constexpr double kMaxGain = 4.0 - 1.0 / 16384.0;  // Q2.14 ceiling
constexpr int kGainFracBits = VignettingStage::kGainFracBits;
// Columns whose curve gains are computed at once, then applied to every
// channel: 1 KiB of stack.
constexpr int kGainBlock = 256;

uint64_t Denominator(const SensorGeometry& g) {
  const uint64_t w = static_cast<uint64_t>(g.width - 1), h = static_cast<uint64_t>(g.height - 1);
  return w * w + h * h;
}

double Rho(const SensorGeometry& g, int x, int y) {
  const uint64_t den = Denominator(g);
  if (den == 0) return 0.0;
  const double dx = 2.0 * x - (g.width - 1), dy = 2.0 * y - (g.height - 1);
  return (dx * dx + dy * dy) / static_cast<double>(den);
}

double CurveGainOf(const VignettingConfig& c, const SensorGeometry& g, double rho) {
  if (c.mode == VignettingMode::kCos4) {
    // r^2 in pixels: rho * ((W-1)^2 + (H-1)^2) / 4.
    const double r2 = rho * static_cast<double>(Denominator(g)) / 4.0;
    const double t = 1.0 + r2 / (c.focal_length_px * c.focal_length_px);
    return 1.0 / (t * t);
  }
  if (c.mode == VignettingMode::kTable) {
    const double pos = rho * (c.table_count - 1);
    int i = static_cast<int>(pos);
    if (i >= c.table_count - 1) return c.table[c.table_count - 1];
    const double f = pos - i;
    return c.table[i] + (c.table[i + 1] - c.table[i]) * f;
  }
  return 1.0;
}

// SatU32(RoundShiftU(v * g, 14)) for a Q2.14 gain g, in a form compilers
// vectorise: a gain is below 2^16, so the product is below 2^48 and adding
// the rounding half cannot overflow; the saturation is tested on the 32-bit
// high half (a 64-bit compare does not vectorise on every target, e.g.
// x86-64 without SSE4.2).
inline uint32_t ApplyGain(uint32_t v, uint32_t g) {
  const uint64_t t = uint64_t{v} * g + (1u << (kGainFracBits - 1));
  const uint32_t high = static_cast<uint32_t>(t >> (32 + kGainFracBits));
  const uint32_t low = static_cast<uint32_t>(t >> kGainFracBits);
  return low | (0u - static_cast<uint32_t>(high != 0));
}

// out[x] = ApplyGain(in[x], gain[x]) for one channel: curve gains (uint32)
// or a mask's (uint16). Functions of their own, compiled twice: the AVX2
// copy takes eight columns a step, where the SSE2 loop took four.
CAMSIM_CPU_CLONES
void ApplyGains(const uint32_t* __restrict in, const uint32_t* __restrict gain, uint32_t* __restrict out, int n) {
  for (int x = 0; x < n; ++x) out[x] = ApplyGain(in[x], gain[x]);
}
CAMSIM_CPU_CLONES
void ApplyGains(const uint32_t* __restrict in, const uint16_t* __restrict gain, uint32_t* __restrict out, int n) {
  for (int x = 0; x < n; ++x) out[x] = ApplyGain(in[x], gain[x]);
}

// The gains of one row applied to columns [x0, x0 + n) of every channel (3,
// or 1 for a mosaic). Not CAMSIM_CPU_CLONES: ApplyGains has its own.
template <typename Gain>
void ApplyRow(const RowArgs& a, int channels, const Gain* __restrict gain, int x0, int n) {
  for (int c = 0; c < channels; ++c) ApplyGains(a.rows[0].ch[c] + x0, gain, a.out[c] + x0, n);
}

// A block's curve gains from column k0 on, gain[k] for column x0 + k
// (k0 <= k < n), and the same reversed, mirrored[n - 1 - k] = gain[k], for
// the mirror image block (unless mirrored is null).
void CurveGains(const uint16_t* curve, UScale rho_to_index, const uint32_t* dx2, uint32_t dy2, int k0, int n,
                uint32_t* gain, uint32_t* mirrored) {
  for (int k = k0; k < n; ++k) gain[k] = VignettingCurveGain(curve, rho_to_index, dx2[k] + dy2);
  for (int k = k0; mirrored != nullptr && k < n; ++k) mirrored[n - 1 - k] = gain[k];
}

#ifdef CAMSIM_X86_AVX2
// RoundShiftU(p, s) of four 64-bit lanes, 1 <= s <= 63.
CAMSIM_AVX2_TARGET inline __m256i RoundShift4(__m256i p, __m128i s, __m128i s_less_1) {
  return _mm256_add_epi64(_mm256_srl_epi64(p, s), _mm256_and_si256(_mm256_srl_epi64(p, s_less_1), _mm256_set1_epi64x(1)));
}

// CurveGains for k < n8 (a multiple of 8) in eight 32-bit lanes, the same integers
// as VignettingCurveGain: UScale::Apply as two sets of four 64-bit products
// (even and odd columns), rounded by the uniform shift (1..63 here, see
// Init); then both curve points of a column from one 32-bit gather
// (curve[i] low, curve[i + 1] high). dx2 + dy2 <= the denominator, so the
// position is at most (kCurvePoints - 1) 2^16: Apply's saturation is never
// reached, and the read ends inside the table (as the scalar one does).
CAMSIM_AVX2_TARGET void CurveGainsAvx2(const uint16_t* curve, UScale rho_to_index, const uint32_t* dx2,
                                       uint32_t dy2, int n8, int n, uint32_t* gain, uint32_t* mirrored) {
  const __m256i mant = _mm256_set1_epi64x(rho_to_index.mant);
  const __m128i shift = _mm_cvtsi32_si128(rho_to_index.shift);
  const __m128i shift_less_1 = _mm_cvtsi32_si128(rho_to_index.shift - 1);
  const __m256i low16 = _mm256_set1_epi32(0xFFFF), unit = _mm256_set1_epi32(0x10000);
  const __m256i reverse = _mm256_setr_epi32(7, 6, 5, 4, 3, 2, 1, 0);
  for (int k = 0; k < n8; k += 8) {
    const __m256i v = _mm256_add_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(dx2 + k)),
                                       _mm256_set1_epi32(static_cast<int>(dy2)));
    const __m256i even = RoundShift4(_mm256_mul_epu32(v, mant), shift, shift_less_1);
    const __m256i odd = RoundShift4(_mm256_mul_epu32(_mm256_srli_epi64(v, 32), mant), shift, shift_less_1);
    const __m256i pos = _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
    const __m256i i = _mm256_srli_epi32(pos, 16), f = _mm256_and_si256(pos, low16);
    const __m256i g01 = _mm256_i32gather_epi32(reinterpret_cast<const int*>(curve), i, 2);
    const __m256i g0 = _mm256_and_si256(g01, low16), g1 = _mm256_srli_epi32(g01, 16);
    const __m256i sum = _mm256_add_epi32(_mm256_add_epi32(_mm256_mullo_epi32(g0, _mm256_sub_epi32(unit, f)),
                                                          _mm256_mullo_epi32(g1, f)),
                                         _mm256_set1_epi32(0x8000));
    const __m256i g = _mm256_srli_epi32(sum, 16);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(gain + k), g);
    if (mirrored != nullptr)
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(mirrored + n - 8 - k), _mm256_permutevar8x32_epi32(g, reverse));
  }
}
#endif

}  // namespace

void VignettingCurveGains(const uint16_t* curve, UScale rho_to_index, const uint32_t* dx2, uint32_t dy2, int n,
                          uint32_t* gain) {
  int k0 = 0;
#ifdef CAMSIM_X86_AVX2
  if (CpuHasAvx2() && rho_to_index.shift >= 1 && rho_to_index.shift <= 63) {  // as VignettingStage::Init
    k0 = n & ~7;
    CurveGainsAvx2(curve, rho_to_index, dx2, dy2, k0, n, gain, nullptr);
  }
#endif
  CurveGains(curve, rho_to_index, dx2, dy2, k0, n, gain, nullptr);
}

double ReferenceVignettingGain(const VignettingConfig& c, const SensorGeometry& g, int x, int y) {
  return CurveGainOf(c, g, Rho(g, x, y));
}

Status BuildVignettingCurve(const VignettingConfig& c, const SensorGeometry& g, uint16_t* curve,
                            UScale* rho_to_index) {
  constexpr int kPoints = VignettingStage::kCurvePoints;
  for (int i = 0; i < kPoints; ++i) {
    const double gain = CurveGainOf(c, g, static_cast<double>(i) / (kPoints - 1));
    curve[i] = static_cast<uint16_t>(Q<2, 14>::FromDouble(gain).raw);
  }
  curve[kPoints] = curve[kPoints - 1];  // lets rho == 1 interpolate without a branch
  *rho_to_index = UScale{};
  // Index scale: (kCurvePoints - 1) * 2^16 / denominator; denominator < 2^31 for frames < 32768 px.
  const uint64_t den = Denominator(g);
  if (den > 0) {
    Result<UScale> s = UScale::FromDouble((kPoints - 1) * 65536.0 / static_cast<double>(den), "sensor.width");
    if (!s.ok()) return s.status();
    *rho_to_index = s.value();
  }
  return Status::Ok();
}

double VignettingStage::CurveGain(double rho) const { return CurveGainOf(config_, geometry_, rho); }

Status VignettingStage::Configure(const VignettingConfig& c, const SensorGeometry& g, bool has_mask) {
  config_ = c;
  geometry_ = g;
  switch (c.mode) {
    case VignettingMode::kOff:
      break;
    case VignettingMode::kCos4:
      if (!(c.focal_length_px >= 1.0 && c.focal_length_px <= 1e6))
        return InvalidArgument("vignetting.focal_length_px", "must be in [1, 1e6] pixels for cos4");
      break;
    case VignettingMode::kTable:
      if (c.table_count < 2 || c.table_count > VignettingConfig::kMaxTable)
        return InvalidArgument("vignetting.table", "needs 2 to 64 gains (centre to corner)");
      for (int i = 0; i < c.table_count; ++i)
        if (!(c.table[i] >= 0.0 && c.table[i] <= kMaxGain))
          return InvalidArgument("vignetting.table", "gains must be in [0, 3.9999]");
      break;
    case VignettingMode::kMask:
      if (!has_mask) return InvalidArgument("vignetting.mode", "'mask' needs a mask image (vignetting.mask)");
      break;
    default: return InvalidArgument("vignetting.mode", "must be off, cos4, table or mask");
  }
  // Index scale: (kCurvePoints - 1) * 2^16 / denominator; denominator < 2^31 for frames < 32768 px.
  const uint64_t den = Denominator(g);
  if (den > 0) {
    Result<UScale> s = UScale::FromDouble((kCurvePoints - 1) * 65536.0 / static_cast<double>(den),
                                          "sensor.width");
    if (!s.ok()) return s.status();
    rho_to_index_ = s.value();
  }
  return Status::Ok();
}

Result<LineFormat> VignettingStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kPhotons) return InvalidArgument("vignetting", "needs photons input");
  return in;
}

const char* VignettingStage::IdentityReason() const {
  if (config_.mode == VignettingMode::kOff) return "vignetting.mode is off";
  if (config_.mode == VignettingMode::kTable) {
    for (int i = 0; i < config_.table_count; ++i)
      if (config_.table[i] != 1.0) return nullptr;
    return "vignetting table is flat 1.0";
  }
  return nullptr;
}

void VignettingStage::CountTables(WorkspaceCounter& counter) const {
  counter.Add<uint16_t>(kCurvePoints + 1);
  counter.Add<uint32_t>(static_cast<size_t>(geometry_.width));
}

Status VignettingStage::Init(Arena& tables) {
  curve_ = tables.Take<uint16_t>(kCurvePoints + 1);
  dx2_ = tables.Take<uint32_t>(static_cast<size_t>(geometry_.width));
  if (curve_ == nullptr || dx2_ == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for vignetting tables");
  UScale unused;
  CAMSIM_TRY(BuildVignettingCurve(config_, geometry_, curve_, &unused));
  for (int x = 0; x < geometry_.width; ++x) {
    const int64_t d = 2 * static_cast<int64_t>(x) - (geometry_.width - 1);
    dx2_[x] = static_cast<uint32_t>(d * d);
  }
  // The lanes round by a shift of 1..63 (UScale::Apply's general case), the
  // only one a frame of 2 x 1 pixels or more reaches.
  avx2_ = CpuHasAvx2() && rho_to_index_.shift >= 1 && rho_to_index_.shift <= 63 && !force_portable_;
  return Status::Ok();
}

void VignettingStage::ProcessRow(const RowArgs& a) const {
  // Channels: 3 (colour) or 1 (mosaic); the gain does not depend on colour.
  int channels = 0;
  while (channels < kMaxChannels && a.out[channels] != nullptr) ++channels;
  if (config_.mode == VignettingMode::kMask) {
    ApplyRow(a, channels, a.input->vignetting_mask.row(a.y), 0, a.width);
    return;
  }
  // The curve gain depends on x only through dx2, which is symmetric about
  // the centre: gains are computed for blocks of the left half [0, half) and
  // applied to each block and to its mirror image in the right half (for an
  // odd width the centre column is its own mirror, written twice alike).
  CAMSIM_DCHECK(a.width == geometry_.width);
  const int64_t dy = 2 * static_cast<int64_t>(a.y) - (geometry_.height - 1);
  const uint32_t dy2 = static_cast<uint32_t>(dy * dy);
  const int width = a.width, half = (a.width + 1) / 2;
  uint32_t gain[kGainBlock], mirrored[kGainBlock];
  for (int x0 = 0; x0 < half; x0 += kGainBlock) {
    const int n = half - x0 < kGainBlock ? half - x0 : kGainBlock;
    int k0 = 0;
#ifdef CAMSIM_X86_AVX2
    if (avx2_) {
      k0 = n & ~7;
      CurveGainsAvx2(curve_, rho_to_index_, dx2_ + x0, dy2, k0, n, gain, mirrored);
    }
#endif
    CurveGains(curve_, rho_to_index_, dx2_ + x0, dy2, k0, n, gain, mirrored);
    const int mirror = width - x0 - n;  // columns mirror .. width - 1 - x0
    ApplyRow(a, channels, gain, x0, n);
    ApplyRow(a, channels, mirrored, mirror, n);
  }
}

}  // namespace camsim
