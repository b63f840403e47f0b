#include "core/sensor/blooming.h"

#include <cstring>

#include "core/base/simd.h"

namespace camsim {
namespace {

// last[x] = row where in[x] reaches its column parity's threshold (t0
// even, t1 odd), else unchanged. A function of its own with __restrict
// pointers and the width a parameter, so that the loop goes in lanes;
// compiled per CPU tier (the same values).
CAMSIM_CPU_CLONES
void MarkOverWell(const uint32_t* __restrict in, int32_t* __restrict last, int width, uint32_t t0, uint32_t t1,
                  int32_t row) {
  for (int x = 0; x < width; ++x) last[x] = in[x] >= ((x & 1) ? t1 : t0) ? row : last[x];
}

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
  const uint64_t w = full_well_q8_;
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
    for (int x = 0; x < width; ++x) {
      if (last_over[x] < first) {  // no pixel of the window over the well
        out[x] = center[x];
        continue;
      }
      // Charge of the window's pixels (Q.8 electrons) and whether any exceeds the well.
      uint64_t level[2 * kMaxBloomingRows + 1];
      uint64_t excess[2 * kMaxBloomingRows + 1];
      uint32_t qe_self = 0;
      uint64_t m_self = 0;
      bool spill = false;
      for (int k = 0; k < n; ++k) {
        const int row = first + k;
        const Colour colour = channels == 3 ? static_cast<Colour>(c) : CfaColour(geometry_.cfa, x, row);
        const uint32_t qe = qe_q16_[colour];
        const uint64_t m = RoundShiftU(static_cast<uint64_t>(a.rows[row - a.y + R].ch[c][x]) * qe, 16);
        if (k == self) {
          qe_self = qe;
          m_self = m;
        }
        level[k] = m < w ? m : w;
        excess[k] = m - level[k];
        spill |= excess[k] != 0;
      }
      if (!spill || qe_self == 0) {
        out[x] = center[x];
        continue;
      }
      uint64_t carry = 0;
      for (int k = 0; k < n; ++k) {
        const uint64_t room = w - level[k];
        const uint64_t take = room < carry ? room : carry;
        level[k] += take;
        carry = carry - take + (excess[k] >> 1);
      }
      carry = 0;
      for (int k = n - 1; k >= self; --k) {  // rows above `self` cannot change it in the up pass
        const uint64_t room = w - level[k];
        const uint64_t take = room < carry ? room : carry;
        level[k] += take;
        carry = carry - take + (excess[k] - (excess[k] >> 1));
      }
      // Back to photons of this pixel's colour (unchanged charge: the input, exactly).
      if (level[self] == m_self) {
        out[x] = center[x];
        continue;
      }
      out[x] = SatU32(((level[self] << 16) + qe_self / 2) / qe_self);
    }
  }
}

}  // namespace camsim
