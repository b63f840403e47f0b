#include "core/sensor/blooming.h"

#include <cstring>

#include "core/base/simd.h"

namespace camsim {
namespace {

// Columns per spill group: sixteen 64-bit lanes (two AVX-512 vectors, so
// that two independent carry chains overlap; four AVX2 ones).
constexpr int kLanes = 16;

// last[x] = row where in[x] reaches its column parity's threshold (t0
// even, t1 odd), else unchanged. A function of its own with __restrict
// pointers and the width a parameter, so that the loop goes in lanes;
// compiled per CPU tier (the same values).
CAMSIM_CPU_CLONES
void MarkOverWell(const uint32_t* __restrict in, int32_t* __restrict last, int width, uint32_t t0, uint32_t t1,
                  int32_t row) {
  for (int x = 0; x < width; ++x) last[x] = in[x] >= ((x & 1) ? t1 : t0) ? row : last[x];
}

// One window row of a pass, in lanes: each pixel takes what fits of the
// carry, then passes on its excess's share, half (rounded down) going down,
// the rest going up.
inline void PassRow(uint64_t* __restrict level, const uint64_t* __restrict excess, uint64_t* __restrict carry,
                    uint64_t w, bool up) {
#pragma GCC unroll 1  // unrolled whole, the lanes are no longer vectorised
  for (int j = 0; j < kLanes; ++j) {
    const uint64_t room = w - level[j];
    const uint64_t take = room < carry[j] ? room : carry[j];
    level[j] += take;
    const uint64_t half = excess[j] >> 1;
    carry[j] = carry[j] - take + (up ? excess[j] - half : half);
  }
}

// One group of kLanes columns: the two passes of the model (blooming.h) on
// window rows window[0 .. n), each read at [x, x + kLanes), all lanes at
// once. qe[k & 1][j] is the QE (Q1.16) of lane j in window row k. Writes
// the centre row's (k = self) charge before and after, Q.8 electrons.
// level and excess hold n * kLanes entries each. Plain loops over the
// lanes, compiled per CPU tier: every copy gives the same integers.
CAMSIM_CPU_CLONES
void SpillGroup(const uint32_t* const* window, int x, int n, int self, const uint32_t (*qe)[kLanes], uint64_t w,
                uint64_t* __restrict level, uint64_t* __restrict excess, uint64_t* __restrict before,
                uint64_t* __restrict after) {
  for (int k = 0; k < n; ++k) {
    const uint32_t* in = window[k] + x;
    const uint32_t* q = qe[k & 1];
    uint64_t* lk = level + k * kLanes;
    uint64_t* ek = excess + k * kLanes;
    for (int j = 0; j < kLanes; ++j) {
      const uint64_t m = RoundShiftU(static_cast<uint64_t>(in[j]) * q[j], 16);
      lk[j] = m < w ? m : w;
      ek[j] = m - lk[j];
    }
  }
  for (int j = 0; j < kLanes; ++j) before[j] = level[self * kLanes + j] + excess[self * kLanes + j];
  uint64_t carry[kLanes] = {};
  for (int k = 0; k < n; ++k) PassRow(level + k * kLanes, excess + k * kLanes, carry, w, false);
  for (int j = 0; j < kLanes; ++j) carry[j] = 0;
  // Up; rows above `self` cannot change it.
  for (int k = n - 1; k >= self; --k) PassRow(level + k * kLanes, excess + k * kLanes, carry, w, true);
  for (int j = 0; j < kLanes; ++j) after[j] = level[self * kLanes + j];
}

// Charge (Q.8 electrons) back to photons (Q24.8) at QE q > 0 (Q1.16): rounded, ties up, saturated.
uint32_t ToPhotons(uint64_t charge, uint32_t q) { return SatU32(((charge << 16) + q / 2) / q); }

}  // namespace

Status BloomingStage::Configure(const BloomingConfig& c, const SensorConfig& sensor, const SensorGeometry& g) {
  if (c.rows < 1 || c.rows > kMaxBloomingRows) return InvalidArgument("blooming.rows", "must be in [1, 64]");
  config_ = c;
  geometry_ = g;
  // The sensor validates QE and the full well; here they only need to be in range for the formats.
  for (int i = 0; i < 3; ++i) {
    const double qe = sensor.quantum_efficiency[i];
    qe_q16_[i] = qe >= 0.0 && qe <= 1.0 ? Q<1, 16>::FromDouble(qe).raw : 0;
  }
  const double w = sensor.full_well_e >= 1.0 && sensor.full_well_e <= 1e6 ? sensor.full_well_e : 1e6;
  full_well_q8_ = Q<24, 8>::FromDouble(w).raw;
  // m = RoundShiftU(p * qe, 16) > W  <=>  p * qe >= (W + 1) * 2^16 - 2^15  <=>  p >= over (qe > 0).
  for (int i = 0; i < 3; ++i) {
    const uint64_t need = ((full_well_q8_ + 1) << 16) - (uint64_t{1} << 15);
    const uint64_t over = qe_q16_[i] == 0 ? ~uint64_t{0} : (need + qe_q16_[i] - 1) / qe_q16_[i];
    over_[i] = over > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<uint32_t>(over);
  }
  return Status::Ok();
}

Result<LineFormat> BloomingStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kPhotons) return InvalidArgument("blooming", "needs photons input (before the sensor)");
  return in;
}

// SpillGroup's level and excess, and the columns of a partial last group.
size_t BloomingStage::ScratchBytes(int /*width*/) const {
  const size_t rows = 2 * static_cast<size_t>(config_.rows) + 1;
  return 2 * AlignUp(sizeof(uint64_t) * rows * kLanes) + AlignUp(sizeof(uint32_t) * rows * kLanes);
}

size_t BloomingStage::StateBytes(int width) const {
  return sizeof(int32_t) * (1 + static_cast<size_t>(kMaxChannels) * static_cast<size_t>(width));
}

void BloomingStage::BeginStrip(uint8_t* state) const { reinterpret_cast<int32_t*>(state)[0] = -1; }

const char* BloomingStage::IdentityReason() const {
  return config_.enabled ? nullptr : "blooming off (blooming.enabled = false)";
}

void BloomingStage::ProcessRow(const RowArgs& a) const {
  const int R = config_.rows;
  const int channels = a.out[1] != nullptr ? 3 : 1;
  const int first = a.y - R < 0 ? 0 : a.y - R;  // window rows inside the frame
  const int last = a.y + R >= geometry_.height ? geometry_.height - 1 : a.y + R;
  const int n = last - first + 1;
  const int self = a.y - first;
  // Scratch (ScratchBytes): SpillGroup's level and excess, then a partial group's columns.
  const size_t group_rows = 2 * static_cast<size_t>(R) + 1;
  const size_t lanes_u64 = AlignUp(sizeof(uint64_t) * group_rows * kLanes) / sizeof(uint64_t);
  uint64_t* const level = reinterpret_cast<uint64_t*>(a.scratch);
  uint64_t* const excess = level + lanes_u64;
  uint32_t* const partial = reinterpret_cast<uint32_t*>(excess + lanes_u64);
  // Strip state (BeginStrip): the row the strip's next call is for, then per
  // channel and column the last row scanned that is over the well. A call
  // that follows the strip's previous one scans only the row entering its
  // window; any other scans the whole window.
  int32_t* const state = reinterpret_cast<int32_t*>(a.state);
  const bool follows = state[0] == a.y;
  state[0] = a.y + 1;
  const int width = a.width;
  for (int c = 0; c < channels; ++c) {
    const uint32_t* const center = a.rows[R].ch[c];
    uint32_t* out = a.out[c];
    int32_t* const last_over = state + 1 + static_cast<size_t>(c) * width;
    const int scan_from = follows ? a.y + R : first;  // (past `last` once the window reaches the frame's end)
    if (!follows)
      for (int x = 0; x < width; ++x) last_over[x] = -1;
    for (int row = scan_from; row <= last; ++row) {
      // Thresholds of even and odd columns of this row.
      const uint32_t t0 = over_[channels == 3 ? c : CfaColour(geometry_.cfa, 0, row)];
      const uint32_t t1 = over_[channels == 3 ? c : CfaColour(geometry_.cfa, 1, row)];
      MarkOverWell(a.rows[row - a.y + R].ch[c], last_over, width, t0, t1, row);
    }
    const uint32_t* window[2 * kMaxBloomingRows + 1];
    for (int k = 0; k < n; ++k) window[k] = a.rows[first + k - a.y + R].ch[c];
    // QE of each lane in window rows of each parity (groups start on even columns).
    uint32_t qe[2][kLanes];
    for (int p = 0; p < 2; ++p)
      for (int j = 0; j < kLanes; ++j)
        qe[p][j] = qe_q16_[channels == 3 ? c : CfaColour(geometry_.cfa, j & 1, first + p)];
    // The group of columns [x0, x0 + m), m <= kLanes; called with m = kLanes
    // for whole groups, so that its loops and copy have a constant length.
    const auto group = [&](int x0, int m) {
      bool over = false;  // a pixel of some column's window is over the well
      for (int j = 0; j < m; ++j) over |= last_over[x0 + j] >= first;
      if (!over) {  // nothing spills: the input, exactly
        std::memcpy(out + x0, center + x0, sizeof(uint32_t) * static_cast<size_t>(m));
        return;
      }
      int x = x0;
      if (m < kLanes) {  // the last group, partial: its columns, zero padded (lanes are independent)
        for (int k = 0; k < n; ++k) {
          uint32_t* row = partial + static_cast<size_t>(k) * kLanes;
          for (int j = 0; j < kLanes; ++j) row[j] = j < m ? window[k][x0 + j] : 0;
          window[k] = row;
        }
        x = 0;
      }
      uint64_t before[kLanes], after[kLanes];
      SpillGroup(window, x, n, self, qe, full_well_q8_, level, excess, before, after);
      for (int j = 0; j < m; ++j) {
        // Back to photons of this pixel's colour (unchanged charge, or QE 0: the input, exactly).
        const uint32_t q = qe[self & 1][j];
        if (q == 0 || after[j] == before[j]) {
          out[x0 + j] = center[x0 + j];
        } else {
          out[x0 + j] = after[j] == full_well_q8_ ? kFullWellPhotons : ToPhotons(after[j], q);
        }
      }
    };
    const int whole = width - width % kLanes;
    for (int x0 = 0; x0 < whole; x0 += kLanes) group(x0, kLanes);
    if (whole < width) group(whole, width - whole);
  }
}

}  // namespace camsim
