// Depth of field and structural blur; formats and method in dof.h.
//
// Why the solver is stable in fixed point. Thomas' algorithm for the matrix
// of dof.h, with p_i the forward pivot (p_0 = 1):
//   p_i = 1 + b_i + b_{i+1} - b_i b_i / p'_{i-1},  p'_{i-1} = p_{i-1} + b_i ...
// is written without any subtraction by tracking r_i = 1 / (pivot minus the
// coupling to the next sample): with e_{i-1} = 1 / (1 + b_i r_{i-1}),
//   r_i = 1 / (1 + b_i e_{i-1}) = D_i / (D_i + b_i),  D_i = 1 + b_i r_{i-1},
// every quantity is a ratio of positive numbers, r and e lie in (0, 1], and
// the eliminated right-hand side u_i = y'_i / e_i obeys
//   u_i = (x_i + b_i e_{i-1} u_{i-1}) / (1 + b_i e_{i-1}) = u_{i-1} + r_i (x_i - u_{i-1}),
// a convex combination; the back substitution y_i = e_i u_i + (1 - e_i) y_{i+1}
// is one too. Rounding a convex step d * w (|w| <= 1) to an integer never
// leaves [0, d], so the maximum principle holds exactly, and a constant line
// is reproduced exactly, for any b (0 .. 2^20) and any ratio of neighbouring
// b. The pivot growth that breaks naive fixed-point Thomas (p up to 1 + 2b,
// products b^2) never appears: D <= 1 + b, and b r <= b < 2^20 in Q.30.
#include "core/lens/dof.h"

#include <bit>
#include <cmath>
#include <cstring>

#include "core/base/simd.h"
#include "core/pipeline/pipeline.h"

namespace camsim {
namespace {

constexpr int kG = dof::kGuardBits;
constexpr int kW = dof::kWeightFracBits;
constexpr uint32_t kOneW = 1u << kW;          // 1.0 in Q2.30
constexpr int kCurvePoints = 257;             // structural curve over rho, as vignetting

// round(n / d * 2^30) for 0 <= n <= d, 0 < d < 2^63. Both are shifted right
// until d < 2^34 (n << 30 then fits 64 bits); d keeps >= 33 significant bits,
// so the quotient's relative error is below 2^-32 plus the final rounding.
inline uint32_t DivQ30(uint64_t n, uint64_t d) {
  const int bits = static_cast<int>(std::bit_width(d));
  const int k = bits > 34 ? bits - 34 : 0;
  n >>= k;
  d >>= k;
  return static_cast<uint32_t>(((n << kW) + (d >> 1)) / d);
}

using dof::MulQ30;

// D = 1 + b r (Q.30) and the next r = D / (D + b).
inline uint64_t DOf(uint32_t b, uint32_t r) {
  return (uint64_t{1} << kW) + RoundShiftU(uint64_t{b} * r, dof::kBetaFracBits);
}
inline uint32_t ROf(uint64_t D, uint32_t b) {
  return DivQ30(D, D + (uint64_t{b} << (kW - dof::kBetaFracBits)));
}

// One forward step's weights, (b_i, r_{i-1}) -> (r_i, e_{i-1} = 1 / D_i),
// keeping the last step's inputs and results: they depend on (b, r) alone, so
// a repeat reuses them with the same bits and no division. Repeats are the
// rule: along a row where b is constant r settles on a fixed point (91 % of
// the row steps of BM_PipelineDof's scene), and neighbouring columns of a
// column tile mostly share b and r (94 % of its downward steps). The empty
// step keeps (0, 0): r is never 0, so no real step matches it (b = 0 reaches
// a step only with skipping off, and gives r = e = 1). kWithE: also compute e.
template <bool kWithE>
struct SweepStep {
  uint32_t b = 0, r = 0;     // the inputs kept
  uint32_t next = 0, e = 0;  // their r_i and (kWithE) e_{i-1}
  void Take(uint32_t b_in, uint32_t r_in) {
    if (b_in == b && r_in == r) return;
    const uint64_t D = DOf(b_in, r_in);
    b = b_in;
    r = r_in;
    next = ROf(D, b_in);
    if constexpr (kWithE) e = DivQ30(kOneW, D);
  }
};

inline uint32_t OutOf(int64_t y) { return SatU32(RoundShift(y, kG)); }

struct Geometry2 {
  static uint64_t Denominator(const SensorGeometry& g) {
    const uint64_t w = static_cast<uint64_t>(g.width - 1), h = static_cast<uint64_t>(g.height - 1);
    return w * w + h * h;
  }
};

// The blur-size limits every DoF method shares.
Status CheckCocLimits(const DofConfig& c) {
  if (!(c.max_coc_px >= 0.25 && c.max_coc_px <= 1023.0))
    return InvalidArgument("dof.max_coc_px", "must be in [0.25, 1023] pixels");
  if (!(c.min_coc_px >= 0.0 && c.min_coc_px <= c.max_coc_px))
    return InvalidArgument("dof.min_coc_px", "must be in [0, dof.max_coc_px]");
  if (!(c.diffusion_scale > 0.0 && c.diffusion_scale <= 1.0))
    return InvalidArgument("dof.diffusion_scale", "must be in (0, 1]");
  return Status::Ok();
}

}  // namespace


// ---------------------------------------------------------------- CocModel

Status CocModel::Configure(const DofConfig& c, double f_number) {
  config_ = c;
  f_number_ = f_number;
  if (!(c.focal_length_mm > 0.0 && c.focal_length_mm <= 10000.0))
    return InvalidArgument("lens.focal_length_mm", "must be in (0, 10000]");
  if (!(c.pixel_pitch_um > 0.0 && c.pixel_pitch_um <= 1000.0))
    return InvalidArgument("sensor.pixel_pitch_um", "depth of field needs a pixel pitch in (0, 1000] um");
  if (!(f_number >= 0.5 && f_number <= 1000.0))
    return InvalidArgument("exposure.f_number", "depth of field needs an f-number in [0.5, 1000]");
  const double f = c.focal_length_mm / 1000.0;
  if (!(c.focus_distance_m > f && c.focus_distance_m <= 1e6))
    return InvalidArgument("dof.focus_distance_m", "must exceed the focal length and be at most 1e6 m");
  CAMSIM_TRY(CheckCocLimits(c));
  const double pitch = c.pixel_pitch_um * 1e-6;
  k_px_m_ = f * f * c.focus_distance_m / (f_number * (c.focus_distance_m - f)) / pitch;
  // |iz - iz_f| in Q12.20 -> pixels Q.8: K' = K_px * 2^8 / 2^20.
  const double kq = k_px_m_ / 4096.0;
  Result<UScale> s = UScale::FromDouble(kq, "dof.focus_distance_m");
  if (!s.ok()) return s.status();
  scale_ = s.value();
  Result<UScale> sd = UScale::FromDouble(kq * 256.0 * c.diffusion_scale, "dof.diffusion_scale");  // Q.16
  if (!sd.ok()) return sd.status();
  diffusion_scale_ = sd.value();
  focus_ = InverseDepthFromMetres(c.focus_distance_m);
  cap_ = static_cast<uint32_t>(Q<10, 8>::FromDouble(c.max_coc_px).raw);
  diffusion_cap_ = static_cast<uint32_t>(Q<10, 16>::FromDouble(c.max_coc_px * c.diffusion_scale).raw);
  // Smallest d with Apply(d) >= min_coc (Apply is monotone): binary search.
  const uint32_t min_raw = static_cast<uint32_t>(Q<10, 8>::FromDouble(c.min_coc_px).raw);
  uint32_t lo = 0, hi = 0xFFFFFFFFu;
  if (scale_.Apply(hi) < min_raw) {
    min_diff_ = hi;
  } else {
    while (lo < hi) {
      const uint32_t mid = lo + (hi - lo) / 2;
      if (scale_.Apply(mid) >= min_raw) hi = mid; else lo = mid + 1;
    }
    min_diff_ = lo;
  }
  return Status::Ok();
}

namespace {
#ifdef CAMSIM_X86_AVX2
// DiffusionCoc squared, four lanes: the scale's RoundShiftU by a shift below
// 64 (a count of 2^64 - 1 for shift 0 makes the rounding bit 0), saturation
// folded into the cap (cap < 2^32).
CAMSIM_AVX2_TARGET void DiffusionCc2Avx2(const uint32_t* iz, int n, uint64_t* cc2, uint32_t focus, uint32_t min_diff,
                                         UScale scale, uint32_t cap) {
  const __m256i zero = _mm256_setzero_si256();
  const __m256i invalid_iz = _mm256_set1_epi64x(kInvalidInverseDepth);
  const __m256i f = _mm256_set1_epi64x(focus);
  const __m256i lo = _mm256_set1_epi64x(min_diff);
  const __m256i mant = _mm256_set1_epi64x(scale.mant);
  const __m256i capv = _mm256_set1_epi64x(cap);
  const __m256i one = _mm256_set1_epi64x(1);
  const __m128i count = _mm_cvtsi64_si128(scale.shift);
  const __m128i count_round = _mm_cvtsi64_si128(static_cast<int64_t>(static_cast<uint64_t>(scale.shift) - 1));
  for (int x = 0; x < n; x += 4) {
    const __m256i v = avx2::LoadU32x4(iz + x);
    const __m256i diff = _mm256_sub_epi64(v, f);
    const __m256i negative = _mm256_cmpgt_epi64(zero, diff);
    const __m256i d = _mm256_sub_epi64(_mm256_xor_si256(diff, negative), negative);  // |iz - focus|
    const __m256i p = _mm256_mul_epu32(d, mant);
    const __m256i c = _mm256_add_epi64(_mm256_srl_epi64(p, count), _mm256_and_si256(_mm256_srl_epi64(p, count_round), one));
    const __m256i over = avx2::GreaterU64(c, capv);
    const __m256i capped = _mm256_blendv_epi8(c, capv, over);
    const __m256i none = _mm256_or_si256(_mm256_cmpeq_epi64(v, invalid_iz), _mm256_cmpgt_epi64(lo, d));
    const __m256i coc = _mm256_andnot_si256(none, capped);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(cc2 + x), _mm256_mul_epu32(coc, coc));
  }
}
#endif
#ifdef CAMSIM_X86_AVX512
// DiffusionCc2Avx2 in eight lanes, with AVX-512's 64-bit absolute value,
// unsigned min and masks (d < 2^32, so its compares are the same).
CAMSIM_AVX512_TARGET void DiffusionCc2Avx512(const uint32_t* iz, int n, uint64_t* cc2, uint32_t focus,
                                             uint32_t min_diff, UScale scale, uint32_t cap) {
  const __m512i invalid_iz = _mm512_set1_epi64(kInvalidInverseDepth);
  const __m512i f = _mm512_set1_epi64(focus);
  const __m512i lo = _mm512_set1_epi64(min_diff);
  const __m512i mant = _mm512_set1_epi64(scale.mant);
  const __m512i capv = _mm512_set1_epi64(cap);
  const __m512i one = _mm512_set1_epi64(1);
  const __m128i count = _mm_cvtsi64_si128(scale.shift);
  const __m128i count_round = _mm_cvtsi64_si128(static_cast<int64_t>(static_cast<uint64_t>(scale.shift) - 1));
  for (int x = 0; x < n; x += 8) {
    const __m512i v = _mm512_cvtepu32_epi64(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(iz + x)));
    const __m512i d = _mm512_abs_epi64(_mm512_sub_epi64(v, f));  // |iz - focus|
    const __m512i p = _mm512_mul_epu32(d, mant);
    const __m512i c =
        _mm512_add_epi64(_mm512_srl_epi64(p, count), _mm512_and_si512(_mm512_srl_epi64(p, count_round), one));
    const __mmask8 some = _mm512_cmpneq_epi64_mask(v, invalid_iz) & _mm512_cmpge_epi64_mask(d, lo);
    const __m512i coc = _mm512_maskz_mov_epi64(some, _mm512_min_epu64(c, capv));
    _mm512_storeu_si512(cc2 + x, _mm512_mul_epu32(coc, coc));
  }
}
#endif
}  // namespace

void CocModel::DiffusionCc2Row(const uint32_t* iz, int n, uint64_t* cc2) const {
  int x = 0;
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512() && diffusion_scale_.shift < 64) {
    x = n & ~7;
    DiffusionCc2Avx512(iz, x, cc2, focus_, min_diff_, diffusion_scale_, diffusion_cap_);
  } else
#endif
#ifdef CAMSIM_X86_AVX2
  if (CpuHasAvx2() && diffusion_scale_.shift < 64) {
    x = n & ~3;
    DiffusionCc2Avx2(iz, x, cc2, focus_, min_diff_, diffusion_scale_, diffusion_cap_);
  }
#endif
  for (; x < n; ++x) {
    const uint64_t c = DiffusionCoc(iz[x]);
    cc2[x] = c * c;
  }
}

// ---------------------------------------------------------------- solver

namespace dof {

namespace {
#ifdef CAMSIM_X86_AVX2
// MulQ30 of four lanes, MulQ30Split's integers: |d| < 2^49, so the low half
// of d >> 24 (logical) is d >> 24 as an int32 and vpmuldq gives the signed
// high product qh (|qh| < 2^55); qh >> 6 (arithmetic; AVX2 has none for
// 64 bits) is ((qh + 2^61) >> 6) - 2^55.
CAMSIM_AVX2_TARGET inline __m256i MulQ30x4(__m256i d, __m256i w) {
  const __m256i qh = _mm256_mul_epi32(_mm256_srli_epi64(d, 24), w);
  const __m256i ql = _mm256_mul_epu32(_mm256_and_si256(d, _mm256_set1_epi64x(0xFFFFFF)), w);
  const __m256i low = _mm256_add_epi64(_mm256_slli_epi64(_mm256_and_si256(qh, _mm256_set1_epi64x(63)), 24),
                                       _mm256_add_epi64(ql, _mm256_set1_epi64x(int64_t{1} << 29)));
  const __m256i high = _mm256_sub_epi64(_mm256_srli_epi64(_mm256_add_epi64(qh, _mm256_set1_epi64x(int64_t{1} << 61)), 6),
                                        _mm256_set1_epi64x(int64_t{1} << 55));
  return _mm256_add_epi64(high, _mm256_srli_epi64(low, 30));
}

CAMSIM_AVX2_TARGET void PullRowAvx2(int64_t* u, const uint32_t* in, const uint32_t* w, int n) {
  for (int x = 0; x < n; x += 4) {
    __m256i* up = reinterpret_cast<__m256i*>(u + x);
    const __m256i v = _mm256_loadu_si256(up);
    const __m256i d = _mm256_sub_epi64(_mm256_slli_epi64(avx2::LoadU32x4(in + x), kG), v);
    _mm256_storeu_si256(up, _mm256_add_epi64(v, MulQ30x4(d, avx2::LoadU32x4(w + x))));
  }
}

// OutOf in lanes: (y + 2^15) >> 16 with y's sign restored, saturated to uint32.
CAMSIM_AVX2_TARGET inline void StoreOut4(__m256i y, uint32_t* out) {
  const __m256i rounded = _mm256_add_epi64(y, _mm256_set1_epi64x(int64_t{1} << (kG - 1)));
  const __m256i negative = _mm256_cmpgt_epi64(_mm256_setzero_si256(), rounded);
  const __m256i t = _mm256_srli_epi64(rounded, kG);
  const __m256i big = _mm256_cmpgt_epi64(t, _mm256_set1_epi64x(0xFFFFFFFFll));
  const __m256i s = _mm256_andnot_si256(negative, _mm256_or_si256(t, big));  // big: all ones, low half 2^32 - 1
  avx2::StoreLow32x4(s, out);
}

CAMSIM_AVX2_TARGET void BackRowAvx2(int64_t* y, const int64_t* us, const uint32_t* e, uint32_t* out, int n) {
  for (int x = 0; x < n; x += 4) {
    __m256i* yp = reinterpret_cast<__m256i*>(y + x);
    __m256i v = _mm256_loadu_si256(yp);
    if (e != nullptr) {
      const __m256i d = _mm256_sub_epi64(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(us + x)), v);
      v = _mm256_add_epi64(v, MulQ30x4(d, avx2::LoadU32x4(e + x)));
      _mm256_storeu_si256(yp, v);
    }
    StoreOut4(v, out + x);
  }
}
#endif

}  // namespace

CAMSIM_CPU_CLONES
void BetaRow(const uint64_t* cc2_a, const uint64_t* cc2_b, int n, uint32_t* beta) {
  for (int x = 0; x < n; ++x) beta[x] = BetaOf(cc2_a[x], cc2_b[x]);
}

size_t LineWorkBytes(int n) {
  return AlignUp(sizeof(uint32_t) * static_cast<size_t>(n)) + 3 * AlignUp(sizeof(int64_t) * static_cast<size_t>(n));
}

namespace {
// SolveLine for a channel count known at compile time: each channel's sweep
// is a chain carried in a register, and the kChannels chains of a step are
// independent, so they overlap (the same operations, so the same bits).
template <int kChannels>
int SolveLineN(uint32_t* const* line, const uint32_t* beta, int n, uint8_t* work, bool skip) {
  uint32_t* e = reinterpret_cast<uint32_t*>(work);
  int64_t* u[kChannels];
  uint8_t* p = work + AlignUp(sizeof(uint32_t) * static_cast<size_t>(n));
  for (int c = 0; c < kChannels; ++c) {
    u[c] = reinterpret_cast<int64_t*>(p);
    p += AlignUp(sizeof(int64_t) * static_cast<size_t>(n));
  }
  int solved = 0;
  if (!skip)  // one segment: a step across b = 0 has r = e = 1 exactly (SolveLines), so the same bits
    for (int i = 0; i < n; ++i) solved += (i > 0 && beta[i] != 0) || (i + 1 < n && beta[i + 1] != 0);
  int s = 0;
  while (s < n) {
    // The segment [s, t]: linked by non-zero b; a lone sample is its own solution.
    int t = s;
    while (t + 1 < n && (!skip || beta[t + 1] != 0)) ++t;
    if (t == s) {
      ++s;
      continue;
    }
    if (skip) solved += t - s + 1;
    int64_t v[kChannels];  // u_{i-1}, then y_{i+1}
    for (int c = 0; c < kChannels; ++c) u[c][s] = v[c] = int64_t{line[c][s]} << kG;
    uint32_t r = kOneW;
    SweepStep<true> step;
    for (int i = s + 1; i <= t; ++i) {
      step.Take(beta[i], r);
      r = step.next;
      e[i - 1] = step.e;
      for (int c = 0; c < kChannels; ++c) {
        v[c] += MulQ30((int64_t{line[c][i]} << kG) - v[c], r);
        u[c][i] = v[c];
      }
    }
    for (int c = 0; c < kChannels; ++c) line[c][t] = OutOf(v[c]);
    for (int i = t - 1; i >= s; --i) {
      const uint32_t ei = e[i];
      for (int c = 0; c < kChannels; ++c) {
        v[c] += MulQ30(u[c][i] - v[c], ei);
        line[c][i] = OutOf(v[c]);
      }
    }
    s = t + 1;
  }
  return solved;
}
}  // namespace

int SolveLine(uint32_t* const* line, int channels, const uint32_t* beta, int n, uint8_t* work, bool skip) {
  switch (channels) {
    case 1: return SolveLineN<1>(line, beta, n, work, skip);
    case 2: return SolveLineN<2>(line, beta, n, work, skip);
    default: return SolveLineN<3>(line, beta, n, work, skip);
  }
}

// SolveLines in lanes. SolveLine's sweeps, run over the whole line instead of
// segment by segment, give the same bits: where b_i = 0, D_i = 1 makes
// r_i = e_{i-1} = 1 exactly, and MulQ30(d, 1) = d exactly, so u_i = x_i
// restarts the forward sweep (as a segment's first sample) and y_{i-1} = u_{i-1}
// the backward one (as a segment's last); a lone sample comes out as its
// input. Starting both sweeps from 0 with weight 1 gives u_0 = x_0 and
// y_{n-1} = u_{n-1}. So the weights alone depend on where the links are:
// LaneWeightsAvx512 computes them per line (SweepStep's recurrence in lanes),
// stored lane-interleaved (rt[8 i + j] = r_i of line j, et likewise e_i),
// and one sweep carries the eight lines' three channels in 64-bit lanes
// (MulQ30x8, OutOf8). The samples go in and out through 8 x 8 transposes.
namespace {
#ifdef CAMSIM_X86_AVX512
// An 8 x 8 block of uint32 transposed: lane j of r[k] becomes lane k of r[j].
CAMSIM_AVX512_TARGET inline void Transpose8(__m256i* r) {
  __m256i t[8], s[8];
  for (int k = 0; k < 8; k += 2) {
    t[k] = _mm256_unpacklo_epi32(r[k], r[k + 1]);
    t[k + 1] = _mm256_unpackhi_epi32(r[k], r[k + 1]);
  }
  for (int k = 0; k < 8; k += 4) {
    s[k] = _mm256_unpacklo_epi64(t[k], t[k + 2]);
    s[k + 1] = _mm256_unpackhi_epi64(t[k], t[k + 2]);
    s[k + 2] = _mm256_unpacklo_epi64(t[k + 1], t[k + 3]);
    s[k + 3] = _mm256_unpackhi_epi64(t[k + 1], t[k + 3]);
  }
  for (int k = 0; k < 4; ++k) {
    r[k] = _mm256_permute2x128_si256(s[k], s[k + 4], 0x20);
    r[k + 4] = _mm256_permute2x128_si256(s[k], s[k + 4], 0x31);
  }
}

// Columns [i0, i0 + m) of eight rows, transposed: x[k] holds column i0 + k
// of every row (m < 8: the columns past m are 0).
CAMSIM_AVX512_TARGET inline void LoadColumns(const uint32_t* const* row, int i0, int m, __m256i* x) {
  if (m == 8) {
    for (int j = 0; j < 8; ++j) x[j] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(row[j] + i0));
    Transpose8(x);
    return;
  }
  alignas(32) uint32_t t[8][8] = {};
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < 8; ++j) t[k][j] = row[j][i0 + k];
  for (int k = 0; k < 8; ++k) x[k] = _mm256_load_si256(reinterpret_cast<const __m256i*>(t[k]));
}

// The inverse: column i0 + k of line j from lane j of y[k], for the count
// real lines (y is overwritten).
CAMSIM_AVX512_TARGET inline void StoreColumns(const LineIo* lines, int count, int c, int i0, int m, __m256i* y) {
  if (m == 8) {
    Transpose8(y);
    for (int j = 0; j < count; ++j) _mm256_storeu_si256(reinterpret_cast<__m256i*>(lines[j].out[c] + i0), y[j]);
    return;
  }
  alignas(32) uint32_t t[8][8];
  for (int k = 0; k < 8; ++k) _mm256_store_si256(reinterpret_cast<__m256i*>(t[k]), y[k]);
  for (int j = 0; j < count; ++j)
    for (int k = 0; k < m; ++k) lines[j].out[c][i0 + k] = t[k][j];
}

// The lane sweep's weights of the eight lines (each line's recurrence, each
// lane keeping its last computed step as SweepStep does) into rt and et, and
// SolveLine's returns: a sample is solved when a link on either side is not
// 0. skip false: every lane takes every step (b = 0 gives r = e = 1 in
// SweepStep too), so nothing is taken without its division or repeat check.
// Where every linked lane repeats its kept step (most steps: 91 % of the
// row steps repeat, per line), the kept weights are taken in lanes; lanes
// that do not repeat compute theirs one by one (SweepStep). Lanes past count
// repeat the last line.
CAMSIM_AVX512_TARGET void LaneWeightsAvx512(const LineIo* lines, int count, int n, uint32_t* rt, uint32_t* et,
                                            int32_t* solved, bool skip) {
  constexpr int kL = kLaneLines;
  const uint32_t* beta[kL];
  for (int j = 0; j < kL; ++j) beta[j] = lines[j < count ? j : count - 1].beta;
  const __m256i one = _mm256_set1_epi32(static_cast<int>(kOneW));
  // Each lane's kept step (SweepStep's b, r, next, e; r = 0: nothing kept).
  alignas(32) uint32_t kb[kL] = {}, kr[kL] = {}, kn[kL] = {}, ke[kL] = {};
  __m256i kept_b = _mm256_setzero_si256(), kept_r = kept_b, kept_next = kept_b, kept_e = kept_b;
  __m256i r = one;  // r_{i-1}
  __mmask8 linked_left = 0;  // beta[i - 1] != 0 (beta[0] is ignored)
  __m256i solved_lanes = _mm256_setzero_si256();
  _mm256_store_si256(reinterpret_cast<__m256i*>(rt), one);
  for (int i0 = 0; i0 < n; i0 += kL) {
    const int m = n - i0 < kL ? n - i0 : kL;
    __m256i b_cols[kL];
    LoadColumns(beta, i0, m, b_cols);
    for (int k = i0 == 0 ? 1 : 0; k < m; ++k) {
      const int i = i0 + k;
      const __m256i b = b_cols[k];
      const __mmask8 linked = _mm256_test_epi32_mask(b, b);
      const __mmask8 stepped = skip ? linked : __mmask8{0xFF};
      const __mmask8 repeat = _mm256_mask_cmpeq_epi32_mask(stepped, b, kept_b) & _mm256_cmpeq_epi32_mask(r, kept_r);
      if (repeat != stepped) {  // some lanes have a step not kept: SweepStep computes it
        alignas(32) uint32_t bj[kL], rj[kL];
        _mm256_store_si256(reinterpret_cast<__m256i*>(bj), b);
        _mm256_store_si256(reinterpret_cast<__m256i*>(rj), r);
        for (int j = 0; j < kL; ++j) {
          if (((stepped & ~repeat) >> j & 1) == 0) continue;
          SweepStep<true> step;
          step.Take(bj[j], rj[j]);
          kb[j] = step.b;
          kr[j] = step.r;
          kn[j] = step.next;
          ke[j] = step.e;
        }
        kept_b = _mm256_load_si256(reinterpret_cast<const __m256i*>(kb));
        kept_r = _mm256_load_si256(reinterpret_cast<const __m256i*>(kr));
        kept_next = _mm256_load_si256(reinterpret_cast<const __m256i*>(kn));
        kept_e = _mm256_load_si256(reinterpret_cast<const __m256i*>(ke));
      }
      r = _mm256_mask_blend_epi32(stepped, one, kept_next);  // b = 0: r = e = 1, the sweep restarts
      _mm256_store_si256(reinterpret_cast<__m256i*>(rt + kL * i), r);
      _mm256_store_si256(reinterpret_cast<__m256i*>(et + kL * (i - 1)), _mm256_mask_blend_epi32(stepped, one, kept_e));
      solved_lanes = _mm256_mask_sub_epi32(solved_lanes, linked | linked_left, solved_lanes, _mm256_set1_epi32(-1));
      linked_left = linked;
    }
  }
  _mm256_store_si256(reinterpret_cast<__m256i*>(et + kL * (n - 1)), one);
  solved_lanes = _mm256_mask_sub_epi32(solved_lanes, linked_left, solved_lanes, _mm256_set1_epi32(-1));  // sample n - 1
  alignas(32) int32_t s[kL];
  _mm256_store_si256(reinterpret_cast<__m256i*>(s), solved_lanes);
  for (int j = 0; j < count; ++j) solved[j] = s[j];
}

// The input's 24 row streams (eight lines, three channels) are more than the
// hardware prefetcher follows: each is prefetched this many columns ahead.
constexpr int kPrefetchColumns = 128;

// The kernels that multiply by a weight (MulQ30x8): PullRow's and BackRow's
// column-pass steps and the row pass's SweepLines, compiled twice, with
// AVX-512 IFMA's 52-bit multiplies where the CPU has them (about 5 % of the
// 1080p DoF pipeline) and without (x86-64-v4, e.g. Skylake-SP); the same
// integers either way (dof_lanes.inc).
namespace lanes8 {
#define CAMSIM_DOF_LANES_TARGET CAMSIM_AVX512_TARGET
#define CAMSIM_DOF_LANES_IFMA 0
#include "core/lens/dof_lanes.inc"
#undef CAMSIM_DOF_LANES_IFMA
#undef CAMSIM_DOF_LANES_TARGET
}  // namespace lanes8
#ifdef CAMSIM_X86_AVX512_IFMA
namespace lanes8_ifma {
#define CAMSIM_DOF_LANES_TARGET CAMSIM_AVX512_IFMA_TARGET
#define CAMSIM_DOF_LANES_IFMA 1
#include "core/lens/dof_lanes.inc"
#undef CAMSIM_DOF_LANES_IFMA
#undef CAMSIM_DOF_LANES_TARGET
}  // namespace lanes8_ifma
#endif

// The eight-lane kernels this CPU runs.
struct Lanes8 {
  void (*pull_row)(int64_t*, const uint32_t*, const uint32_t*, int);
  void (*back_row)(int64_t*, const int64_t*, const uint32_t*, uint32_t*, int);
  void (*sweep_lines)(const LineIo*, int, int, const uint32_t*, const uint32_t*, int64_t*);
};
const Lanes8& Lanes8ForCpu() {
  static constexpr Lanes8 kPlain{lanes8::PullRow, lanes8::BackRow, lanes8::SweepLines};
#ifdef CAMSIM_X86_AVX512_IFMA
  static constexpr Lanes8 kIfma{lanes8_ifma::PullRow, lanes8_ifma::BackRow, lanes8_ifma::SweepLines};
  if (CpuHasAvx512Ifma()) return kIfma;
#endif
  return kPlain;
}

// Aligned sizes of the lane sweep's arrays for n samples.
size_t LaneWeightBytes(int n) { return AlignUp(sizeof(uint32_t) * kLaneLines * static_cast<size_t>(n)); }
size_t LaneStateBytes(int n) { return AlignUp(sizeof(int64_t) * 3 * kLaneLines * static_cast<size_t>(n)); }
#endif
}  // namespace

void PullRow(int64_t* u, const uint32_t* in, const uint32_t* w, int n) {
  int x = 0;
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512()) {
    x = n & ~7;
    Lanes8ForCpu().pull_row(u, in, w, x);
  } else
#endif
#ifdef CAMSIM_X86_AVX2
  if (CpuHasAvx2()) {
    x = n & ~3;
    PullRowAvx2(u, in, w, x);
  }
#endif
  for (; x < n; ++x) u[x] += MulQ30((int64_t{in[x]} << kG) - u[x], w[x]);
}

void BackRow(int64_t* y, const int64_t* us, const uint32_t* e, uint32_t* out, int n) {
  int x = 0;
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512()) {
    x = n & ~7;
    Lanes8ForCpu().back_row(y, us, e, out, x);
  } else
#endif
#ifdef CAMSIM_X86_AVX2
  if (CpuHasAvx2()) {
    x = n & ~3;
    BackRowAvx2(y, us, e, out, x);
  }
#endif
  for (; x < n; ++x) {
    if (e != nullptr) y[x] += MulQ30(us[x] - y[x], e[x]);
    out[x] = OutOf(y[x]);
  }
}

size_t LinesWorkBytes(int n) {
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512()) return 2 * LaneWeightBytes(n) + LaneStateBytes(n);
#endif
  return LineWorkBytes(n);
}

void SolveLines(const LineIo* lines, int count, int n, uint8_t* work, int32_t* solved, bool skip) {
  CAMSIM_DCHECK(count >= 1 && count <= kLaneLines);
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512()) {
    uint32_t* rt = reinterpret_cast<uint32_t*>(work);
    uint32_t* et = reinterpret_cast<uint32_t*>(work + LaneWeightBytes(n));
    int64_t* u = reinterpret_cast<int64_t*>(work + 2 * LaneWeightBytes(n));
    LaneWeightsAvx512(lines, count, n, rt, et, solved, skip);
    Lanes8ForCpu().sweep_lines(lines, count, n, rt, et, u);
    return;
  }
#endif
  for (int j = 0; j < count; ++j) {
    for (int c = 0; c < 3; ++c) std::memcpy(lines[j].out[c], lines[j].in[c], sizeof(uint32_t) * static_cast<size_t>(n));
    solved[j] = SolveLine(lines[j].out, 3, lines[j].beta, n, work, skip);
  }
}

}  // namespace dof

// ---------------------------------------------------------------- row stage

Status DofRowStage::Configure(const DofConfig& c, const SensorGeometry& g, double f_number) {
  config_ = c;
  geometry_ = g;
  structural_ = false;
  for (double a : c.structural_poly) {
    if (!(a >= -1023.0 && a <= 1023.0))
      return InvalidArgument("dof.structural_poly", "coefficients must be in [-1023, 1023] pixels");
    if (a != 0.0) structural_ = true;
  }
  if (c.method != DofMethod::kOff && c.method != DofMethod::kDiffusion && c.method != DofMethod::kGather)
    return InvalidArgument("dof.method", "must be off, diffusion or gather");
  if (c.column_window < 1 || c.column_window > kMaxColumnWindow)
    return InvalidArgument("dof.column_window", "must be in [1, 496] rows");
  if (c.method == DofMethod::kDiffusion && !c.structural_only) {
    CAMSIM_TRY(coc_.Configure(c, f_number));
  } else if (structural_) {  // no lens model needed, but the shared limits still apply
    CAMSIM_TRY(CheckCocLimits(c));
  }
  const uint64_t den = Geometry2::Denominator(g);
  if (structural_ && den > 0) {
    Result<UScale> s = UScale::FromDouble((kCurvePoints - 1) * 65536.0 / static_cast<double>(den), "sensor.width");
    if (!s.ok()) return s.status();
    rho_to_index_ = s.value();
  }
  return Status::Ok();
}

Result<LineFormat> DofRowStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kRadiance || in.channels != 3)
    return InvalidArgument("dof", "depth of field needs 3-channel radiance input (run it before exposure)");
  return in;
}

const char* DofRowStage::IdentityReason() const {
  if (config_.method != DofMethod::kDiffusion && !structural_)
    return "dof.method is not diffusion and there is no structural blur";
  if (config_.structural_only && !structural_) return "dof.structural_only without dof.structural_poly";
  return nullptr;
}

void DofRowStage::CountTables(WorkspaceCounter& counter) const {
  if (!structural_) return;
  counter.Add<uint64_t>(kCurvePoints + 1);
  counter.Add<uint32_t>(static_cast<size_t>(geometry_.width));
}

Status DofRowStage::Init(Arena& tables) {
  if (!structural_) return Status::Ok();
  struct_cc2_ = tables.Take<uint64_t>(kCurvePoints + 1);
  dx2_ = tables.Take<uint32_t>(static_cast<size_t>(geometry_.width));
  if (struct_cc2_ == nullptr || dx2_ == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for structural blur tables");
  for (int i = 0; i < kCurvePoints; ++i) {
    const double r = std::sqrt(static_cast<double>(i) / (kCurvePoints - 1));
    double d = 0.0, rk = 1.0;
    for (double a : config_.structural_poly) {
      d += a * rk;
      rk *= r;
    }
    if (d < 0.0) d = 0.0;
    if (d > config_.max_coc_px) d = config_.max_coc_px;
    if (d < config_.min_coc_px) d = 0.0;
    const double sd = d * config_.diffusion_scale * 256.0;  // Q.8 diffusion diameter
    const double sq = sd * sd;                              // Q.16 squared, < (1023 * 256)^2 < 2^37: exact
    struct_cc2_[i] = static_cast<uint64_t>(sq + 0.5);
  }
  struct_cc2_[kCurvePoints] = struct_cc2_[kCurvePoints - 1];
  for (int x = 0; x < geometry_.width; ++x) {
    const int64_t d = 2 * static_cast<int64_t>(x) - (geometry_.width - 1);
    dx2_[x] = static_cast<uint32_t>(d * d);
  }
  return Status::Ok();
}

void DofRowStage::RowCc2(const FrameInput& input, int y, int x0, int x1, uint64_t* cc2) const {
  const int n = x1 - x0;
  if (config_.method == DofMethod::kDiffusion && !config_.structural_only) {
    coc_.DiffusionCc2Row(input.inverse_depth.row(y) + x0, n, cc2);
  } else {
    for (int x = 0; x < n; ++x) cc2[x] = 0;
  }
  if (!structural_) return;
  const int64_t dy = 2 * static_cast<int64_t>(y) - (geometry_.height - 1);
  const uint32_t dy2 = static_cast<uint32_t>(dy * dy);
  for (int x = 0; x < n; ++x) {
    const uint32_t pos = rho_to_index_.Apply(dx2_[x0 + x] + dy2);
    const uint32_t i = pos >> 16, f = pos & 0xFFFF;
    const uint64_t g0 = struct_cc2_[i], g1 = struct_cc2_[i + 1];
    cc2[x] += ((g0 * (0x10000 - f) + g1 * f + 0x8000) >> 16) << 16;  // Q.16 -> Q.32
  }
}

RowWindow DofRowStage::InputRows(int y, int height) const {
  const int b0 = y / kBlock * kBlock;
  return {b0, b0 + kBlock - 1 < height - 1 ? b0 + kBlock - 1 : height - 1};
}

// Scratch: the squared CoCs of one row, the block's links (kBlock rows of
// w + 1), the solver's work.
size_t DofRowStage::ScratchBytes(int width) const {
  const size_t w = static_cast<size_t>(width);
  return AlignUp(sizeof(uint64_t) * w) + kBlock * AlignUp(sizeof(uint32_t) * (w + 1)) + dof::LinesWorkBytes(width);
}

// State: a header (int32: [0] the solved block's first row, -1 for none;
// [1 + k] solved pixels of its row k), then the solved block (kBlock rows x
// 3 channels x width, uint32).
size_t DofRowStage::StateBytes(int width) const {
  return AlignUp(sizeof(int32_t) * (1 + kBlock)) + AlignUp(sizeof(uint32_t) * 3 * kBlock * static_cast<size_t>(width));
}

void DofRowStage::BeginStrip(uint8_t* state) const { reinterpret_cast<int32_t*>(state)[0] = -1; }

void DofRowStage::ProcessRow(const RowArgs& a) const {
  const size_t w = static_cast<size_t>(a.width);
  int32_t* header = reinterpret_cast<int32_t*>(a.state);
  uint32_t* cache = reinterpret_cast<uint32_t*>(a.state + AlignUp(sizeof(int32_t) * (1 + kBlock)));
  const int b0 = a.first_row;  // InputRows: the block's rows, none reflected
  CAMSIM_DCHECK(b0 == a.y / kBlock * kBlock && a.row_count >= 1 && a.row_count <= kBlock);
  if (header[0] != b0) {
    uint64_t* cc2 = reinterpret_cast<uint64_t*>(a.scratch);
    uint8_t* links = a.scratch + AlignUp(sizeof(uint64_t) * w);
    const size_t link_pitch = AlignUp(sizeof(uint32_t) * (w + 1));
    uint8_t* work = links + kBlock * link_pitch;
    dof::LineIo lines[kBlock];
    bool linked = false;
    for (int k = 0; k < a.row_count; ++k) {
      uint32_t* beta = reinterpret_cast<uint32_t*>(links + static_cast<size_t>(k) * link_pitch);
      RowCc2(*a.input, b0 + k, 0, a.width, cc2);
      beta[0] = 0;
      beta[w] = 0;
      dof::BetaRow(cc2, cc2 + 1, a.width - 1, beta + 1);
      for (size_t x = 1; x < w; ++x) linked |= beta[x] != 0;
      for (int c = 0; c < 3; ++c) {
        lines[k].in[c] = a.rows[k].ch[c];
        lines[k].out[c] = cache + (static_cast<size_t>(k) * 3 + c) * w;
      }
      lines[k].beta = beta;
    }
    if (linked || !skip_idle_) {
      dof::SolveLines(lines, a.row_count, a.width, work, header + 1, skip_idle_);
    } else {  // no link in the block (in focus): every line is its own solution
      for (int k = 0; k < a.row_count; ++k) {
        for (int c = 0; c < 3; ++c) std::memcpy(lines[k].out[c], lines[k].in[c], sizeof(uint32_t) * w);
        header[1 + k] = 0;
      }
    }
    header[0] = b0;
  }
  const int k = a.y - b0;
  for (int c = 0; c < 3; ++c) std::memcpy(a.out[c], cache + (static_cast<size_t>(k) * 3 + c) * w, sizeof(uint32_t) * w);
  if (a.stats != nullptr) a.stats->skipped_px += a.width - header[1 + k];
}

// ---------------------------------------------------------------- column stage

Status DofColumnStage::Configure(const DofConfig& c, const SensorGeometry& g, const DofRowStage* rows) {
  config_ = c;
  geometry_ = g;
  rows_ = rows;
  return Status::Ok();
}

Result<LineFormat> DofColumnStage::Plan(LineFormat in) const { return rows_->Plan(in); }

// Every row of block b reads the block's window [bB - W, bB + B - 1 + W],
// clipped at the frame ends (insulated there, as the row pass).
RowWindow DofColumnStage::InputRows(int y, int height) const {
  const int b0 = (y / kBlock) * kBlock;
  const int lo = b0 - config_.column_window, hi = b0 + kBlock - 1 + config_.column_window;
  return {lo < 0 ? 0 : lo, hi > height - 1 ? height - 1 : hi};
}

size_t DofColumnStage::ScratchBytes(int width) const {
  const size_t n = static_cast<size_t>(width < kTile ? width : kTile);
  const size_t nb = n * kBlock;
  return 2 * AlignUp(sizeof(uint32_t) * n) + 6 * AlignUp(sizeof(int64_t) * n) + AlignUp(sizeof(uint32_t) * nb) +
         3 * AlignUp(sizeof(int64_t) * nb);
}

namespace {
// The column stage's strip state, in this order: a header (int32: [0] the
// solved block, [1 + k] solved pixels of its row k, [kBlock + 1] the next row
// whose link is not yet in the ring, -1 for none), the solved block
// (kBlock x 3 channels x width, uint32), the squared diffusion CoC of the
// ring's last row and a row to compute the next one (uint64 x width each),
// then the ring of links: slot i mod R holds b between rows i - 1 and i for
// every column, R = kBlock + 2W (the largest window). Each row's CoC is
// computed once per strip, not once per block and tile that reads it.
struct ColumnState {
  int32_t* header;
  uint32_t* cache;
  uint64_t* cc2_last;
  uint64_t* cc2_next;
  uint32_t* ring;
  int ring_rows;
};
constexpr int kHeaderInts = DofColumnStage::kBlock + 2;
ColumnState ColumnStateOf(uint8_t* state, int width, int window) {
  const size_t w = static_cast<size_t>(width);
  ColumnState c;
  c.header = reinterpret_cast<int32_t*>(state);
  state += AlignUp(sizeof(int32_t) * kHeaderInts);
  c.cache = reinterpret_cast<uint32_t*>(state);
  state += AlignUp(sizeof(uint32_t) * 3 * DofColumnStage::kBlock * w);
  c.cc2_last = reinterpret_cast<uint64_t*>(state);
  state += AlignUp(sizeof(uint64_t) * w);
  c.cc2_next = reinterpret_cast<uint64_t*>(state);
  state += AlignUp(sizeof(uint64_t) * w);
  c.ring = reinterpret_cast<uint32_t*>(state);
  c.ring_rows = DofColumnStage::kBlock + 2 * window;
  return c;
}
}  // namespace

size_t DofColumnStage::StateBytes(int width) const {
  const size_t w = static_cast<size_t>(width);
  const size_t ring_rows = static_cast<size_t>(kBlock + 2 * config_.column_window);
  return AlignUp(sizeof(int32_t) * kHeaderInts) + AlignUp(sizeof(uint32_t) * 3 * kBlock * w) +
         2 * AlignUp(sizeof(uint64_t) * w) + AlignUp(sizeof(uint32_t) * ring_rows * w);
}

void DofColumnStage::BeginStrip(uint8_t* state) const {
  int32_t* header = reinterpret_cast<int32_t*>(state);
  header[0] = -1;
  header[kBlock + 1] = -1;
}

// Brings the ring's links up to row hi (rows lo .. hi of the block's window).
// A link depends on its two rows only, so the ring holds the same values
// whichever block or strip computed them.
void DofColumnStage::FillLinks(const RowArgs& a, uint8_t* state, int lo, int hi) const {
  const ColumnState st = ColumnStateOf(state, a.width, config_.column_window);
  int32_t& next = st.header[kBlock + 1];
  if (next < lo || next > hi + 1) {  // nothing usable: start at the window's top (its link is never read)
    rows_->RowCc2(*a.input, lo, 0, a.width, st.cc2_last);
    next = lo + 1;
  }
  for (; next <= hi; ++next) {
    rows_->RowCc2(*a.input, next, 0, a.width, st.cc2_next);
    uint32_t* link = st.ring + static_cast<size_t>(next % st.ring_rows) * static_cast<size_t>(a.width);
    dof::BetaRow(st.cc2_last, st.cc2_next, a.width, link);
    std::memcpy(st.cc2_last, st.cc2_next, sizeof(uint64_t) * static_cast<size_t>(a.width));
  }
}

void DofColumnStage::ProcessRow(const RowArgs& a) const {
  const ColumnState st = ColumnStateOf(a.state, a.width, config_.column_window);
  int32_t* header = st.header;  // [0] block, [1 + k] solved pixels of row k
  uint32_t* cache = st.cache;
  const int block = a.y / kBlock;
  const size_t pitch = static_cast<size_t>(a.width);
  if (header[0] != block) {
    const int yb = block * kBlock;
    const int ye = yb + kBlock - 1 < geometry_.height - 1 ? yb + kBlock - 1 : geometry_.height - 1;
    for (int k = 0; k < kBlock; ++k) header[1 + k] = 0;
    FillLinks(a, a.state, a.first_row, a.first_row + a.row_count - 1);
    for (int x0 = 0; x0 < a.width; x0 += kTile)
      SolveTile(a, yb, ye, x0, x0 + kTile < a.width ? x0 + kTile : a.width, cache, header + 1, st.ring,
                st.ring_rows);
    header[0] = block;
  }
  const int k = a.y - block * kBlock;
  for (int c = 0; c < 3; ++c)
    std::memcpy(a.out[c], cache + (static_cast<size_t>(k) * 3 + c) * pitch, sizeof(uint32_t) * pitch);
  if (a.stats != nullptr) a.stats->skipped_px += a.width - header[1 + k];
}

namespace {
// Column x of one sweep step over a tile: r[x] <- r_i and (kWithE) e[x] <-
// e_{i-1}, from b_i = link[x] and r_{i-1} = r[x]; b = 0 decouples (r = e = 1:
// the sweep restarts there, u = x exactly).
template <bool kWithE>
inline void StepColumn(const uint32_t* link, uint32_t* r, uint32_t* e, int x, SweepStep<kWithE>* step) {
  const uint32_t b = link[x];
  if (b == 0) {
    if constexpr (kWithE) e[x] = kOneW;
    r[x] = kOneW;
    return;
  }
  step->Take(b, r[x]);
  if constexpr (kWithE) e[x] = step->e;
  r[x] = step->next;
}

#ifdef CAMSIM_X86_AVX512
// Sixteen columns at a time: the linked columns that repeat the kept step
// take its r and e, then the first linked column that does not is computed
// (SweepStep), which becomes the kept step, and so on until every linked
// column has its weights: one computation per distinct (b, r) of the group
// (the column-by-column loop computes at least as many). The kept step at
// the end may differ from that loop's, which changes what the next group
// computes, never a result. Returns the columns done (a multiple of 16).
template <bool kWithE>
CAMSIM_AVX512_TARGET int TileStepAvx512(const uint32_t* link, uint32_t* r, uint32_t* e, int w,
                                        SweepStep<kWithE>* step) {
  const __m512i one = _mm512_set1_epi32(static_cast<int>(kOneW));
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    const __m512i b = _mm512_loadu_si512(link + x);
    const __m512i r_in = _mm512_loadu_si512(r + x);
    __m512i r_out = one, e_out = one;  // b = 0: r = e = 1, the sweep restarts
    for (__mmask16 pending = _mm512_test_epi32_mask(b, b);;) {
      const __mmask16 repeat =
          _mm512_mask_cmpeq_epi32_mask(pending, b, _mm512_set1_epi32(static_cast<int>(step->b))) &
          _mm512_cmpeq_epi32_mask(r_in, _mm512_set1_epi32(static_cast<int>(step->r)));
      r_out = _mm512_mask_mov_epi32(r_out, repeat, _mm512_set1_epi32(static_cast<int>(step->next)));
      if constexpr (kWithE)
        e_out = _mm512_mask_mov_epi32(e_out, repeat, _mm512_set1_epi32(static_cast<int>(step->e)));
      pending &= static_cast<__mmask16>(~repeat);
      if (pending == 0) break;
      const int j = std::countr_zero(static_cast<unsigned>(pending));
      step->Take(link[x + j], r[x + j]);
    }
    _mm512_storeu_si512(r + x, r_out);
    if constexpr (kWithE) _mm512_storeu_si512(e + x, e_out);
  }
  return x;
}
#endif

// One sweep step's weights across a tile's w columns (StepColumn for each).
// Neighbouring columns mostly repeat the kept step (94 % of the downward
// steps, docs/depth-of-field.md); the AVX-512 path sets such runs in lanes.
// Every column's result is a function of its (b, r) alone, so the bits are
// the same either way.
template <bool kWithE>
void TileStep(const uint32_t* link, uint32_t* r, uint32_t* e, int w, SweepStep<kWithE>* step) {
  int x = 0;
#ifdef CAMSIM_X86_AVX512
  if (CpuHasAvx512()) x = TileStepAvx512(link, r, e, w, step);
#endif
  for (; x < w; ++x) StepColumn(link, r, e, x, step);
}
}  // namespace

// Columns [x0, x1) of the block's rows [yb, ye]: a downward sweep over the
// window down to ye (storing u and e of the block's rows), an upward sweep
// from the window's end to ye + 1, the twist at ye, then back substitution
// up to yb. Columns are independent; a tile of kTile keeps the state in L1/L2.
void DofColumnStage::SolveTile(const RowArgs& a, int yb, int ye, int x0, int x1, uint32_t* cache,
                               int32_t* solved_rows, const uint32_t* ring, int ring_rows) const {
  const int w = x1 - x0;
  const int lo = a.first_row, hi = a.first_row + a.row_count - 1;
  const size_t n = static_cast<size_t>(a.width < kTile ? a.width : kTile);  // as ScratchBytes
  const size_t pitch = static_cast<size_t>(a.width);
  uint8_t* p = a.scratch;
  auto take64 = [&p](size_t count) { uint64_t* q = reinterpret_cast<uint64_t*>(p); p += AlignUp(sizeof(uint64_t) * count); return q; };
  // The link between rows i - 1 and i, columns x0 .. x1 - 1.
  auto links = [ring, ring_rows, pitch, x0](int i) {
    return ring + static_cast<size_t>(i % ring_rows) * pitch + x0;
  };
  uint32_t* rf = reinterpret_cast<uint32_t*>(p);
  p += AlignUp(sizeof(uint32_t) * n);
  uint32_t* rb = reinterpret_cast<uint32_t*>(p);
  p += AlignUp(sizeof(uint32_t) * n);
  int64_t* uf[3];
  int64_t* ub[3];
  for (int c = 0; c < 3; ++c) uf[c] = reinterpret_cast<int64_t*>(take64(n));
  for (int c = 0; c < 3; ++c) ub[c] = reinterpret_cast<int64_t*>(take64(n));
  uint32_t* eb = reinterpret_cast<uint32_t*>(p);  // [row - yb][x]: e of the block's rows
  p += AlignUp(sizeof(uint32_t) * n * kBlock);
  int64_t* us[3];  // [row - yb][x]: forward u of the block's rows
  for (int c = 0; c < 3; ++c) us[c] = reinterpret_cast<int64_t*>(take64(n * kBlock));

  // A tile whose window holds no link (in focus) is its own solution: every
  // r and e is 1, so the sweeps would return the input bits. Copy it
  // (unless skipping is off: then they do return them). A window of one row
  // has no links at all.
  bool coupled = !skip_idle_ && hi > lo;
  for (int i = lo + 1; i <= hi && !coupled; ++i) {
    const uint32_t* link = links(i);
    for (int x = 0; x < w; ++x) coupled |= link[x] != 0;
  }
  if (!coupled) {
    for (int i = yb; i <= ye; ++i)
      for (int c = 0; c < 3; ++c) {
        const uint32_t* in = a.rows[i - lo].ch[c] + x0;
        uint32_t* out = cache + (static_cast<size_t>(i - yb) * 3 + c) * pitch + x0;
        for (int x = 0; x < w; ++x) out[x] = in[x];
      }
    return;
  }
  auto start = [w, x0](const RowIn& in, uint32_t* r, int64_t* const* u) {
    for (int x = 0; x < w; ++x) {
      r[x] = kOneW;
      for (int c = 0; c < 3; ++c) u[c][x] = int64_t{in.ch[c][x0 + x]} << kG;
    }
  };
  auto keep = [&](int row) {  // the forward u of a block row
    if (row < yb) return;
    const size_t o = static_cast<size_t>(row - yb) * n;
    for (int c = 0; c < 3; ++c) std::memcpy(us[c] + o, uf[c], sizeof(int64_t) * static_cast<size_t>(w));
  };

  // Downward sweep: rows lo .. ye.
  start(a.rows[0], rf, uf);
  keep(lo);
  for (int i = lo + 1; i <= ye; ++i) {
    const uint32_t* link = links(i);
    const RowIn& in = a.rows[i - lo];
    uint32_t* e = i - 1 >= yb ? eb + static_cast<size_t>(i - 1 - yb) * n : nullptr;
    if (e != nullptr) {  // e_{i-1} where a block row needs it, r alone above the block
      SweepStep<true> step;
      TileStep(link, rf, e, w, &step);
    } else {
      SweepStep<false> step;
      TileStep(link, rf, nullptr, w, &step);
    }
    for (int c = 0; c < 3; ++c) dof::PullRow(uf[c], in.ch[c] + x0, rf, w);
    keep(i);
  }

  // y_ye (Q.kG) per column and channel, into uf.
  if (hi > ye) {
    // Upward sweep: rows hi .. ye + 1.
    start(a.rows[hi - lo], rb, ub);
    for (int i = hi - 1; i > ye; --i) {
      const uint32_t* link = links(i + 1);
      const RowIn& in = a.rows[i - lo];
      SweepStep<false> step;
      TileStep(link, rb, nullptr, w, &step);
      for (int c = 0; c < 3; ++c) dof::PullRow(ub[c], in.ch[c] + x0, rb, w);
    }
    // Twist: y_ye = u_ye + w (v_{ye+1} - u_ye), w = b r_ye / (D' + b r_ye).
    const uint32_t* link = links(ye + 1);
    for (int x = 0; x < w; ++x) {
      const uint32_t b = link[x];
      if (b == 0) continue;
      const uint64_t Dp = DOf(b, rb[x]);
      const uint64_t tb = RoundShiftU(uint64_t{b} * rf[x], dof::kBetaFracBits);
      const uint32_t wt = DivQ30(tb, Dp + tb);
      for (int c = 0; c < 3; ++c) uf[c][x] += MulQ30(ub[c][x] - uf[c][x], wt);
    }
  }
  // Back substitution: y_i = y_{i+1} + e_i (u_i - y_{i+1}), rows ye .. yb.
  // Row by row (uf holds y_{i+1}), so the cache is written sequentially.
  for (int i = ye; i >= yb; --i) {
    const size_t o = static_cast<size_t>(i - yb) * n;
    for (int c = 0; c < 3; ++c)
      dof::BackRow(uf[c], us[c] + o, i < ye ? eb + o : nullptr,
                   cache + (static_cast<size_t>(i - yb) * 3 + c) * pitch + x0, w);
  }
  // Solved pixels: those with a link to a neighbour inside the window.
  // At the window's ends, the one neighbour stands in for the missing one
  // (hi > lo here: a window of one row has no links), so that the loop has
  // no branch and vectorises.
  for (int i = yb; i <= ye; ++i) {
    const uint32_t* above = i > lo ? links(i) : links(i + 1);
    const uint32_t* below = i < hi ? links(i + 1) : above;
    int32_t count = 0;
    for (int x = 0; x < w; ++x) count += (above[x] | below[x]) != 0;
    solved_rows[i - yb] += count;
  }
}

}  // namespace camsim
