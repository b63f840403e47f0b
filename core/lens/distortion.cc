#include "core/lens/distortion.h"

#include <cmath>  // std::sqrt only (IEEE basic operation)
#include <cstring>

#include "core/base/detmath.h"
#include "core/base/simd.h"

#ifdef CAMSIM_X86_AVX2
#include <immintrin.h>
#endif

namespace camsim {
namespace {

constexpr double kPi = 3.14159265358979323846;
// A node without a source (see the header's Fill); any cell touching one fills.
constexpr int32_t kNoSource = INT32_MIN;
// Largest displacement a node stores, pixels: Q15.16 signed.
constexpr double kMaxDisplacement = 32767.0;
// Configuration limits (each named in its error).
constexpr double kMaxCoefficient = 1e6;                    // |k|
constexpr double kMaxTangential = 1.0;                     // |p|
constexpr double kMinChromatic = 0.5, kMaxChromatic = 2.0;

int Log2Exact(int v) {
  int b = 0;
  while ((1 << b) < v) ++b;
  return (1 << b) == v ? b : -1;
}

double Sinc(double x) {
  if (x == 0.0) return 1.0;
  const double px = kPi * x;
  return detmath::Sin(px) / px;
}

double Floor(double v) {
  const double t = static_cast<double>(static_cast<int64_t>(v));
  return t > v ? t - 1.0 : t;
}

// The taps of one source position: the N input rows (indices into
// RowArgs::rows), the N columns (x0 .. x0 + N - 1 or reflected) and the
// weights of the two phases. Valid is false when the pixel gets the fill:
// the source is off the image, or a tap row is outside the window the
// driver provided (impossible for valid nodes; see InputRows).
// What the taps need from RowArgs, copied into locals: a store through an
// output pointer (uint32_t) may alias RowArgs' int fields, which would make
// the compiler reload them for every sample.
struct Source {
  const RowIn* rows;
  int first_row, row_count, width, height, phase_bits;
  const int16_t* weights;
  bool ring_clamp;  // DistortionConfig::ringing_clamp
};

template <int N>
struct Taps {
  int row[N];
  int col[N];
  bool contiguous;  // col[t] == col[0] + t
  const int16_t* wx;
  const int16_t* wy;
};

template <int N>
[[gnu::always_inline]] inline bool SetUpTaps(const Source a, int64_t px, int64_t py, Taps<N>* t) {
  const int width = a.width, height = a.height, phase_bits = a.phase_bits;
  const int16_t* weights = a.weights;
  constexpr int64_t kHalf = int64_t{1} << 15;
  if (px < -kHalf || py < -kHalf || px > (int64_t{width} << 16) - kHalf || py > (int64_t{height} << 16) - kHalf)
    return false;
  const int shift = 16 - phase_bits;
  const int64_t qx = (px + (int64_t{1} << (shift - 1))) >> shift;  // 1/phases of a pixel, ties up
  const int64_t qy = (py + (int64_t{1} << (shift - 1))) >> shift;
  const int mask = (1 << phase_bits) - 1;
  const int ix = static_cast<int>(qx >> phase_bits), iy = static_cast<int>(qy >> phase_bits);
  t->wx = weights + (qx & mask) * N;
  t->wy = weights + (qy & mask) * N;
  constexpr int kBefore = N / 2 - 1;  // taps before the integer position
  const int x0 = ix - kBefore, y0 = iy - kBefore;
  if (y0 >= 0 && y0 + N - 1 < height && y0 >= a.first_row && y0 + N - 1 < a.first_row + a.row_count) {
    for (int k = 0; k < N; ++k) t->row[k] = y0 - a.first_row + k;
  } else {
    for (int k = 0; k < N; ++k) {
      const int r = Reflect101(y0 + k, height) - a.first_row;
      if (r < 0 || r >= a.row_count) return false;
      t->row[k] = r;
    }
  }
  t->contiguous = x0 >= 0 && x0 + N - 1 < width;
  if (t->contiguous) {
    for (int k = 0; k < N; ++k) t->col[k] = x0 + k;
  } else {
    for (int k = 0; k < N; ++k) t->col[k] = Reflect101(x0 + k, width);
  }
  return true;
}

// The ringing clamp of the N-tap filters: v limited to the range of the 2x2
// samples around the source.
[[gnu::always_inline]] inline int64_t ClampToSamples(int64_t v, uint32_t s00, uint32_t s01, uint32_t s10,
                                                     uint32_t s11) {
  uint32_t lo = s00 < s01 ? s00 : s01, hi = s00 < s01 ? s01 : s00;
  if (s10 < lo) lo = s10;
  if (s10 > hi) hi = s10;
  if (s11 < lo) lo = s11;
  if (s11 > hi) hi = s11;
  if (v < lo) v = lo;
  if (v > hi) v = hi;
  return v;
}

// The filtered sample of channel c at the taps.
template <int N>
[[gnu::always_inline]] inline uint32_t Filter(const Source a, int c, const Taps<N>& t) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  constexpr int kBefore = N / 2 - 1;
  // Row pointers are loaded where they are used (not all N up front): with
  // N = 6 that keeps the horizontal weights in registers (fewer spills;
  // callgrind: 5 % fewer instructions for Lanczos-3).
  int64_t v = 0;
  if (t.contiguous) {
    const int x0 = t.col[0];
    int64_t wx[N];
    for (int i = 0; i < N; ++i) wx[i] = t.wx[i];
    for (int k = 0; k < N; ++k) {
      const uint32_t* p = a.rows[t.row[k]].ch[c] + x0;
      int64_t s = 0;
      for (int i = 0; i < N; ++i) s += wx[i] * p[i];
      v += int64_t{t.wy[k]} * ((s + (int64_t{1} << (kF - 1))) >> kF);
    }
  } else {
    for (int k = 0; k < N; ++k) {
      const uint32_t* row = a.rows[t.row[k]].ch[c];
      int64_t s = 0;
      for (int i = 0; i < N; ++i) s += int64_t{t.wx[i]} * row[t.col[i]];
      v += int64_t{t.wy[k]} * ((s + (int64_t{1} << (kF - 1))) >> kF);
    }
  }
  v = (v + (int64_t{1} << (kF - 1))) >> kF;
  if constexpr (N > 2) {
    if (!a.ring_clamp) return SatU32(v);
    const uint32_t* r0 = a.rows[t.row[kBefore]].ch[c];
    const uint32_t* r1 = a.rows[t.row[kBefore + 1]].ch[c];
    v = ClampToSamples(v, r0[t.col[kBefore]], r0[t.col[kBefore + 1]], r1[t.col[kBefore]], r1[t.col[kBefore + 1]]);
  }
  return SatU32(v);
}

// Filter<N> for taps that need no reflection: rows r[0 .. N-1], columns
// x0 .. x0 + N - 1 (the fast path's interior case). The same sums as Filter.
template <int N>
[[gnu::always_inline]] inline uint32_t FilterInterior(const RowIn* r, int c, int x0, const int16_t* wxp,
                                                      const int16_t* wyp, bool ring_clamp) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  constexpr int64_t kR = int64_t{1} << (kF - 1);
  if constexpr (N == 2) {
    // Each phase's two weights sum to exactly 2^14, so w0 a + w1 b equals
    // 2^14 a + w1 (b - a), and rounding that >> 14 is a + ((w1 (b - a) +
    // 2^13) >> 14): one product per sum instead of two, the same bits.
    const uint32_t* p0 = r[0].ch[c] + x0;
    const uint32_t* p1 = r[1].ch[c] + x0;
    const int64_t wx = wxp[1], wy = wyp[1];
    const int64_t h0 = int64_t{p0[0]} + ((wx * (int64_t{p0[1]} - p0[0]) + kR) >> kF);
    const int64_t h1 = int64_t{p1[0]} + ((wx * (int64_t{p1[1]} - p1[0]) + kR) >> kF);
    return SatU32(h0 + ((wy * (h1 - h0) + kR) >> kF));
  } else {
    constexpr int kBefore = N / 2 - 1;
    int64_t wx[N];
    for (int i = 0; i < N; ++i) wx[i] = wxp[i];
    int64_t v = 0;
    for (int k = 0; k < N; ++k) {
      const uint32_t* p = r[k].ch[c] + x0;
      int64_t s = 0;
      for (int i = 0; i < N; ++i) s += wx[i] * p[i];
      v += int64_t{wyp[k]} * ((s + kR) >> kF);
    }
    v = (v + kR) >> kF;
    if (!ring_clamp) return SatU32(v);
    const uint32_t* r0 = r[kBefore].ch[c] + x0 + kBefore;
    const uint32_t* r1 = r[kBefore + 1].ch[c] + x0 + kBefore;
    return static_cast<uint32_t>(ClampToSamples(v, r0[0], r0[1], r1[0], r1[1]));
  }
}

// The bilinear fast path stages a chunk of kChunk output pixels: per pixel
// the two weights (phase x, phase y: the weight of the second tap) and per
// channel the 2x2 samples, then computes them all in 32-bit lanes.
constexpr int kChunk = 64;  // pixels; a multiple of every grid_step (<= 64)
struct BilinearChunk {
  int32_t wx[kChunk], wy[kChunk];
  uint32_t s[3][2][kChunk][2];  // channel, tap row, pixel, tap column (pairs: one 64-bit copy)
  uint32_t v[3][kChunk];
};

// a + ((w (b - a) + 2^13) >> 14) for 0 <= w <= 2^14 (FilterInterior<2>'s
// step) in 32-bit arithmetic: with b - a = 2^16 dh + dl split into the
// samples' 16-bit halves, w (b - a) = 2^16 X + Y with X = w dh and Y = w dl,
// |X|, |Y| < 2^30, and the rounded shift is 4 X + ((Y + 2^13) >> 14) exactly
// (2^16 X is a multiple of 2^14). The result lies between a and b, so the
// sum modulo 2^32 is the result.
[[gnu::always_inline]] inline uint32_t Lerp32(uint32_t a, uint32_t b, int32_t w) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  const int32_t dh = static_cast<int32_t>(b >> 16) - static_cast<int32_t>(a >> 16);
  const int32_t dl = static_cast<int32_t>(b & 0xFFFF) - static_cast<int32_t>(a & 0xFFFF);
  const int32_t x = w * dh, y = w * dl;
  return a + 4u * static_cast<uint32_t>(x) + static_cast<uint32_t>((y + (1 << (kF - 1))) >> kF);
}

// channels planes of a chunk: v = lerp(lerp(s00, s01, wx), lerp(s10, s11, wx), wy).
// A fixed trip count over local arrays, so GCC vectorises it even at -O2
// (vpmulld in the AVX2 clone).
CAMSIM_CPU_CLONES
void BilinearLanes(BilinearChunk* __restrict k, int channels) {
  for (int c = 0; c < channels; ++c)
    for (int f = 0; f < kChunk; ++f) {
      const uint32_t h0 = Lerp32(k->s[c][0][f][0], k->s[c][0][f][1], k->wx[f]);
      const uint32_t h1 = Lerp32(k->s[c][1][f][0], k->s[c][1][f][1], k->wx[f]);
      k->v[c][f] = Lerp32(h0, h1, k->wy[f]);
    }
}

// The source positions (Q.16, int32) of the kChunk pixels from xs of row y,
// n of them real, for every fast path: per grid cell, from the row's
// interpolated displacements a, b at its two nodes, a + ((b - a) f + half)
// >> step_bits. In 32 bits (Init checks the ranges: |displacement| <= 2^29,
// neighbouring columns differ by less than 2^24) this equals the general
// path's (a w0 + b f + half) >> step_bits, as a 2^step_bits is a multiple
// of 2^step_bits. kChunkOff (off the image) for pixels beyond n or in a cell
// touching a node without a source: they get the fill.
constexpr int32_t kChunkOff = INT32_MIN;
[[gnu::always_inline]] inline void ChunkPositions(const int32_t* vdx, const int32_t* vdy, int xs, int n, int y,
                                                  int step_bits, int32_t* sx, int32_t* sy) {
  const int step = 1 << step_bits, half = step >> 1;
  const int32_t y16 = y * 65536;  // < 2^30
  for (int xc = 0; xc < kChunk; xc += step) {
    const int i = (xs + xc) >> step_bits;
    if (xc >= n || vdx[i] == kNoSource || vdx[i + 1] == kNoSource) {
      for (int f = 0; f < step; ++f) sx[xc + f] = sy[xc + f] = kChunkOff;
      continue;
    }
    const int32_t ax = vdx[i] + (xs + xc) * 65536, dx = vdx[i + 1] - vdx[i];
    const int32_t ay = vdy[i] + y16, dy = vdy[i + 1] - vdy[i];
    for (int f = 0; f < step; ++f) {
      sx[xc + f] = ax + f * 65536 + ((dx * f + half) >> step_bits);
      sy[xc + f] = ay + ((dy * f + half) >> step_bits);
    }
  }
}

// The per-pixel set-up of a bilinear chunk in lanes: from the positions
// (sx, sy; Q.16, int32), whether the pixel is inside (all four taps in the
// frame and the window: the staged path), or needs the general path (border),
// or gets the fill; its first tap column and window row, and its two weights.
// Bilinear weights are exact: the second tap's weight of phase p is
// p << (14 - phase_bits) (Init checks the table against that).
struct BilinearSetUp {
  int32_t sx[kChunk], sy[kChunk];
  int32_t x0[kChunk], row[kChunk];
  int32_t wx[kChunk], wy[kChunk];
  int32_t inside[kChunk], border[kChunk];  // 0 or 1; int32 like the rest, so all lanes are one width
};
// The fast paths' bounds for one row and an N-tap filter, in 32 bits (Init
// checks the ranges): where a Q.16 source position is on the image, how it
// splits into tap and phase, and which first taps (x0, y0) keep all N x N
// taps inside the frame and the driver's window of rows.
struct FastLimits {
  static constexpr int32_t kLow = -(1 << 15);  // smallest position on the image: -1/2 pixel
  int32_t xmax, ymax;                          // largest position on the image
  int32_t col_hi, row_lo, row_hi, first_row;
  int32_t qround, shift, phase_bits, mask;
  // 1 when (px, py) is on the image; & rather than && (no branches), so loops vectorise.
  int32_t On(int32_t px, int32_t py) const { return (px >= kLow) & (py >= kLow) & (px <= xmax) & (py <= ymax); }
};
FastLimits MakeFastLimits(const RowArgs& a, int height, int taps, int phase_bits) {
  FastLimits l;
  l.xmax = a.width * 65536 + FastLimits::kLow;  // < 2^30
  l.ymax = height * 65536 + FastLimits::kLow;
  l.col_hi = a.width - taps;
  l.row_lo = a.first_row > 0 ? a.first_row : 0;
  l.row_hi = (a.first_row + a.row_count < height ? a.first_row + a.row_count : height) - taps;
  l.first_row = a.first_row;
  l.phase_bits = phase_bits;
  l.shift = 16 - phase_bits;
  l.mask = (1 << phase_bits) - 1;
  l.qround = 1 << (l.shift - 1);
  return l;
}

// A pixel's class in ProcessRowLanes: all taps inside the frame and the
// row window, off the image (output 0), or neither (a border: SetUpTaps).
#ifdef CAMSIM_X86_AVX512
// ChunkPositions in sixteen lanes, the same integers: each pixel's two nodes
// picked by vpermt2d from the nodes the chunk reads (at most 17, those of
// the cells that start before n, as ChunkPositions reads them).
CAMSIM_AVX512_TARGET void ChunkPositionsAvx512(const int32_t* vdx, const int32_t* vdy, int xs, int n, int y,
                                               int step_bits, int32_t* sx, int32_t* sy) {
  const int i0 = xs >> step_bits;
  const int count = ((n - 1) >> step_bits) + 2;  // n >= 1
  const __mmask16 m0 = count >= 16 ? 0xFFFF : static_cast<__mmask16>((1u << count) - 1);
  const __mmask16 m1 = count > 16 ? static_cast<__mmask16>((1u << (count - 16)) - 1) : 0;
  const __m512i nx0 = _mm512_maskz_loadu_epi32(m0, vdx + i0), nx1 = _mm512_maskz_loadu_epi32(m1, vdx + i0 + 16);
  const __m512i ny0 = _mm512_maskz_loadu_epi32(m0, vdy + i0), ny1 = _mm512_maskz_loadu_epi32(m1, vdy + i0 + 16);
  const __m128i shift = _mm_cvtsi32_si128(step_bits);
  const __m512i fraction = _mm512_set1_epi32((1 << step_bits) - 1), half = _mm512_set1_epi32((1 << step_bits) >> 1);
  const __m512i none = _mm512_set1_epi32(kNoSource), one = _mm512_set1_epi32(1);
  const __m512i y16 = _mm512_set1_epi32(y * 65536);
  for (int p = 0; p < kChunk; p += 16) {
    const __m512i f = _mm512_add_epi32(_mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15),
                                       _mm512_set1_epi32(p));
    const __m512i cell = _mm512_srl_epi32(f, shift), fr = _mm512_and_si512(f, fraction);
    const __m512i ax = _mm512_permutex2var_epi32(nx0, cell, nx1);
    const __m512i bx = _mm512_permutex2var_epi32(nx0, _mm512_add_epi32(cell, one), nx1);
    const __m512i ay = _mm512_permutex2var_epi32(ny0, cell, ny1);
    const __m512i by = _mm512_permutex2var_epi32(ny0, _mm512_add_epi32(cell, one), ny1);
    const __mmask16 fill = _mm512_cmpeq_epi32_mask(ax, none) | _mm512_cmpeq_epi32_mask(bx, none) |
                           _mm512_cmpge_epi32_mask(_mm512_sub_epi32(f, fr), _mm512_set1_epi32(n));
    const __m512i dx = _mm512_sub_epi32(bx, ax), dy = _mm512_sub_epi32(by, ay);
    const __m512i ex = _mm512_sra_epi32(_mm512_add_epi32(_mm512_mullo_epi32(dx, fr), half), shift);
    const __m512i ey = _mm512_sra_epi32(_mm512_add_epi32(_mm512_mullo_epi32(dy, fr), half), shift);
    const __m512i column16 = _mm512_slli_epi32(_mm512_add_epi32(f, _mm512_set1_epi32(xs)), 16);
    const __m512i px = _mm512_add_epi32(_mm512_add_epi32(ax, column16), ex);
    const __m512i py = _mm512_add_epi32(_mm512_add_epi32(ay, y16), ey);
    _mm512_storeu_si512(sx + p, _mm512_mask_mov_epi32(px, fill, _mm512_set1_epi32(kChunkOff)));
    _mm512_storeu_si512(sy + p, _mm512_mask_mov_epi32(py, fill, _mm512_set1_epi32(kChunkOff)));
  }
}
#endif

// ChunkPositions, in AVX-512 lanes where the CPU has them (avx512).
inline void ChunkPositionsFor(bool avx512, const int32_t* vdx, const int32_t* vdy, int xs, int n, int y,
                              int step_bits, int32_t* sx, int32_t* sy) {
#ifdef CAMSIM_X86_AVX512
  if (avx512) return ChunkPositionsAvx512(vdx, vdy, xs, n, y, step_bits, sx, sy);
#else
  (void)avx512;
#endif
  ChunkPositions(vdx, vdy, xs, n, y, step_bits, sx, sy);
}

constexpr int32_t kPixelBorder = 0, kPixelInterior = 1, kPixelOff = 2;

#ifdef CAMSIM_X86_AVX2  // ProcessRowLanes runs only there
// ProcessRowLanes' per-chunk set-up: from the source positions
// (ChunkPositions), per pixel its first tap column and row (relative to the
// window), its two phases and its class, branch-free so that the loop
// vectorises; off the image (or past n) the position is taken as 0, never used.
CAMSIM_CPU_CLONES
void ClassifyChunk(int n, const FastLimits l, int before, const int32_t* __restrict sx, const int32_t* __restrict sy,
                   int32_t (*__restrict by_pixel)[kChunk]) {
  for (int f = 0; f < kChunk; ++f) {
    const int32_t on = (f < n) & l.On(sx[f], sy[f]);
    const int32_t px = on ? sx[f] : 0, py = on ? sy[f] : 0;
    const int32_t qx = (px + l.qround) >> l.shift, qy = (py + l.qround) >> l.shift;
    const int32_t x0 = (qx >> l.phase_bits) - before, y0 = (qy >> l.phase_bits) - before;
    by_pixel[0][f] = x0;
    by_pixel[1][f] = y0 - l.first_row;
    by_pixel[2][f] = qx & l.mask;
    by_pixel[3][f] = qy & l.mask;
    const int32_t inside = (x0 >= 0) & (x0 <= l.col_hi) & (y0 >= l.row_lo) & (y0 <= l.row_hi);
    by_pixel[4][f] = on ? (inside ? kPixelInterior : kPixelBorder) : kPixelOff;
  }
}
#endif

CAMSIM_CPU_CLONES
void BilinearSetUpLanes(BilinearSetUp* __restrict u, const FastLimits l) {
  const int wshift = DistortionStage::kWeightFracBits - l.phase_bits;
  for (int f = 0; f < kChunk; ++f) {
    const int32_t px = u->sx[f], py = u->sy[f];
    const int32_t on = l.On(px, py);
    const int32_t qx = (px + l.qround) >> l.shift, qy = (py + l.qround) >> l.shift;
    const int32_t x0 = qx >> l.phase_bits, y0 = qy >> l.phase_bits;
    const int32_t inside = on & (x0 >= 0) & (x0 <= l.col_hi) & (y0 >= l.row_lo) & (y0 <= l.row_hi);
    const int32_t keep = -inside;  // all ones when inside
    u->inside[f] = inside;
    u->border[f] = on & (inside ^ 1);
    u->x0[f] = x0 & keep;
    u->row[f] = (y0 - l.first_row) & keep;
    u->wx[f] = ((qx & l.mask) << wshift) & keep;
    u->wy[f] = ((qy & l.mask) << wshift) & keep;
  }
}

#ifdef CAMSIM_X86_AVX2
// The bilinear fast path with AVX2 (replaces the staging and BilinearLanes).
// Eight neighbouring pixels of a smooth remap read a short run of columns
// from at most three rows: per row and channel, two 8-sample loads cover
// columns min(x0) .. min(x0) + 15 and vpermd picks each lane's two taps.
// A group of eight qualifies when all are inside, their tap rows lie in
// row0 .. row0 + 2 (two values of row), and max(x0) - min(x0) <= 14 with
// min(x0) + 15 < width; others (frame borders, strong compression) take the
// scalar Lerp32 per pixel. Both give BilinearLanes' bits.

// Software prefetch of the samples a group's pixels will read one or two
// output rows later: source rows move down as output rows do, and the next
// output row first touches the row below the group's taps (a row not yet in the
// cache: for most of the frame, the hardware prefetcher sees too short a run
// of it to start). Two rows ahead measured best (bilinear RGB 1080p: one row
// ahead 21-22 ms, two 20.2-20.6, three the same, none 30-31). Prefetches
// `cols` columns from `col` of window row last_tap_row + 2, if the window
// has it. No effect on the output.
constexpr int kPrefetchRowsAhead = 2;
CAMSIM_AVX2_TARGET inline void PrefetchBelow(const RowIn* rows, int row_count, int last_tap_row, int plane, int col,
                                             int cols) {
  const int row = last_tap_row + kPrefetchRowsAhead;
  if (row >= row_count) return;
  const uint32_t* p = rows[row].ch[plane] + col;
  for (int x = 0; x < cols; x += 16) _mm_prefetch(reinterpret_cast<const char*>(p + x), _MM_HINT_T0);
}

// Lerp32 in eight lanes.
CAMSIM_AVX2_TARGET inline __m256i Lerp32x8(__m256i a, __m256i b, __m256i w) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  const __m256i low = _mm256_set1_epi32(0xFFFF);
  const __m256i dh = _mm256_sub_epi32(_mm256_srli_epi32(b, 16), _mm256_srli_epi32(a, 16));
  const __m256i dl = _mm256_sub_epi32(_mm256_and_si256(b, low), _mm256_and_si256(a, low));
  const __m256i x = _mm256_mullo_epi32(w, dh), y = _mm256_mullo_epi32(w, dl);
  const __m256i r = _mm256_srai_epi32(_mm256_add_epi32(y, _mm256_set1_epi32(1 << (kF - 1))), kF);
  return _mm256_add_epi32(_mm256_add_epi32(a, _mm256_slli_epi32(x, 2)), r);
}

// Lane i gets run[idx[i]] from run = (lo, hi), 0 <= idx <= 15.
CAMSIM_AVX2_TARGET inline __m256i Pick16(__m256i lo, __m256i hi, __m256i idx) {
  const __m256i from_hi = _mm256_cmpgt_epi32(idx, _mm256_set1_epi32(7));
  return _mm256_blendv_epi8(_mm256_permutevar8x32_epi32(lo, idx), _mm256_permutevar8x32_epi32(hi, idx), from_hi);
}

// The bilinear value of eight pixels, the even lanes of plane `even`, the
// odd ones of plane `odd` (RGB: the same plane; CFA site only: the sites'
// colours, each lane's taps picked from its own plane before the one
// interpolation): rows r0, r0 + 1 and, when `three`, r0 + 2 of the window;
// `lower` selects per lane whether its taps are rows (r0, r0 + 1) or
// (r0 + 1, r0 + 2).
CAMSIM_AVX2_TARGET inline __m256i BilinearRun8(const RowIn* rows, int r0, bool three, int even, int odd, int col,
                                               __m256i ia, __m256i ib, __m256i lower, __m256i wx, __m256i wy) {
  const __m256i odd_lanes = _mm256_setr_epi32(0, -1, 0, -1, 0, -1, 0, -1);
  __m256i h[3];
  for (int r = 0; r < (three ? 3 : 2); ++r) {
    const uint32_t* p = rows[r0 + r].ch[even] + col;
    const __m256i lo = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
    const __m256i hi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p + 8));
    __m256i a = Pick16(lo, hi, ia), b = Pick16(lo, hi, ib);
    if (odd != even) {
      const uint32_t* q = rows[r0 + r].ch[odd] + col;
      const __m256i lo_o = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(q));
      const __m256i hi_o = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(q + 8));
      a = _mm256_blendv_epi8(a, Pick16(lo_o, hi_o, ia), odd_lanes);
      b = _mm256_blendv_epi8(b, Pick16(lo_o, hi_o, ib), odd_lanes);
    }
    h[r] = Lerp32x8(a, b, wx);
  }
  if (!three) return Lerp32x8(h[0], h[1], wy);
  const __m256i top = _mm256_blendv_epi8(h[0], h[1], lower);
  const __m256i bottom = _mm256_blendv_epi8(h[1], h[2], lower);
  return Lerp32x8(top, bottom, wy);
}

// k->v for a chunk set up in u: channels 0..2 into v[0..2] (RGB), or with
// site_only the colour of each pixel's CFA site into v[0] (colours c_even and
// c_odd alternate along the row; the chunk starts on an even column).
// One group of eight pixels from f (a multiple of 8) of BilinearChunkAvx2.
CAMSIM_AVX2_TARGET inline void BilinearGroup8(const RowIn* rows, int row_count, const BilinearSetUp& u, int width,
                                              bool site_only, int c_even, int c_odd, int f, BilinearChunk* k) {
  const __m256i x0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(u.x0 + f));
  const __m256i row = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(u.row + f));
  const __m256i outside = _mm256_cmpeq_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(u.inside + f)),
                                             _mm256_setzero_si256());
  // The group's extremes of x0 and row, both at once: lanes 0-3 reduce
  // x0, lanes 4-7 row.
  const __m256i lo = _mm256_permute2x128_si256(x0, row, 0x20), hi = _mm256_permute2x128_si256(x0, row, 0x31);
  __m256i mn = _mm256_min_epi32(lo, hi), mx = _mm256_max_epi32(lo, hi);
  mn = _mm256_min_epi32(mn, _mm256_shuffle_epi32(mn, 0x4E));
  mx = _mm256_max_epi32(mx, _mm256_shuffle_epi32(mx, 0x4E));
  mn = _mm256_min_epi32(mn, _mm256_shuffle_epi32(mn, 0xB1));
  mx = _mm256_max_epi32(mx, _mm256_shuffle_epi32(mx, 0xB1));
  const int xmin = _mm256_cvtsi256_si32(mn), xmax = _mm256_cvtsi256_si32(mx);
  const int rmin = _mm256_extract_epi32(mn, 4), rmax = _mm256_extract_epi32(mx, 4);
  if (_mm256_testz_si256(outside, outside) && rmax - rmin <= 1 && xmax - xmin <= 14 && xmin + 15 < width) {
    const __m256i ia = _mm256_sub_epi32(x0, _mm256_set1_epi32(xmin));
    const __m256i ib = _mm256_add_epi32(ia, _mm256_set1_epi32(1));
    const __m256i lower = _mm256_cmpgt_epi32(row, _mm256_set1_epi32(rmin));
    const __m256i wx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(u.wx + f));
    const __m256i wy = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(u.wy + f));
    const bool three = rmax > rmin;
    if (site_only) {
      PrefetchBelow(rows, row_count, rmax + 1, c_even, xmin, 16);
      PrefetchBelow(rows, row_count, rmax + 1, c_odd, xmin, 16);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(k->v[0] + f),
                          BilinearRun8(rows, rmin, three, c_even, c_odd, xmin, ia, ib, lower, wx, wy));
    } else {
      for (int c = 0; c < 3; ++c) PrefetchBelow(rows, row_count, rmax + 1, c, xmin, 16);
      for (int c = 0; c < 3; ++c)
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(k->v[c] + f),
                            BilinearRun8(rows, rmin, three, c, c, xmin, ia, ib, lower, wx, wy));
    }
    return;
  }
  for (int i = f; i < f + 8; ++i) {
    const int channels = site_only ? 1 : 3;
    for (int c = 0; c < channels; ++c) {
      if (!u.inside[i]) {
        k->v[c][i] = 0;
        continue;
      }
      const int plane = site_only ? ((i & 1) ? c_odd : c_even) : c;
      const uint32_t* p0 = rows[u.row[i]].ch[plane] + u.x0[i];
      const uint32_t* p1 = rows[u.row[i] + 1].ch[plane] + u.x0[i];
      k->v[c][i] = Lerp32(Lerp32(p0[0], p0[1], u.wx[i]), Lerp32(p1[0], p1[1], u.wx[i]), u.wy[i]);
    }
  }
}

CAMSIM_AVX2_TARGET
void BilinearChunkAvx2(const RowIn* rows, int row_count, const BilinearSetUp& u, int width, bool site_only,
                       int c_even, int c_odd, BilinearChunk* k) {
  for (int f = 0; f < kChunk; f += 8) BilinearGroup8(rows, row_count, u, width, site_only, c_even, c_odd, f, k);
}

#ifdef CAMSIM_X86_AVX512
// BilinearChunkAvx2 in sixteen lanes: a group of sixteen pixels reads
// columns min(x0) .. min(x0) + 31 (two loads per row, vpermt2d picks each
// lane's two taps) from rows rmin .. rmax + 1 of the window, rmax - rmin <=
// kMaxBilinearSpread16 (sixteen pixels drift over more rows than eight near
// a strongly distorted frame's corners); each lane takes its two rows' values
// by mask. The extremes are those of the inside lanes; the others compute
// with any taps in the run and are written 0 (BilinearGroup8's fill). A group
// that does not qualify goes as two groups of eight. The same Lerp32 steps,
// so the same bits.
constexpr int kMaxBilinearSpread16 = 3;

CAMSIM_AVX512_TARGET inline __m512i Lerp32x16(__m512i a, __m512i b, __m512i w) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  const __m512i low = _mm512_set1_epi32(0xFFFF);
  const __m512i dh = _mm512_sub_epi32(_mm512_srli_epi32(b, 16), _mm512_srli_epi32(a, 16));
  const __m512i dl = _mm512_sub_epi32(_mm512_and_si512(b, low), _mm512_and_si512(a, low));
  const __m512i x = _mm512_mullo_epi32(w, dh), y = _mm512_mullo_epi32(w, dl);
  const __m512i r = _mm512_srai_epi32(_mm512_add_epi32(y, _mm512_set1_epi32(1 << (kF - 1))), kF);
  return _mm512_add_epi32(_mm512_add_epi32(a, _mm512_slli_epi32(x, 2)), r);
}

// The bilinear value of sixteen pixels, the even lanes of plane `even`, the
// odd ones of plane `odd` (as BilinearRun8): row_is[d] holds the lanes whose
// top tap row is rmin + d (d = 1 .. spread; the rest rmin).
[[gnu::always_inline]] CAMSIM_AVX512_TARGET inline __m512i BilinearRun16(const RowIn* rows, int rmin, int spread,
                                                                          const __mmask16* row_is, int even, int odd,
                                                                          int col, __m512i ia, __m512i ib, __m512i wx,
                                                                          __m512i wy) {
  constexpr __mmask16 kOdd = 0xAAAA;
  __m512i h[kMaxBilinearSpread16 + 2] = {};  // [0, spread + 1] are set
  for (int r = 0; r <= spread + 1; ++r) {
    const uint32_t* p = rows[rmin + r].ch[even] + col;
    const __m512i lo = _mm512_loadu_si512(p), hi = _mm512_loadu_si512(p + 16);
    __m512i a = _mm512_permutex2var_epi32(lo, ia, hi), b = _mm512_permutex2var_epi32(lo, ib, hi);
    if (odd != even) {
      const uint32_t* q = rows[rmin + r].ch[odd] + col;
      const __m512i lo_o = _mm512_loadu_si512(q), hi_o = _mm512_loadu_si512(q + 16);
      a = _mm512_mask_mov_epi32(a, kOdd, _mm512_permutex2var_epi32(lo_o, ia, hi_o));
      b = _mm512_mask_mov_epi32(b, kOdd, _mm512_permutex2var_epi32(lo_o, ib, hi_o));
    }
    h[r] = Lerp32x16(a, b, wx);
  }
  __m512i top = h[0], bottom = h[1];
  for (int d = 1; d <= spread; ++d) {
    top = _mm512_mask_mov_epi32(top, row_is[d], h[d]);
    bottom = _mm512_mask_mov_epi32(bottom, row_is[d], h[d + 1]);
  }
  return Lerp32x16(top, bottom, wy);
}

CAMSIM_AVX512_TARGET
void BilinearChunkAvx512(const RowIn* rows, int row_count, const BilinearSetUp& u, int width, bool site_only,
                         int c_even, int c_odd, BilinearChunk* k) {
  for (int f = 0; f < kChunk; f += 16) {
    const __mmask16 inside = _mm512_test_epi32_mask(_mm512_loadu_si512(u.inside + f), _mm512_set1_epi32(1));
    if (inside == 0) {  // no lane inside: all 0, as BilinearGroup8
      for (int c = 0; c < (site_only ? 1 : 3); ++c) _mm512_storeu_si512(k->v[c] + f, _mm512_setzero_si512());
      continue;
    }
    const __m512i x0 = _mm512_loadu_si512(u.x0 + f);
    const __m512i row = _mm512_loadu_si512(u.row + f);
    const int xmin = _mm512_mask_reduce_min_epi32(inside, x0), xmax = _mm512_mask_reduce_max_epi32(inside, x0);
    const int rmin = _mm512_mask_reduce_min_epi32(inside, row);
    const int spread = _mm512_mask_reduce_max_epi32(inside, row) - rmin;
    if (spread > kMaxBilinearSpread16 || xmax - xmin > 30 || xmin + 31 >= width) {
      BilinearGroup8(rows, row_count, u, width, site_only, c_even, c_odd, f, k);
      BilinearGroup8(rows, row_count, u, width, site_only, c_even, c_odd, f + 8, k);
      continue;
    }
    const __m512i ia = _mm512_sub_epi32(x0, _mm512_set1_epi32(xmin));
    const __m512i ib = _mm512_add_epi32(ia, _mm512_set1_epi32(1));
    __mmask16 row_is[kMaxBilinearSpread16 + 1];
    for (int d = 1; d <= spread; ++d) row_is[d] = _mm512_cmpeq_epi32_mask(row, _mm512_set1_epi32(rmin + d));
    const __m512i wx = _mm512_loadu_si512(u.wx + f), wy = _mm512_loadu_si512(u.wy + f);
    const int last_tap_row = rmin + spread + 1;
    if (site_only) {
      PrefetchBelow(rows, row_count, last_tap_row, c_even, xmin, 32);
      PrefetchBelow(rows, row_count, last_tap_row, c_odd, xmin, 32);
      _mm512_storeu_si512(k->v[0] + f, _mm512_maskz_mov_epi32(inside, BilinearRun16(rows, rmin, spread, row_is, c_even,
                                                                                    c_odd, xmin, ia, ib, wx, wy)));
    } else {
      for (int c = 0; c < 3; ++c) PrefetchBelow(rows, row_count, last_tap_row, c, xmin, 32);
      for (int c = 0; c < 3; ++c)
        _mm512_storeu_si512(k->v[c] + f, _mm512_maskz_mov_epi32(inside, BilinearRun16(rows, rmin, spread, row_is, c,
                                                                                      c, xmin, ia, ib, wx, wy)));
    }
  }
}
#endif

// Lanes = pixels for the N-tap filters (bicubic, Lanczos-3): eight pixels
// whose taps are all interior, whose first tap rows take at most two values
// (rmin, rmin + 1) and whose tap columns lie in xmin .. xmin + 8 L - 1.
// Per tap row, L 8-sample loads and vpermd give each lane its N samples.
// The sums are FilterInterior's, exactly, in 32-bit lanes: with the samples
// split into 16-bit halves, s = sum w p = 2^16 SH + SL, where SH = sum w hi
// and SL = sum w lo are exact in int32 (Init checks sum |w| < 2^15 for every
// phase; vpmaddwd sums them two taps at a time, FilterLanesAvx2), so the
// rounded row sum is h = 4 SH + q, q = (SL + 2^13) >> 14;
// the vertical sum 4 sum wy SH + sum wy q is taken in int64 lanes (even and
// odd pixels apart), rounded, clamped to the 2x2 samples and packed back.
struct FilterLanes {
  __m256i x0;     // first tap column - xmin
  __m256i lower;  // all ones where the first tap row is rmin + 1
  __m256i wp[DistortionStage::kLaneTaps / 2];  // horizontal weights by pairs of taps: w 2k in the low word, w 2k+1 in the high
  __m256i start;  // the row sums' start: 2^15 times the sum of the horizontal weights
  __m256i wy[DistortionStage::kLaneTaps];
  bool ring_clamp;  // else only saturation to [0, 2^32 - 1]
};

// Each lane's N weights for its phase, tap by tap: the eight lanes' rows of
// the phase-major table (kLaneTaps int32 per phase) transposed as an 8 x 8
// block (a load per lane and 22 shuffles, against N gathers).
template <int N>
CAMSIM_AVX2_TARGET inline void LaneWeights(const int32_t* table, const int32_t* phase, __m256i* w) {
  __m256i r[8], t[8], u[8];
  for (int k = 0; k < 8; ++k)
    r[k] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(table + phase[k] * DistortionStage::kLaneTaps));
  for (int k = 0; k < 8; k += 2) {  // t[k]: taps 0,1 | 4,5 of rows k, k + 1; t[k + 1]: taps 2,3 | 6,7
    t[k] = _mm256_unpacklo_epi32(r[k], r[k + 1]);
    t[k + 1] = _mm256_unpackhi_epi32(r[k], r[k + 1]);
  }
  for (int k = 0; k < 8; k += 4) {  // u[k + j]: tap j | tap j + 4 of rows k .. k + 3
    u[k] = _mm256_unpacklo_epi64(t[k], t[k + 2]);
    u[k + 1] = _mm256_unpackhi_epi64(t[k], t[k + 2]);
    u[k + 2] = _mm256_unpacklo_epi64(t[k + 1], t[k + 3]);
    u[k + 3] = _mm256_unpackhi_epi64(t[k + 1], t[k + 3]);
  }
  for (int j = 0; j < N; ++j)
    w[j] = j < 4 ? _mm256_permute2x128_si256(u[j], u[j + 4], 0x20) : _mm256_permute2x128_si256(u[j - 4], u[j], 0x31);
}

// Lane i gets run[idx[i]] from run = v[0 .. L-1] (8 samples each), 0 <= idx < 8 L.
template <int L>
CAMSIM_AVX2_TARGET inline __m256i PickRun(const __m256i* v, __m256i idx) {
  __m256i r = _mm256_permutevar8x32_epi32(v[0], idx);
  for (int l = 1; l < L; ++l)
    r = _mm256_blendv_epi8(r, _mm256_permutevar8x32_epi32(v[l], idx),
                           _mm256_cmpgt_epi32(idx, _mm256_set1_epi32(8 * l - 1)));
  return r;
}

template <int N, int L>
CAMSIM_AVX2_TARGET __m256i FilterLanesAvx2(const RowIn* rows, int rmin, bool two, int plane, int xmin,
                                           const FilterLanes& in) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  constexpr int kBefore = N / 2 - 1;
  const __m256i one = _mm256_set1_epi32(1);
  const __m256i flip = _mm256_set1_epi32(0x80008000);
  // The row sums by vpmaddwd, two taps at a time: per pair, its weights
  // (in.wp) against the taps' low halves, then their high halves, as words
  // offset by -2^15 (xor 0x8000; the sums start at in.start to make up for
  // it). The products and sums are the 32-bit ones of the halves, modulo
  // 2^32, so the same.
  __m256i sh[N + 1], q[N + 1], clamp[3][2];
  const int row_count = two ? N + 1 : N;
  for (int r = 0; r < row_count; ++r) {
    const uint32_t* p = rows[rmin + r].ch[plane] + xmin;
    __m256i x[L];  // the samples, xor 0x80008000
    for (int l = 0; l < L; ++l)
      x[l] = _mm256_xor_si256(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(p + 8 * l)), flip);
    __m256i h = in.start, lo = in.start, idx = in.x0;
    for (int t = 0; t < N; t += 2, idx = _mm256_add_epi32(idx, _mm256_add_epi32(one, one))) {
      const __m256i a = PickRun<L>(x, idx), b = PickRun<L>(x, _mm256_add_epi32(idx, one));
      const __m256i wp = in.wp[t / 2];
      lo = _mm256_add_epi32(lo, _mm256_madd_epi16(_mm256_blend_epi16(a, _mm256_slli_epi32(b, 16), 0xAA), wp));
      h = _mm256_add_epi32(h, _mm256_madd_epi16(_mm256_blend_epi16(_mm256_srli_epi32(a, 16), b, 0xAA), wp));
      for (int u = t; u < t + 2; ++u)
        if (r >= kBefore && r <= kBefore + 2 && (u == kBefore || u == kBefore + 1))
          clamp[r - kBefore][u - kBefore] = _mm256_xor_si256(u == t ? a : b, flip);
    }
    sh[r] = h;
    q[r] = _mm256_srai_epi32(_mm256_add_epi32(lo, _mm256_set1_epi32(1 << (kF - 1))), kF);
  }
  __m256i even = _mm256_setzero_si256(), odd = _mm256_setzero_si256();
  for (int k = 0; k < N; ++k) {
    const __m256i hk = two ? _mm256_blendv_epi8(sh[k], sh[k + 1], in.lower) : sh[k];
    const __m256i qk = two ? _mm256_blendv_epi8(q[k], q[k + 1], in.lower) : q[k];
    const __m256i w4 = _mm256_slli_epi32(in.wy[k], 2);
    even = _mm256_add_epi64(even, _mm256_add_epi64(_mm256_mul_epi32(w4, hk), _mm256_mul_epi32(in.wy[k], qk)));
    odd = _mm256_add_epi64(
        odd, _mm256_add_epi64(_mm256_mul_epi32(_mm256_srli_epi64(w4, 32), _mm256_srli_epi64(hk, 32)),
                              _mm256_mul_epi32(_mm256_srli_epi64(in.wy[k], 32), _mm256_srli_epi64(qk, 32))));
  }
  // (acc + 2^13) >> 14 with a logical shift: |acc| < 2^50, so adding 2^54
  // keeps it positive and adds exactly 2^40 to the quotient.
  const __m256i bias = _mm256_set1_epi64x((int64_t{1} << (kF - 1)) + (int64_t{1} << 54));
  const __m256i unbias = _mm256_set1_epi64x(int64_t{1} << 40);
  even = _mm256_sub_epi64(_mm256_srli_epi64(_mm256_add_epi64(even, bias), kF), unbias);
  odd = _mm256_sub_epi64(_mm256_srli_epi64(_mm256_add_epi64(odd, bias), kF), unbias);
  // Ringing clamp to the 2x2 samples around the source; without it, to
  // [0, 2^32 - 1] (SatU32).
  __m256i lo = _mm256_setzero_si256(), hi = _mm256_set1_epi32(-1);
  if (in.ring_clamp) {
    __m256i s00 = clamp[0][0], s01 = clamp[0][1], s10 = clamp[1][0], s11 = clamp[1][1];
    if (two) {
      s00 = _mm256_blendv_epi8(s00, clamp[1][0], in.lower);
      s01 = _mm256_blendv_epi8(s01, clamp[1][1], in.lower);
      s10 = _mm256_blendv_epi8(s10, clamp[2][0], in.lower);
      s11 = _mm256_blendv_epi8(s11, clamp[2][1], in.lower);
    }
    lo = _mm256_min_epu32(_mm256_min_epu32(s00, s01), _mm256_min_epu32(s10, s11));
    hi = _mm256_max_epu32(_mm256_max_epu32(s00, s01), _mm256_max_epu32(s10, s11));
  }
  const __m256i low32 = _mm256_set1_epi64x(0xFFFFFFFF);
  const __m256i lo_e = _mm256_and_si256(lo, low32), lo_o = _mm256_srli_epi64(lo, 32);
  const __m256i hi_e = _mm256_and_si256(hi, low32), hi_o = _mm256_srli_epi64(hi, 32);
  even = _mm256_blendv_epi8(even, lo_e, _mm256_cmpgt_epi64(lo_e, even));
  even = _mm256_blendv_epi8(even, hi_e, _mm256_cmpgt_epi64(even, hi_e));
  odd = _mm256_blendv_epi8(odd, lo_o, _mm256_cmpgt_epi64(lo_o, odd));
  odd = _mm256_blendv_epi8(odd, hi_o, _mm256_cmpgt_epi64(odd, hi_o));
  return _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
}

// One set of lanes of ProcessRowLanes: its slots' arrays from the set's
// first. FilterSet8 and FilterSet16 filter the set's interior pixels and
// write them (lanes whose pixels are not interior compute with the first
// interior lane's taps, so that every load stays inside the row, and are not
// written), write 0 for the pixels off the image (RGB; site only, they are 0
// already), and return the mask of lanes done. They return 0, with nothing
// written, for a set whose interior pixels' first tap rows spread further
// than the kernel takes (one row for eight lanes, kMaxRowSpread16 rows for
// sixteen), or whose tap columns span more than the lanes' loads (L x lanes
// samples from the set's first tap column; at the row's end, from the
// column that makes them end with it). A set without interior pixels is
// done for its pixels off the image. Site only, lane i is the pixel x + 2 i
// of colour plane; RGB, x + i.
struct LaneSet {
  const int32_t *x0s, *rows, *phx, *phy, *cls;
  bool ring_clamp;  // DistortionConfig::ringing_clamp
};

template <int N, bool kSiteOnly>
CAMSIM_AVX2_TARGET uint32_t FilterSet8(const RowIn* rows, int row_count, int width, const int32_t* wt,
                                       const LaneSet& set, int plane, uint32_t* const* out, int x) {
  constexpr int L = kSiteOnly ? 3 : 2;
  uint32_t inside = 0, off = 0;
  for (int j = 0; j < 8; ++j) {
    inside |= static_cast<uint32_t>(set.cls[j] == kPixelInterior) << j;
    off |= static_cast<uint32_t>(set.cls[j] == kPixelOff) << j;
  }
  if (inside == 0) {
    if constexpr (!kSiteOnly)
      for (int i = 0; i < 8; ++i)
        if ((off >> i) & 1) out[0][x + i] = out[1][x + i] = out[2][x + i] = 0;
    return off;
  }
  const int first = __builtin_ctz(inside);  // the other lanes take its taps
  alignas(32) int32_t x0s[8], rws[8];
  for (int j = 0; j < 8; ++j) {
    const bool in_j = (inside >> j) & 1;
    x0s[j] = in_j ? set.x0s[j] : set.x0s[first];
    rws[j] = in_j ? set.rows[j] : set.rows[first];
  }
  int rmin = rws[0], rmax = rmin, xmin = x0s[0], xmx = xmin;
  for (int j = 1; j < 8; ++j) {
    rmin = rws[j] < rmin ? rws[j] : rmin;
    rmax = rws[j] > rmax ? rws[j] : rmax;
    xmin = x0s[j] < xmin ? x0s[j] : xmin;
    xmx = x0s[j] > xmx ? x0s[j] : xmx;
  }
  if (xmin + 8 * L > width) xmin = width - 8 * L;  // the loads end with the row
  if (rmax - rmin > 1 || xmin < 0 || xmx - xmin + N > 8 * L) return 0;
  FilterLanes in;
  in.ring_clamp = set.ring_clamp;
  in.x0 = _mm256_sub_epi32(_mm256_load_si256(reinterpret_cast<const __m256i*>(x0s)), _mm256_set1_epi32(xmin));
  in.lower = _mm256_cmpgt_epi32(_mm256_load_si256(reinterpret_cast<const __m256i*>(rws)), _mm256_set1_epi32(rmin));
  __m256i wx[N];
  LaneWeights<N>(wt, set.phx, wx);
  const __m256i low = _mm256_set1_epi32(0xFFFF);
  in.start = _mm256_setzero_si256();
  for (int k = 0; k < N / 2; ++k) {
    in.wp[k] = _mm256_or_si256(_mm256_and_si256(wx[2 * k], low), _mm256_slli_epi32(wx[2 * k + 1], 16));
    in.start = _mm256_add_epi32(in.start, _mm256_add_epi32(wx[2 * k], wx[2 * k + 1]));
  }
  in.start = _mm256_slli_epi32(in.start, 15);
  LaneWeights<N>(wt, set.phy, in.wy);
  const bool two = rmax > rmin;
  if constexpr (kSiteOnly) {  // off lanes: ProcessRowLanes has zeroed the chunk
    alignas(32) uint32_t v[8];
    PrefetchBelow(rows, row_count, rmax + N - 1, plane, xmin, 8 * L);
    _mm256_store_si256(reinterpret_cast<__m256i*>(v), FilterLanesAvx2<N, L>(rows, rmin, two, plane, xmin, in));
    for (int i = 0; i < 8; ++i)
      if ((inside >> i) & 1) out[plane][x + 2 * i] = v[i];
  } else {
    const __m256i bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    const __m256i keep = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(static_cast<int>(inside)), bit), bit);
    const __m256i write = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(static_cast<int>(inside | off)), bit), bit);
    for (int c = 0; c < 3; ++c) PrefetchBelow(rows, row_count, rmax + N - 1, c, xmin, 8 * L);
    for (int c = 0; c < 3; ++c)
      _mm256_maskstore_epi32(reinterpret_cast<int*>(out[c] + x), write,
                             _mm256_and_si256(keep, FilterLanesAvx2<N, L>(rows, rmin, two, c, xmin, in)));
  }
  return inside | off;
}

#ifdef CAMSIM_X86_AVX512
// FilterLanesAvx2 in sixteen lanes, step for step: L loads of sixteen
// samples per row, each lane's taps picked by vpermt2d (from the first 32)
// and vpermd (from the third load), the same 32-bit row sums on the 16-bit
// halves (vpmaddwd), the vertical pass in 64-bit even and odd lanes, and the same
// rounding and ringing clamp. The lanes' first tap rows may spread over S + 1
// rows (S <= kMaxRowSpread16, against AVX2's one): N + S rows are summed and
// each lane picks its N (sixteen pixels of one colour span 32 columns, over
// which a strongly distorted row's source drifts by several rows: up to 5
// near the corners of the bench's lens, BM_SensorPath; with 3, 2 % of its
// pixels were left to eight lanes or the scalar filter).
constexpr int kMaxRowSpread16 = 5;
struct FilterLanes16 {
  __m512i x0;                                 // first tap column - xmin
  __mmask16 row_is[kMaxRowSpread16 + 1];      // [d]: lanes whose first tap row is rmin + d
  __m512i wp[DistortionStage::kLaneTaps / 2], start, wy[DistortionStage::kLaneTaps];  // as FilterLanes'
  bool ring_clamp;
};

template <int L>
CAMSIM_AVX512_TARGET inline __m512i PickRun16(const __m512i* v, __m512i idx) {
  static_assert(L == 2 || L == 3, "32 or 48 samples");
  const __m512i r = _mm512_permutex2var_epi32(v[0], idx, v[1]);
  if constexpr (L == 2) return r;
  return _mm512_mask_permutexvar_epi32(r, _mm512_cmpgt_epi32_mask(idx, _mm512_set1_epi32(31)), idx, v[2]);
}

// Each lane's value of rows[first + its d], from the row values v[first .. first + S].
template <int S>
CAMSIM_AVX512_TARGET inline __m512i PickRow(const __m512i* v, int first, const FilterLanes16& in) {
  __m512i r = v[first];
  for (int d = 1; d <= S; ++d) r = _mm512_mask_mov_epi32(r, in.row_is[d], v[first + d]);
  return r;
}

// The vertical pass, rounding and ringing clamp, from the row sums of
// rows rmin .. rmin + N + S - 1 (sh: the high halves' sums; q: the low
// halves' sums rounded to integers) and the 2x2 samples around each lane's
// source (clamp[tap column][row - kBefore]).
template <int N, int S>
CAMSIM_AVX512_TARGET inline __m512i FinishLanes16(const __m512i* sh, const __m512i* q, const __m512i (*clamp)[2 + S],
                                                  const FilterLanes16& in) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  __m512i even = _mm512_setzero_si512(), odd = _mm512_setzero_si512();
  for (int k = 0; k < N; ++k) {
    const __m512i hk = PickRow<S>(sh, k, in), qk = PickRow<S>(q, k, in);
    const __m512i w4 = _mm512_slli_epi32(in.wy[k], 2);
    even = _mm512_add_epi64(even, _mm512_add_epi64(_mm512_mul_epi32(w4, hk), _mm512_mul_epi32(in.wy[k], qk)));
    odd = _mm512_add_epi64(
        odd, _mm512_add_epi64(_mm512_mul_epi32(_mm512_srli_epi64(w4, 32), _mm512_srli_epi64(hk, 32)),
                              _mm512_mul_epi32(_mm512_srli_epi64(in.wy[k], 32), _mm512_srli_epi64(qk, 32))));
  }
  // (acc + 2^13) >> 14: an arithmetic shift here (|acc| < 2^50).
  const __m512i round = _mm512_set1_epi64(int64_t{1} << (kF - 1));
  even = _mm512_srai_epi64(_mm512_add_epi64(even, round), kF);
  odd = _mm512_srai_epi64(_mm512_add_epi64(odd, round), kF);
  // Ringing clamp to the 2x2 samples around the source; without it, to
  // [0, 2^32 - 1] (SatU32).
  __m512i lo = _mm512_setzero_si512(), hi = _mm512_set1_epi32(-1);
  if (in.ring_clamp) {
    const __m512i s00 = PickRow<S>(clamp[0], 0, in), s01 = PickRow<S>(clamp[1], 0, in);
    const __m512i s10 = PickRow<S>(clamp[0], 1, in), s11 = PickRow<S>(clamp[1], 1, in);
    lo = _mm512_min_epu32(_mm512_min_epu32(s00, s01), _mm512_min_epu32(s10, s11));
    hi = _mm512_max_epu32(_mm512_max_epu32(s00, s01), _mm512_max_epu32(s10, s11));
  }
  const __m512i low32 = _mm512_set1_epi64(0xFFFFFFFF);
  even = _mm512_min_epi64(_mm512_max_epi64(even, _mm512_and_si512(lo, low32)), _mm512_and_si512(hi, low32));
  odd = _mm512_min_epi64(_mm512_max_epi64(odd, _mm512_srli_epi64(lo, 32)), _mm512_srli_epi64(hi, 32));
  return _mm512_mask_blend_epi32(0xAAAA, even, _mm512_slli_epi64(odd, 32));
}

template <int N, int L, int S>
CAMSIM_AVX512_TARGET __m512i FilterLanesAvx512(const RowIn* rows, int rmin, int plane, int xmin,
                                               const FilterLanes16& in) {
  constexpr int kF = DistortionStage::kWeightFracBits;
  constexpr int kBefore = N / 2 - 1;
  constexpr __mmask32 kHighWords = 0xAAAAAAAA;
  const __m512i one = _mm512_set1_epi32(1), flip = _mm512_set1_epi32(0x80008000);
  __m512i sh[N + S], q[N + S], clamp[2][2 + S];  // clamp[tap column][row - kBefore]
  for (int r = 0; r < N + S; ++r) {
    const uint32_t* p = rows[rmin + r].ch[plane] + xmin;
    __m512i x[L];  // the samples, xor 0x80008000
    for (int l = 0; l < L; ++l) x[l] = _mm512_xor_si512(_mm512_loadu_si512(p + 16 * l), flip);
    __m512i h = in.start, lo = in.start, idx = in.x0;
    for (int t = 0; t < N; t += 2, idx = _mm512_add_epi32(idx, _mm512_add_epi32(one, one))) {
      const __m512i a = PickRun16<L>(x, idx), b = PickRun16<L>(x, _mm512_add_epi32(idx, one));
      lo = _mm512_add_epi32(
          lo, _mm512_madd_epi16(_mm512_mask_blend_epi16(kHighWords, a, _mm512_slli_epi32(b, 16)), in.wp[t / 2]));
      h = _mm512_add_epi32(
          h, _mm512_madd_epi16(_mm512_mask_blend_epi16(kHighWords, _mm512_srli_epi32(a, 16), b), in.wp[t / 2]));
      for (int u = t; u < t + 2; ++u)
        if (r >= kBefore && r <= kBefore + 1 + S && (u == kBefore || u == kBefore + 1))
          clamp[u - kBefore][r - kBefore] = _mm512_xor_si512(u == t ? a : b, flip);
    }
    sh[r] = h;
    q[r] = _mm512_srai_epi32(_mm512_add_epi32(lo, _mm512_set1_epi32(1 << (kF - 1))), kF);
  }
  return FinishLanes16<N, S>(sh, q, clamp, in);
}

template <int N, int L>
CAMSIM_AVX512_TARGET inline __m512i FilterLanesAvx512(const RowIn* rows, int rmin, int spread, int plane, int xmin,
                                                      const FilterLanes16& in) {
  switch (spread) {
    case 0: return FilterLanesAvx512<N, L, 0>(rows, rmin, plane, xmin, in);
    case 1: return FilterLanesAvx512<N, L, 1>(rows, rmin, plane, xmin, in);
    case 2: return FilterLanesAvx512<N, L, 2>(rows, rmin, plane, xmin, in);
    case 3: return FilterLanesAvx512<N, L, 3>(rows, rmin, plane, xmin, in);
    case 4: return FilterLanesAvx512<N, L, 4>(rows, rmin, plane, xmin, in);
    default: return FilterLanesAvx512<N, L, 5>(rows, rmin, plane, xmin, in);
  }
}

// Each lane's N weights for its phase, tap by tap, from the tap-major table
// (kBlocks x 32 int32 per tap): one vpermt2d per 32 phases.
template <int N, int kBlocks>
CAMSIM_AVX512_TARGET inline void LaneWeights16(const int32_t* wtap, const int32_t* phase, __m512i* w) {
  const __m512i ph = _mm512_loadu_si512(phase);
  __mmask16 in_block[kBlocks];
  for (int b = 1; b < kBlocks; ++b)
    in_block[b] = _mm512_cmpeq_epi32_mask(_mm512_srli_epi32(ph, 5), _mm512_set1_epi32(b));
  for (int t = 0; t < N; ++t) {
    const int32_t* row = wtap + t * 32 * kBlocks;
    w[t] = _mm512_permutex2var_epi32(_mm512_loadu_si512(row), ph, _mm512_loadu_si512(row + 16));
    for (int b = 1; b < kBlocks; ++b)
      w[t] = _mm512_mask_mov_epi32(w[t], in_block[b],
                                   _mm512_permutex2var_epi32(_mm512_loadu_si512(row + 32 * b), ph,
                                                             _mm512_loadu_si512(row + 32 * b + 16)));
  }
}

// LaneWeights16 for a table of tap_stride (32, 64, 128 or 256) int32 per tap.
template <int N>
CAMSIM_AVX512_TARGET inline void LaneWeights16(const int32_t* wtap, int tap_stride, const int32_t* phase,
                                               __m512i* w) {
  switch (tap_stride) {
    case 32: return LaneWeights16<N, 1>(wtap, phase, w);
    case 64: return LaneWeights16<N, 2>(wtap, phase, w);
    case 128: return LaneWeights16<N, 4>(wtap, phase, w);
    default: return LaneWeights16<N, 8>(wtap, phase, w);
  }
}

template <int N, bool kSiteOnly>
CAMSIM_AVX512_TARGET uint32_t FilterSet16(const RowIn* rows, int row_count, int width, const int32_t* wtap,
                                          int tap_stride, const LaneSet& set, int plane, uint32_t* const* out, int x) {
  constexpr int L = kSiteOnly ? 3 : 2;
  const __m512i cls = _mm512_loadu_si512(set.cls);
  const __mmask16 inside = _mm512_cmpeq_epi32_mask(cls, _mm512_set1_epi32(kPixelInterior));
  const __mmask16 off = _mm512_cmpeq_epi32_mask(cls, _mm512_set1_epi32(kPixelOff));
  if (inside == 0) {
    if constexpr (!kSiteOnly)
      for (int c = 0; c < 3; ++c) _mm512_mask_storeu_epi32(out[c] + x, off, _mm512_setzero_si512());
    return off;
  }
  const int first = __builtin_ctz(inside);  // the other lanes take its taps
  const __m512i rv = _mm512_mask_loadu_epi32(_mm512_set1_epi32(set.rows[first]), inside, set.rows);
  const __m512i x0v = _mm512_mask_loadu_epi32(_mm512_set1_epi32(set.x0s[first]), inside, set.x0s);
  const int rmin = _mm512_reduce_min_epi32(rv), rmax = _mm512_reduce_max_epi32(rv);
  int xmin = _mm512_reduce_min_epi32(x0v);
  const int xmx = _mm512_reduce_max_epi32(x0v);
  if (xmin + 16 * L > width) xmin = width - 16 * L;  // the loads end with the row
  const int spread = rmax - rmin;
  if (spread > kMaxRowSpread16 || xmin < 0 || xmx - xmin + N > 16 * L) return 0;
  FilterLanes16 in;
  in.ring_clamp = set.ring_clamp;
  in.x0 = _mm512_sub_epi32(x0v, _mm512_set1_epi32(xmin));
  for (int d = 1; d <= spread; ++d) in.row_is[d] = _mm512_cmpeq_epi32_mask(rv, _mm512_set1_epi32(rmin + d));
  __m512i wx[N];
  LaneWeights16<N>(wtap, tap_stride, set.phx, wx);
  const __m512i low = _mm512_set1_epi32(0xFFFF);
  in.start = _mm512_setzero_si512();
  for (int k = 0; k < N / 2; ++k) {
    in.wp[k] = _mm512_or_si512(_mm512_and_si512(wx[2 * k], low), _mm512_slli_epi32(wx[2 * k + 1], 16));
    in.start = _mm512_add_epi32(in.start, _mm512_add_epi32(wx[2 * k], wx[2 * k + 1]));
  }
  in.start = _mm512_slli_epi32(in.start, 15);
  LaneWeights16<N>(wtap, tap_stride, set.phy, in.wy);
  if constexpr (kSiteOnly) {  // off lanes: ProcessRowLanes has zeroed the chunk
    PrefetchBelow(rows, row_count, rmax + N - 1, plane, xmin, 16 * L);
    alignas(64) uint32_t v[16];
    _mm512_store_si512(v, FilterLanesAvx512<N, L>(rows, rmin, spread, plane, xmin, in));
    for (int i = 0; i < 16; ++i)
      if ((inside >> i) & 1) out[plane][x + 2 * i] = v[i];
  } else {
    for (int c = 0; c < 3; ++c) PrefetchBelow(rows, row_count, rmax + N - 1, c, xmin, 16 * L);
    for (int c = 0; c < 3; ++c)
      _mm512_mask_storeu_epi32(
          out[c] + x, inside | off,
          _mm512_maskz_mov_epi32(inside, FilterLanesAvx512<N, L>(rows, rmin, spread, c, xmin, in)));
  }
  return inside | off;
}
#endif
#endif

}  // namespace

int ResampleTaps(ResampleFilter f) {
  switch (f) {
    case ResampleFilter::kBilinear: return 2;
    case ResampleFilter::kBicubic: return 4;
    case ResampleFilter::kLanczos3: return 6;
    case ResampleFilter::kLanczos4: return 8;
  }
  return 2;
}

double ResampleKernel(ResampleFilter f, double t) {
  const double a = t < 0.0 ? -t : t;
  switch (f) {
    case ResampleFilter::kBilinear: return a < 1.0 ? 1.0 - a : 0.0;
    case ResampleFilter::kBicubic: {
      // Keys (1981) cubic convolution with a = -0.5 (Catmull-Rom).
      constexpr double k = -0.5;
      if (a < 1.0) return ((k + 2.0) * a - (k + 3.0)) * a * a + 1.0;
      if (a < 2.0) return ((k * a - 5.0 * k) * a + 8.0 * k) * a - 4.0 * k;
      return 0.0;
    }
    case ResampleFilter::kLanczos3: return a < 3.0 ? Sinc(a) * Sinc(a / 3.0) : 0.0;
    case ResampleFilter::kLanczos4: return a < 4.0 ? Sinc(a) * Sinc(a / 4.0) : 0.0;
  }
  return 0.0;
}

Status DistortionStage::Configure(const DistortionConfig& c, const SensorGeometry& g,
                                  const DistortionStage* previous) {
  config_ = c;
  geometry_ = g;
  site_only_ = false;
  fast_path_ = false;
  bands_borrowed_ = false;
  configured_ = false;
  table_ = nullptr;
  weights_ = nullptr;
  const LensModel& m = config_.lens;
  if (static_cast<uint8_t>(m.model) > static_cast<uint8_t>(DistortionModel::kFisheye))
    return InvalidArgument("distortion.model", "must be off, brown or fisheye");
  if (static_cast<uint8_t>(c.filter) > static_cast<uint8_t>(ResampleFilter::kLanczos4))
    return InvalidArgument("distortion.filter", "must be bilinear, bicubic, lanczos3 or lanczos4");
  phase_bits_ = Log2Exact(c.phases);
  if (phase_bits_ < 4 || phase_bits_ > 8) return InvalidArgument("distortion.phases", "must be 16, 32, 64, 128 or 256");
  step_bits_ = Log2Exact(c.grid_step);
  if (step_bits_ < 2 || step_bits_ > 6) return InvalidArgument("distortion.grid_step", "must be 4, 8, 16, 32 or 64 pixels");
  for (int i = 0; i < 3; ++i)
    if (!(c.chromatic_scale[i] >= kMinChromatic && c.chromatic_scale[i] <= kMaxChromatic))
      return InvalidArgument("distortion.chromatic_scale", "each scale must be in [0.5, 2]");
  const DisplacementMesh& mesh = c.mesh;
  if (mesh.dxdy != nullptr) {
    if (mesh.cols < 2 || mesh.rows < 2 || mesh.cols > 4096 || mesh.rows > 4096)
      return InvalidArgument("distortion.mesh", "needs 2 to 4096 nodes per row and column");
    if (!(mesh.step >= 1.0 && mesh.step <= 16384.0))
      return InvalidArgument("distortion.mesh", "node step must be in [1, 16384] pixels");
    for (int i = 0; i < 2 * mesh.cols * mesh.rows; ++i)
      if (!(mesh.dxdy[i] >= -4096.0f && mesh.dxdy[i] <= 4096.0f))
        return InvalidArgument("distortion.mesh", "displacements must be finite, within 4096 pixels");
  }
  mesh_digest_ = MeshDigest(mesh);
  if (IdentityReason() != nullptr) {
    configured_ = true;
    return Status::Ok();
  }
  if (m.model == DistortionModel::kOff && m.fx == 0.0 && m.fy == 0.0) {
    // Mesh or chromatic aberration alone: the centre defaults to the frame's.
    config_.lens.fx = config_.lens.fy = 1.0;
    if (m.cx == 0.0 && m.cy == 0.0) {
      config_.lens.cx = (g.width - 1) / 2.0;
      config_.lens.cy = (g.height - 1) / 2.0;
    }
  }

  if (!(m.fx >= kMinFocalPx && m.fx <= kMaxFocalPx)) return InvalidArgument("distortion.fx", "must be in [1, 1e6] pixels");
  if (!(m.fy >= kMinFocalPx && m.fy <= kMaxFocalPx)) return InvalidArgument("distortion.fy", "must be in [1, 1e6] pixels");
  if (!(m.cx >= -g.width && m.cx <= 2.0 * g.width))
    return InvalidArgument("distortion.cx", "must be within one frame width of the frame");
  if (!(m.cy >= -g.height && m.cy <= 2.0 * g.height))
    return InvalidArgument("distortion.cy", "must be within one frame height of the frame");
  static constexpr const char* kKeys[6] = {"distortion.k1", "distortion.k2", "distortion.k3",
                                           "distortion.k4", "distortion.k5", "distortion.k6"};
  for (int i = 0; i < 6; ++i)
    if (!(m.k[i] >= -kMaxCoefficient && m.k[i] <= kMaxCoefficient))
      return InvalidArgument(kKeys[i], "must be finite, |k| <= 1e6");
  if (m.model == DistortionModel::kFisheye && (m.k[4] != 0.0 || m.k[5] != 0.0))
    return InvalidArgument(m.k[4] != 0.0 ? "distortion.k5" : "distortion.k6", "the fisheye model has k1..k4 only");
  if (!(m.p1 >= -kMaxTangential && m.p1 <= kMaxTangential)) return InvalidArgument("distortion.p1", "must be in [-1, 1]");
  if (!(m.p2 >= -kMaxTangential && m.p2 <= kMaxTangential)) return InvalidArgument("distortion.p2", "must be in [-1, 1]");
  if (m.model == DistortionModel::kFisheye && (m.p1 != 0.0 || m.p2 != 0.0))
    return InvalidArgument("distortion.p1", "the fisheye model has no tangential terms");

  taps_ = ResampleTaps(c.filter);
  const int step = 1 << step_bits_;
  grid_w_ = ((g.width - 1) >> step_bits_) + 2;
  grid_h_ = ((g.height - 1) >> step_bits_) + 2;
  for (int i = 0; i < 3; ++i) {
    scale_[i] = static_cast<int64_t>(Q<8, 24>::FromDouble(c.chromatic_scale[i]).raw);
    scaled_[i] = scale_[i] != (int64_t{1} << kScaleFracBits);
  }
  centre_x_ = static_cast<int64_t>(Floor(m.cx * 65536.0 + 0.5));  // Q.16, |cx| < 2^15
  centre_y_ = static_cast<int64_t>(Floor(m.cy * 65536.0 + 0.5));

  // The distorted radius the branch must cover: the farthest grid node, and
  // the farthest pixel of the frame (a fold inside it is refused).
  const auto radius = [&m](double u, double v) {
    const double x = (u - m.cx) / m.fx, y = (v - m.cy) / m.fy;
    return std::sqrt(x * x + y * y);
  };
  const double umax = static_cast<double>((grid_w_ - 1) * step), vmax = static_cast<double>((grid_h_ - 1) * step);
  double rd_nodes = 0.0, rd_frame = 0.0;
  for (int corner = 0; corner < 4; ++corner) {
    const double rn = radius(corner & 1 ? umax : 0.0, corner & 2 ? vmax : 0.0);
    const double rf = radius(corner & 1 ? g.width - 1.0 : 0.0, corner & 2 ? g.height - 1.0 : 0.0);
    if (rn > rd_nodes) rd_nodes = rn;
    if (rf > rd_frame) rd_frame = rf;
  }
  branch_ = m.model == DistortionModel::kOff ? LensBranch() : LensAnalyse(m, rd_nodes);  // off: no inverse to solve
  if (branch_.folds && branch_.rd_max < rd_frame)
    return InvalidArgument(m.model == DistortionModel::kFisheye ? "distortion.k1" : "distortion.k1",
                           "the radial model folds over (stops increasing) inside the frame, so those pixels "
                           "have no unique source: check k1..k6 (fisheye: k1..k4) and fx, fy");

  if (previous != nullptr && SameGrid(*previous)) {
    for (int j = 0; j < grid_h_; ++j) {
      band_first_[j] = previous->band_first_[j];
      band_last_[j] = previous->band_last_[j];
    }
    max_window_ = previous->max_window_;
    bands_borrowed_ = true;
    configured_ = true;
    return Status::Ok();
  }

  // Input rows per band: the floor of the lowest and highest source row of
  // the band's two node rows (every interpolated position lies between them),
  // widened by the filter's reach and one row for the rounding to phases,
  // then reflected into the frame and made monotone.
  const int h = g.height;
  const int bands = grid_h_ - 1;
  for (int j = 0; j < grid_h_; ++j) {
    double lo = 1e300, hi = -1e300;
    for (int i = 0; i < grid_w_; ++i) {
      double sx = 0.0, sy = 0.0;
      if (!NodeSource(i, j, &sx, &sy)) continue;
      for (int ch = 0; ch < 3; ++ch) {
        double y = m.cy + c.chromatic_scale[ch] * (sy - m.cy);
        if (y < -0.5) y = -0.5;
        if (y > h - 0.5) y = h - 0.5;
        if (y < lo) lo = y;
        if (y > hi) hi = y;
      }
    }
    band_first_[j] = static_cast<int16_t>(lo <= hi ? Floor(lo) : h);
    band_last_[j] = static_cast<int16_t>(lo <= hi ? Floor(hi) : -1);
  }
  const int before = taps_ / 2 - 1, after = taps_ / 2;
  for (int j = 0; j < bands; ++j) {
    int a = band_first_[j] < band_first_[j + 1] ? band_first_[j] : band_first_[j + 1];
    int b = band_last_[j] > band_last_[j + 1] ? band_last_[j] : band_last_[j + 1];
    if (a > b) a = b = (j << step_bits_) < h ? (j << step_bits_) : h - 1;  // all fill: any row
    a -= before + 1;
    b += after + 1;
    int lo = h, hi = -1;
    for (int r = a; r <= b; ++r) {
      const int rr = Reflect101(r, h);
      if (rr < lo) lo = rr;
      if (rr > hi) hi = rr;
    }
    band_first_[j] = static_cast<int16_t>(lo);
    band_last_[j] = static_cast<int16_t>(hi);
  }
  for (int j = 1; j < bands; ++j)
    if (band_last_[j] < band_last_[j - 1]) band_last_[j] = band_last_[j - 1];
  for (int j = bands - 2; j >= 0; --j)
    if (band_first_[j] > band_first_[j + 1]) band_first_[j] = band_first_[j + 1];
  max_window_ = 1;
  for (int j = 0; j < bands; ++j)
    if (band_last_[j] - band_first_[j] + 1 > max_window_) max_window_ = band_last_[j] - band_first_[j] + 1;
  if (max_window_ > kMaxWindowRows)
    return InvalidArgument("distortion.k1",
                           "the distortion bends one output row over more than 1024 input rows, beyond the "
                           "streaming driver's window; the lens is too strong for this frame height");
  configured_ = true;
  return Status::Ok();
}

bool DistortionStage::NodeSource(int i, int j, double* sx, double* sy) const {
  const LensModel& m = config_.lens;
  const double u = static_cast<double>(i << step_bits_), v = static_cast<double>(j << step_bits_);
  const double xd = (u - m.cx) / m.fx, yd = (v - m.cy) / m.fy;
  double x = 0.0, y = 0.0;
  if (!LensUndistort(m, branch_, xd, yd, &x, &y)) return false;
  *sx = m.fx * x + m.cx;
  *sy = m.fy * y + m.cy;
  if (config_.mesh.dxdy != nullptr) {
    double dx = 0.0, dy = 0.0;
    MeshDisplacement(u, v, &dx, &dy);
    *sx += dx;
    *sy += dy;
  }
  return *sx == *sx && *sy == *sy;
}

void DistortionStage::MeshDisplacement(double u, double v, double* dx, double* dy) const {
  const DisplacementMesh& mesh = config_.mesh;
  double gx = u / mesh.step, gy = v / mesh.step;
  gx = gx < 0.0 ? 0.0 : (gx > mesh.cols - 1 ? mesh.cols - 1 : gx);
  gy = gy < 0.0 ? 0.0 : (gy > mesh.rows - 1 ? mesh.rows - 1 : gy);
  int i = static_cast<int>(gx), j = static_cast<int>(gy);
  if (i > mesh.cols - 2) i = mesh.cols - 2;
  if (j > mesh.rows - 2) j = mesh.rows - 2;
  const double fx = gx - i, fy = gy - j;
  const auto at = [&mesh](int ii, int jj, int k) {
    return static_cast<double>(mesh.dxdy[(static_cast<size_t>(jj) * mesh.cols + ii) * 2 + k]);
  };
  for (int k = 0; k < 2; ++k) {
    const double top = at(i, j, k) + (at(i + 1, j, k) - at(i, j, k)) * fx;
    const double bottom = at(i, j + 1, k) + (at(i + 1, j + 1, k) - at(i, j + 1, k)) * fx;
    (k == 0 ? *dx : *dy) = top + (bottom - top) * fy;
  }
}

Result<LineFormat> DistortionStage::Plan(LineFormat in) const {
  if ((in.domain != Domain::kRadiance && in.domain != Domain::kPhotons) || in.channels != 3 || in.mosaic)
    return InvalidArgument("distortion", "needs RGB radiance or photons input (place it before the CFA)");
  if (site_only_) return LineFormat{in.domain, 1, true};
  return in;
}

const char* DistortionStage::IdentityReason() const {
  const bool chromatic = config_.chromatic_scale[0] != 1.0 || config_.chromatic_scale[1] != 1.0 ||
                         config_.chromatic_scale[2] != 1.0;
  if (chromatic || config_.mesh.dxdy != nullptr) return nullptr;
  const LensModel& m = config_.lens;
  if (m.model == DistortionModel::kOff) return "distortion.model is off and no chromatic aberration";
  if (m.model == DistortionModel::kBrown) {
    for (double k : m.k)
      if (k != 0.0) return nullptr;
    if (m.p1 != 0.0 || m.p2 != 0.0) return nullptr;
    return "distortion coefficients are all 0 and no chromatic aberration";
  }
  return nullptr;  // fisheye: even k = 0 is the equidistant projection, not a pinhole
}

RowWindow DistortionStage::InputRows(int y, int height) const {
  int band = y >> step_bits_;
  if (band < 0) band = 0;
  if (band > grid_h_ - 2) band = grid_h_ - 2;
  (void)height;
  return {band_first_[band], band_last_[band]};
}

size_t DistortionStage::TableBytes() const {
  return static_cast<size_t>(grid_w_) * grid_h_ * 2 * sizeof(int32_t) +
         static_cast<size_t>(taps_) * (size_t{1} << phase_bits_) * sizeof(int16_t);
}

int DistortionStage::MaxWindowRows() const { return max_window_; }

void DistortionStage::CountTables(WorkspaceCounter& counter) const {
  counter.Add<int32_t>(static_cast<size_t>(grid_w_) * grid_h_ * 2);
  counter.Add<int16_t>(static_cast<size_t>(taps_) << phase_bits_);
  counter.Add<int32_t>(static_cast<size_t>(kLaneTaps) << phase_bits_);  // wt_
  counter.Add<int32_t>(static_cast<size_t>(taps_) * TapStride());      // wtap_
}

size_t DistortionStage::ScratchBytes(int /*width*/) const { return static_cast<size_t>(grid_w_) * 2 * sizeof(int32_t); }

namespace {

bool SameLens(const LensModel& a, const LensModel& b) {
  for (int i = 0; i < 6; ++i)
    if (!SameBits(a.k[i], b.k[i])) return false;
  return a.model == b.model && SameBits(a.fx, b.fx) && SameBits(a.fy, b.fy) && SameBits(a.cx, b.cx) &&
         SameBits(a.cy, b.cy) && SameBits(a.p1, b.p1) && SameBits(a.p2, b.p2);
}

}  // namespace

// The mesh's values as Configure read them: a 64-bit FNV-1a of their bits, so
// that a mesh changed in place (the same pointer) between two configurations
// does not count as the same.
uint64_t DistortionStage::MeshDigest(const DisplacementMesh& mesh) {
  if (mesh.dxdy == nullptr) return 0;
  const size_t values = 2 * static_cast<size_t>(mesh.cols) * mesh.rows;
  uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a's offset basis and prime, a value's 32 bits at a time
  for (size_t i = 0; i < values; ++i) {
    uint32_t bits;
    std::memcpy(&bits, mesh.dxdy + i, sizeof bits);
    h = (h ^ bits) * 0x100000001b3ull;
  }
  return h;
}

bool DistortionStage::SameGrid(const DistortionStage& o) const {
  const DistortionConfig &a = config_, &b = o.config_;
  for (int i = 0; i < 3; ++i)
    if (!SameBits(a.chromatic_scale[i], b.chromatic_scale[i])) return false;
  const bool same_mesh = (a.mesh.dxdy == nullptr) == (b.mesh.dxdy == nullptr) && a.mesh.cols == b.mesh.cols &&
                         a.mesh.rows == b.mesh.rows && SameBits(a.mesh.step, b.mesh.step) &&
                         mesh_digest_ == o.mesh_digest_;
  return &o != this && o.configured_ && geometry_ == o.geometry_ && a.filter == b.filter &&
         a.phases == b.phases && a.grid_step == b.grid_step && SameLens(a.lens, b.lens) && same_mesh;
}

Status DistortionStage::Init(Arena& tables) { return Build(tables, nullptr); }

Status DistortionStage::InitFrom(Arena& tables, const Stage& previous, int* copied) {
  const DistortionStage& p = static_cast<const DistortionStage&>(previous);  // the same class (Stage::InitFrom)
  const DistortionStage* same = SameTables(p) ? &p : nullptr;
  *copied = same != nullptr ? 4 : 0;
  return Build(tables, same);
}

Status DistortionStage::Build(Arena& tables, const DistortionStage* same) {
  const size_t nodes = static_cast<size_t>(grid_w_) * grid_h_ * 2, weights = static_cast<size_t>(taps_) << phase_bits_,
               lane_weights = static_cast<size_t>(kLaneTaps) << phase_bits_,
               tap_weights = static_cast<size_t>(taps_) * TapStride();
  table_ = tables.Take<int32_t>(nodes);
  weights_ = tables.Take<int16_t>(weights);
  wt_ = tables.Take<int32_t>(lane_weights);
  wtap_ = tables.Take<int32_t>(tap_weights);
  if (table_ == nullptr || weights_ == nullptr || wt_ == nullptr || wtap_ == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for the distortion table");
  if (same != nullptr) {
    std::memcpy(table_, same->table_, nodes * sizeof(int32_t));
    std::memcpy(weights_, same->weights_, weights * sizeof(int16_t));
    std::memcpy(wt_, same->wt_, lane_weights * sizeof(int32_t));
    std::memcpy(wtap_, same->wtap_, tap_weights * sizeof(int32_t));
    fast_path_ = same->fast_path_;
    avx2_ = same->avx2_;
    avx512_ = same->avx512_;
    return Status::Ok();
  }
  for (int j = 0; j < grid_h_; ++j)
    for (int i = 0; i < grid_w_; ++i) {
      int32_t* node = table_ + (static_cast<size_t>(j) * grid_w_ + i) * 2;
      double sx = 0.0, sy = 0.0;
      if (!NodeSource(i, j, &sx, &sy)) {
        node[0] = node[1] = kNoSource;
        continue;
      }
      double dx = sx - (i << step_bits_), dy = sy - (j << step_bits_);
      // A displacement beyond the format is far off the image either way.
      dx = dx > kMaxDisplacement ? kMaxDisplacement : (dx < -kMaxDisplacement ? -kMaxDisplacement : dx);
      dy = dy > kMaxDisplacement ? kMaxDisplacement : (dy < -kMaxDisplacement ? -kMaxDisplacement : dy);
      node[0] = Q<15, 16, true>::FromDouble(dx).raw;
      node[1] = Q<15, 16, true>::FromDouble(dy).raw;
    }
  // Weights per phase: kernel at the taps' offsets, normalised in double,
  // rounded to Q1.14, the remainder to 2^14 put on the largest tap.
  const int phases = 1 << phase_bits_, before = taps_ / 2 - 1;
  for (int p = 0; p < phases; ++p) {
    double w[kLaneTaps] = {}, sum = 0.0;
    for (int t = 0; t < taps_; ++t) {
      w[t] = ResampleKernel(config_.filter, static_cast<double>(t - before) - static_cast<double>(p) / phases);
      sum += w[t];
    }
    int16_t* out = weights_ + p * taps_;
    int total = 0, largest = 0;
    for (int t = 0; t < taps_; ++t) {
      out[t] = static_cast<int16_t>(Q<1, kWeightFracBits, true>::FromDouble(w[t] / sum).raw);
      total += out[t];
      if (out[t] > out[largest]) largest = t;
    }
    out[largest] = static_cast<int16_t>(out[largest] + ((1 << kWeightFracBits) - total));
  }
  // The fast path's 32-bit positions (RowPositions) need |displacement| <=
  // 2^29 (plus x << 16 < 2^30 stays below 2^31) and neighbouring valid nodes
  // of a grid row closer than 2^24 (256 px; times the fraction < 2^6 stays
  // far below 2^31). Chromatic scaling (64-bit products) takes the general path.
  constexpr int64_t kMaxFastDisplacement = int64_t{1} << 29, kMaxFastDifference = int64_t{1} << 24;
  fast_path_ = !scaled_[0] && !scaled_[1] && !scaled_[2];
  // The bilinear fast path computes the weights: phase p's second weight is
  // p << (14 - phase_bits) (exact in double and Q1.14; checked here).
  if (config_.filter == ResampleFilter::kBilinear)
    for (int p = 0; p < phases; ++p)
      if (weights_[2 * p + 1] != (p << (kWeightFracBits - phase_bits_)) ||
          weights_[2 * p] != (1 << kWeightFracBits) - weights_[2 * p + 1])
        fast_path_ = false;
  for (int j = 0; j < grid_h_ && fast_path_; ++j)
    for (int i = 0; i < grid_w_; ++i) {
      const int32_t* node = table_ + (static_cast<size_t>(j) * grid_w_ + i) * 2;
      if (node[0] == kNoSource) continue;
      for (int k = 0; k < 2; ++k) {
        const int64_t v = node[k];
        if (v > kMaxFastDisplacement || v < -kMaxFastDisplacement) fast_path_ = false;
        if (i + 1 < grid_w_ && node[2] != kNoSource) {
          const int64_t d = int64_t{node[2 + k]} - v;
          if (d + 1 >= kMaxFastDifference || d - 1 <= -kMaxFastDifference) fast_path_ = false;
        }
      }
    }
  // The weights as int32, kLaneTaps per phase (LaneWeights) and tap-major
  // (LaneWeights16; phases past the last are 0), and the bound
  // FilterLanesAvx2's 32-bit row sums need: sum |w| < 2^15 for every phase.
  CAMSIM_DCHECK(taps_ <= kLaneTaps);
  bool small_weights = true;
  for (int i = 0; i < taps_ * TapStride(); ++i) wtap_[i] = 0;
  for (int p = 0; p < phases; ++p) {
    int sum = 0;
    for (int t = 0; t < kLaneTaps; ++t) {
      const int w = t < taps_ ? weights_[p * taps_ + t] : 0;
      wt_[p * kLaneTaps + t] = w;
      if (t < taps_) wtap_[t * TapStride() + p] = w;
      sum += w < 0 ? -w : w;
    }
    if (sum >= (1 << 15)) small_weights = false;
  }
  avx2_ = CpuHasAvx2() && small_weights;
  avx512_ = avx2_ && CpuHasAvx512();
  return Status::Ok();
}

// The displacements (Q.16) of `count` grid nodes interpolated a fraction
// fy / 2^s (s = step_bits <= 6) of the way from grid row n0 to grid row n1:
// (n0 (2^s - fy) + n1 fy + 2^(s-1)) >> s, rounded ties up; kNoSource where
// either node has none. Written so that the AVX2 clone vectorises it: branch-free, the
// widening int32 x int32 -> int64 products spelt out (vpmuldq), and the
// arithmetic shift (AVX2 has none for 64 bits) taken as a logical one of the
// sum plus 2^40: |sum| < 2^38 (|n| <= 2^31) and 2^40 is a multiple of 2^s,
// so that adds exactly 2^(40 - s) to the quotient, which is taken off again.
CAMSIM_CPU_CLONES
static void NodeRow(const int32_t* __restrict n0, const int32_t* __restrict n1, int count, int step_bits, int fy,
                    int32_t* __restrict dx, int32_t* __restrict dy) {
  const int32_t w0 = (1 << step_bits) - fy, w1 = fy;
  constexpr int64_t kBias = int64_t{1} << 40;
  const int64_t add = kBias + ((int64_t{1} << step_bits) >> 1), sub = kBias >> step_bits;
  const auto shift = [step_bits, add, sub](int64_t v) {
    return static_cast<int32_t>(static_cast<int64_t>(static_cast<uint64_t>(v + add) >> step_bits) - sub);
  };
  for (int i = 0; i < count; ++i) {
    const int32_t x0 = n0[2 * i], y0 = n0[2 * i + 1], x1 = n1[2 * i], y1 = n1[2 * i + 1];
    const int32_t none = -static_cast<int32_t>((x0 == kNoSource) | (x1 == kNoSource));  // all ones or 0
    const int32_t x = shift(int64_t{x0} * w0 + int64_t{x1} * w1);
    const int32_t y = shift(int64_t{y0} * w0 + int64_t{y1} * w1);
    dx[i] = (x & ~none) | (kNoSource & none);
    dy[i] = (y & ~none) | (kNoSource & none);
  }
}

void DistortionStage::InterpolateRow(int y, int32_t* dx, int32_t* dy) const {
  const int j = y >> step_bits_, fy = y & ((1 << step_bits_) - 1);
  const int32_t* n0 = table_ + static_cast<size_t>(j) * grid_w_ * 2;
  NodeRow(n0, n0 + static_cast<size_t>(grid_w_) * 2, grid_w_, step_bits_, fy, dx, dy);
}

bool DistortionStage::SourcePosition(int x, int y, int c, int64_t* sx, int64_t* sy) const {
  const int i = x >> step_bits_, j = y >> step_bits_;
  const int32_t* n0 = table_ + (static_cast<size_t>(j) * grid_w_ + i) * 2;
  int32_t dx[2], dy[2];  // nodes i and i + 1 of the row, as InterpolateRow
  NodeRow(n0, n0 + static_cast<size_t>(grid_w_) * 2, 2, step_bits_, y & ((1 << step_bits_) - 1), dx, dy);
  const int64_t ax = dx[0], ay = dy[0], bx = dx[1], by = dy[1];
  if (ax == kNoSource || bx == kNoSource) return false;
  const int64_t fx = x & ((1 << step_bits_) - 1), w0 = (1 << step_bits_) - fx, half = (int64_t{1} << step_bits_) >> 1;
  int64_t px = (int64_t{x} << 16) + ((ax * w0 + bx * fx + half) >> step_bits_);
  int64_t py = (int64_t{y} << 16) + ((ay * w0 + by * fx + half) >> step_bits_);
  if (scaled_[c]) {
    constexpr int64_t kRound = int64_t{1} << (kScaleFracBits - 1);
    px = centre_x_ + (((px - centre_x_) * scale_[c] + kRound) >> kScaleFracBits);
    py = centre_y_ + (((py - centre_y_) * scale_[c] + kRound) >> kScaleFracBits);
  }
  *sx = px;
  *sy = py;
  return true;
}

// Every ProcessRow variant starts here: the row's displacements per grid
// column interpolated into scratch, and RowArgs' fields copied to locals
// (a store through an output pointer may alias them; see Source).
struct DistortionStage::RowView {
  const int32_t* vdx;
  const int32_t* vdy;
  Source src;
  uint32_t* out[3];
  FastLimits lim;  // for taps_
};

DistortionStage::RowView DistortionStage::StartRow(const RowArgs& a) const {
  int32_t* vdx = reinterpret_cast<int32_t*>(a.scratch);
  int32_t* vdy = vdx + grid_w_;
  InterpolateRow(a.y, vdx, vdy);
  return RowView{vdx, vdy, Source{a.rows, a.first_row, a.row_count, a.width, geometry_.height, phase_bits_, weights_,
                                          config_.ringing_clamp},
                 // Site only: the one mosaic plane, whichever colour a pixel computes.
                 {a.out[0], site_only_ ? a.out[0] : a.out[1], site_only_ ? a.out[0] : a.out[2]},
                 MakeFastLimits(a, geometry_.height, taps_, phase_bits_)};
}

template <int N>
void DistortionStage::ProcessRowN(const RowArgs& a) const {
  const RowView row_view = StartRow(a);
  const int32_t* const vdx = row_view.vdx;
  const int32_t* const vdy = row_view.vdy;
  const Source& src = row_view.src;
  uint32_t* const* out = row_view.out;
  const int width = a.width, y = a.y;
  const Cfa cfa = geometry_.cfa;
  const bool site_only = site_only_;
  const int step_bits = step_bits_, smask = (1 << step_bits) - 1;
  const int64_t half = (int64_t{1} << step_bits) >> 1;
  constexpr int64_t kRound = int64_t{1} << (kScaleFracBits - 1);
  const bool any_scaled = scaled_[0] || scaled_[1] || scaled_[2];
  for (int x = 0; x < width; ++x) {
    const int i = x >> step_bits;
    int c0 = 0, c1 = 3;
    if (site_only) {
      c0 = CfaColour(cfa, x, y);
      c1 = c0 + 1;
    }
    if (vdx[i] == kNoSource || vdx[i + 1] == kNoSource) {
      for (int c = c0; c < c1; ++c) out[c][x] = 0;
      continue;
    }
    const int64_t fx = x & smask, w0 = (1 << step_bits) - fx;
    const int64_t sx = (int64_t{x} << 16) + ((vdx[i] * w0 + vdx[i + 1] * fx + half) >> step_bits);
    const int64_t sy = (int64_t{y} << 16) + ((vdy[i] * w0 + vdy[i + 1] * fx + half) >> step_bits);
    Taps<N> t;
    if (!any_scaled) {  // one position for every channel
      if (SetUpTaps<N>(src, sx, sy, &t)) {
        for (int c = c0; c < c1; ++c) out[c][x] = Filter<N>(src, c, t);
      } else {
        for (int c = c0; c < c1; ++c) out[c][x] = 0;
      }
      continue;
    }
    for (int c = c0; c < c1; ++c) {
      int64_t px = sx, py = sy;
      if (scaled_[c]) {
        px = centre_x_ + (((sx - centre_x_) * scale_[c] + kRound) >> kScaleFracBits);
        py = centre_y_ + (((sy - centre_y_) * scale_[c] + kRound) >> kScaleFracBits);
      }
      Taps<N> tc;
      out[c][x] = SetUpTaps<N>(src, px, py, &tc) ? Filter<N>(src, c, tc) : 0;
    }
  }
}

// Fast path (fast_path()), per chunk of kChunk pixels: the source positions
// (ChunkPositions), then per pixel the phase rounding in 32 bits and, where
// all taps lie inside the frame and the driver's window, FilterInterior; the
// rest (borders) goes through SetUpTaps and Filter as in the general path.
// The same bits as ProcessRowN.
template <int N, bool kSiteOnly>
void DistortionStage::ProcessRowFast(const RowArgs& a) const {
  const int width = a.width, y = a.y;
  const RowView row_view = StartRow(a);
  const Source& src = row_view.src;
  uint32_t* const* out = row_view.out;
  const RowIn* const rows = a.rows;
  const int16_t* const weights = weights_;
  const Cfa cfa = geometry_.cfa;
  const FastLimits& l = row_view.lim;
  const bool clamp = config_.ringing_clamp;
  CAMSIM_DCHECK(N == taps_);
  constexpr int kBefore = N / 2 - 1;
  int32_t sx[kChunk], sy[kChunk];
  for (int xs = 0; xs < width; xs += kChunk) {
    const int n = width - xs < kChunk ? width - xs : kChunk;
    ChunkPositions(row_view.vdx, row_view.vdy, xs, n, y, step_bits_, sx, sy);
    for (int f = 0; f < n; ++f) {
      const int x = xs + f;
      int c0 = 0, c1 = 3;
      if constexpr (kSiteOnly) {
        c0 = CfaColour(cfa, x, y);
        c1 = c0 + 1;
      }
      const int32_t px = sx[f], py = sy[f];
      if (!l.On(px, py)) {
        for (int c = c0; c < c1; ++c) out[c][x] = 0;
        continue;
      }
      const int32_t qx = (px + l.qround) >> l.shift, qy = (py + l.qround) >> l.shift;
      const int x0 = (qx >> l.phase_bits) - kBefore, y0 = (qy >> l.phase_bits) - kBefore;
      if (x0 >= 0 && x0 <= l.col_hi && y0 >= l.row_lo && y0 <= l.row_hi) {
        const RowIn* r = rows + (y0 - l.first_row);
        const int16_t* wx = weights + (qx & l.mask) * N;
        const int16_t* wy = weights + (qy & l.mask) * N;
        if constexpr (kSiteOnly) {
          out[c0][x] = FilterInterior<N>(r, c0, x0, wx, wy, clamp);
        } else {
          out[0][x] = FilterInterior<N>(r, 0, x0, wx, wy, clamp);
          out[1][x] = FilterInterior<N>(r, 1, x0, wx, wy, clamp);
          out[2][x] = FilterInterior<N>(r, 2, x0, wx, wy, clamp);
        }
        continue;
      }
      Taps<N> t;
      if (SetUpTaps<N>(src, px, py, &t)) {
        for (int c = c0; c < c1; ++c) out[c][x] = Filter<N>(src, c, t);
      } else {
        for (int c = c0; c < c1; ++c) out[c][x] = 0;
      }
    }
  }
}

// Bilinear fast path: per chunk of kChunk pixels, the positions
// (ChunkPositions), then per pixel its weights and 2x2 samples staged
// (fill: weights and samples 0, which gives 0), BilinearLanes, and the
// pixels whose taps need reflection or leave the window (frame borders)
// through SetUpTaps / Filter afterwards. The same bits as ProcessRowN<2>.
template <bool kSiteOnly>
void DistortionStage::ProcessRowBilinear(const RowArgs& a) const {
  const int width = a.width, y = a.y;
  const RowView row_view = StartRow(a);
  uint32_t* const* out = row_view.out;
  const RowIn* const rows = a.rows;
  const Cfa cfa = geometry_.cfa;
  const FastLimits& l = row_view.lim;
  CAMSIM_DCHECK(taps_ == 2);
  constexpr int kChannels = kSiteOnly ? 1 : 3;
  BilinearChunk k;
  BilinearSetUp u;
  uint8_t site[kChunk];  // site only: the colour computed
  for (int xs = 0; xs < width; xs += kChunk) {
    const int n = width - xs < kChunk ? width - xs : kChunk;
    ChunkPositionsFor(avx512_, row_view.vdx, row_view.vdy, xs, n, y, step_bits_, u.sx, u.sy);
    BilinearSetUpLanes(&u, l);
    if constexpr (kSiteOnly)
      for (int f = 0; f < kChunk; ++f) site[f] = static_cast<uint8_t>(CfaColour(cfa, xs + f, y));
#ifdef CAMSIM_X86_AVX2
    if (avx2_) {
      const int c_even = kSiteOnly ? site[0] : 0, c_odd = kSiteOnly ? site[1] : 0;
#ifdef CAMSIM_X86_AVX512
      if (avx512_) {
        BilinearChunkAvx512(rows, a.row_count, u, width, kSiteOnly, c_even, c_odd, &k);
      } else
#endif
      {
        BilinearChunkAvx2(rows, a.row_count, u, width, kSiteOnly, c_even, c_odd, &k);
      }
    } else
#endif
    {
      for (int f = 0; f < kChunk; ++f) {
        const int c0 = kSiteOnly ? site[f] : 0;
        k.wx[f] = u.wx[f];
        k.wy[f] = u.wy[f];
        if (u.inside[f]) {
          const RowIn* r = rows + u.row[f];
          const int x0 = u.x0[f];
          for (int c = 0; c < kChannels; ++c) {
            std::memcpy(k.s[c][0][f], r[0].ch[c0 + c] + x0, 2 * sizeof(uint32_t));
            std::memcpy(k.s[c][1][f], r[1].ch[c0 + c] + x0, 2 * sizeof(uint32_t));
          }
        } else {
          for (int c = 0; c < kChannels; ++c) k.s[c][0][f][0] = k.s[c][0][f][1] = k.s[c][1][f][0] = k.s[c][1][f][1] = 0;
        }
      }
      BilinearLanes(&k, kChannels);
    }
    if constexpr (kSiteOnly) {
      std::memcpy(out[0] + xs, k.v[0], static_cast<size_t>(n) * sizeof(uint32_t));
    } else if (n == kChunk) {  // a constant size: inlined vector moves, not a call or rep movs
      for (int c = 0; c < 3; ++c) std::memcpy(out[c] + xs, k.v[c], sizeof(k.v[c]));
    } else {
      for (int c = 0; c < 3; ++c) std::memcpy(out[c] + xs, k.v[c], static_cast<size_t>(n) * sizeof(uint32_t));
    }
    int32_t any_border = 0;  // most chunks have none; this OR vectorises
    for (int f = 0; f < kChunk; ++f) any_border |= u.border[f];
    for (int f = 0; any_border != 0 && f < n; ++f) {
      if (!u.border[f]) continue;
      Taps<2> t;
      const int c0 = kSiteOnly ? site[f] : 0, c1 = kSiteOnly ? c0 + 1 : 3;
      if (SetUpTaps<2>(row_view.src, u.sx[f], u.sy[f], &t))
        for (int c = c0; c < c1; ++c) out[c][xs + f] = Filter<2>(row_view.src, c, t);
    }
  }
}

#ifdef CAMSIM_X86_AVX2
// The N-tap fast path with AVX2: per chunk of kChunk pixels the positions
// and each pixel's class (fill, interior, border) as in ProcessRowFast, then
// the interior pixels in sets of lanes, and ProcessRowFast's per-pixel code
// for the rest. A set is sixteen lanes where the CPU has AVX-512
// (FilterSet16; a set that does not fit it goes as two sets of eight), else
// eight (FilterSet8). RGB: neighbouring pixels, L = 2 loads per row;
// CFA site only: the pixels of one colour among twice as many, L = 3. Lane
// slots: RGB slot = pixel; site only, each group of 2 x lanes pixels is
// stored even ones first, so a set's lanes are consecutive slots.
#ifdef CAMSIM_X86_AVX512
// ProcessRowLanes' site-only slots for sets of sixteen lanes: of each group
// of 32 pixels, the even ones, then the odd ones (two vpermt2d per 32).
CAMSIM_AVX512_TARGET void SlotsOf32(const int32_t (*by_pixel)[kChunk], int32_t (*by_slot)[kChunk]) {
  const __m512i even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
  const __m512i odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
  for (int v = 0; v < 5; ++v)
    for (int g = 0; g < kChunk; g += 32) {
      const __m512i lo = _mm512_loadu_si512(by_pixel[v] + g), hi = _mm512_loadu_si512(by_pixel[v] + g + 16);
      _mm512_storeu_si512(by_slot[v] + g, _mm512_permutex2var_epi32(lo, even, hi));
      _mm512_storeu_si512(by_slot[v] + g + 16, _mm512_permutex2var_epi32(lo, odd, hi));
    }
}
#endif

// A set's mask of lanes done as pixels of the chunk from its first: lane j
// is pixel step j (site only: every other bit, as a Morton spread).
template <bool kSiteOnly>
inline uint64_t LanePixels(uint32_t lanes) {
  uint64_t m = lanes & 0xFFFF;
  if constexpr (kSiteOnly) {
    m = (m | m << 8) & 0x00FF00FF;
    m = (m | m << 4) & 0x0F0F0F0F;
    m = (m | m << 2) & 0x33333333;
    m = (m | m << 1) & 0x55555555;
  }
  return m;
}

template <int N, bool kSiteOnly>
CAMSIM_AVX2_TARGET void DistortionStage::ProcessRowLanes(const RowArgs& a) const {
  constexpr int kBefore = N / 2 - 1;
  const int lanes = avx512_ ? 16 : 8;
  const int group = kSiteOnly ? 2 * lanes : lanes;  // a power of two, <= kChunk
  const int width = a.width, y = a.y;
  const RowView row_view = StartRow(a);
  uint32_t* const* out = row_view.out;
  const RowIn* const rows = a.rows;
  const Cfa cfa = geometry_.cfa;
  const FastLimits& l = row_view.lim;
  CAMSIM_DCHECK(N == taps_);
  int32_t sx[kChunk], sy[kChunk];                                          // by pixel
  int32_t by_pixel[5][kChunk];                                             // x0, row, phases, class
  int32_t by_slot[5][kChunk];                                              // the same by slot (site only)
  int32_t* const x0s = kSiteOnly ? by_slot[0] : by_pixel[0];
  int32_t* const rows_ = kSiteOnly ? by_slot[1] : by_pixel[1];
  int32_t* const phx = kSiteOnly ? by_slot[2] : by_pixel[2];
  int32_t* const phy = kSiteOnly ? by_slot[3] : by_pixel[3];
  int32_t* const cls = kSiteOnly ? by_slot[4] : by_pixel[4];
  auto slot_of = [group, lanes](int f) {
    return kSiteOnly ? ((f & ~(group - 1)) | ((f & 1) * lanes) | ((f & (group - 1)) >> 1)) : f;
  };
  for (int xs = 0; xs < width; xs += kChunk) {
    const int n = width - xs < kChunk ? width - xs : kChunk;
    ChunkPositionsFor(avx512_, row_view.vdx, row_view.vdy, xs, n, y, step_bits_, sx, sy);
    ClassifyChunk(n, l, kBefore, sx, sy, by_pixel);
    if constexpr (kSiteOnly) {  // slots: the even pixels of each group, then the odd ones
#ifdef CAMSIM_X86_AVX512
      if (lanes == 16) {
        SlotsOf32(by_pixel, by_slot);
      } else
#endif
      {
        for (int v = 0; v < 5; ++v)
          for (int g = 0; g < kChunk; g += group)
            for (int i = 0; i < lanes; ++i) {
              by_slot[v][g + i] = by_pixel[v][g + 2 * i];
              by_slot[v][g + lanes + i] = by_pixel[v][g + 2 * i + 1];
            }
      }
      if (n == kChunk) {  // vector stores: GCC makes a 256-byte memset a rep stos
        for (int i = 0; i < kChunk; i += 8)
          _mm256_storeu_si256(reinterpret_cast<__m256i*>(out[0] + xs + i), _mm256_setzero_si256());
      } else {
        std::memset(out[0] + xs, 0, static_cast<size_t>(n) * sizeof(uint32_t));
      }
    }
    uint64_t done = 0;  // by pixel of the chunk
    const int step = kSiteOnly ? 2 : 1;  // between the pixels of a set's lanes
    for (int g = 0; g + group <= n; g += group)
      for (int set = 0; set < group; set += lanes) {
        const int k = g + set;                                 // the set's first slot
        const int f = g + (kSiteOnly ? set / lanes : 0);       // and pixel
        const int plane = kSiteOnly ? CfaColour(cfa, xs + f, y) : 0;
#ifdef CAMSIM_X86_AVX512
        if (lanes == 16) {
          const LaneSet lane_set{x0s + k, rows_ + k, phx + k, phy + k, cls + k, config_.ringing_clamp};
          const uint32_t lanes_done =
              FilterSet16<N, kSiteOnly>(rows, a.row_count, width, wtap_, TapStride(), lane_set, plane, out,
                                        xs + f);
          done |= LanePixels<kSiteOnly>(lanes_done) << f;
          if (lanes_done != 0) continue;
        }
#endif
        for (int j0 = 0; j0 < lanes; j0 += 8) {  // sets of eight lanes
          const LaneSet lane_set{x0s + k + j0, rows_ + k + j0, phx + k + j0, phy + k + j0, cls + k + j0,
                                 config_.ringing_clamp};
          const int f8 = f + step * j0;  // the first pixel of these eight
          const uint32_t lanes_done =
              FilterSet8<N, kSiteOnly>(rows, a.row_count, width, wt_, lane_set, plane, out, xs + f8);
          done |= LanePixels<kSiteOnly>(lanes_done) << f8;
        }
      }
    // The rest, pixel by pixel as ProcessRowFast.
    static_assert(kChunk == 64, "one bit per pixel");
    for (uint64_t todo = ~done & (~uint64_t{0} >> (kChunk - n)); todo != 0; todo &= todo - 1) {
      const int f = __builtin_ctzll(todo);
      const int k = slot_of(f), x = xs + f;
      const int c0 = kSiteOnly ? CfaColour(cfa, x, y) : 0, c1 = kSiteOnly ? c0 + 1 : 3;
      if (cls[k] == kPixelInterior) {
        const RowIn* r = rows + rows_[k];
        const int16_t* wx = weights_ + phx[k] * N;
        const int16_t* wy = weights_ + phy[k] * N;
        for (int c = c0; c < c1; ++c) out[c][x] = FilterInterior<N>(r, c, x0s[k], wx, wy, config_.ringing_clamp);
        continue;
      }
      Taps<N> t;
      if (l.On(sx[f], sy[f]) && SetUpTaps<N>(row_view.src, sx[f], sy[f], &t)) {
        for (int c = c0; c < c1; ++c) out[c][x] = Filter<N>(row_view.src, c, t);
      } else {
        for (int c = c0; c < c1; ++c) out[c][x] = 0;
      }
    }
  }
}
#endif

void DistortionStage::ProcessRow(const RowArgs& a) const {
  if (fast_path()) {
    switch (taps_ * 2 + (site_only_ ? 1 : 0)) {
      case 4: ProcessRowBilinear<false>(a); return;
      case 5: ProcessRowBilinear<true>(a); return;
#ifdef CAMSIM_X86_AVX2
      case 8: avx2_ ? ProcessRowLanes<4, false>(a) : ProcessRowFast<4, false>(a); return;
      case 9: avx2_ ? ProcessRowLanes<4, true>(a) : ProcessRowFast<4, true>(a); return;
      case 12: avx2_ ? ProcessRowLanes<6, false>(a) : ProcessRowFast<6, false>(a); return;
      case 13: avx2_ ? ProcessRowLanes<6, true>(a) : ProcessRowFast<6, true>(a); return;
      case 16: avx2_ ? ProcessRowLanes<8, false>(a) : ProcessRowFast<8, false>(a); return;
      default: avx2_ ? ProcessRowLanes<8, true>(a) : ProcessRowFast<8, true>(a); return;
#else
      case 8: ProcessRowFast<4, false>(a); return;
      case 9: ProcessRowFast<4, true>(a); return;
      case 12: ProcessRowFast<6, false>(a); return;
      case 13: ProcessRowFast<6, true>(a); return;
      case 16: ProcessRowFast<8, false>(a); return;
      default: ProcessRowFast<8, true>(a); return;
#endif
    }
  }
  switch (taps_) {
    case 2: ProcessRowN<2>(a); break;
    case 4: ProcessRowN<4>(a); break;
    case 6: ProcessRowN<6>(a); break;
    default: ProcessRowN<8>(a); break;
  }
}

}  // namespace camsim
