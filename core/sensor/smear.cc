#include "core/sensor/smear.h"

#include <cstdint>
#include <cstring>

#include "core/aperture/exposure.h"
#include "core/base/wide.h"

namespace camsim {
namespace {

// The column sums live in the caller's uint32 entries: they are read and
// written only through this type, which may alias them (GCC and Clang).
using AliasedU64 = uint64_t __attribute__((may_alias));

// sum[x] += row[x], and the same of the vignetted radiance
// RoundShift(row[x] * gain[x], 14), for x < n.
void AddRow(AliasedU64* __restrict sum, const uint32_t* __restrict row, int n) {
  for (int x = 0; x < n; ++x) sum[x] += row[x];
}
void AddVignettedRow(AliasedU64* __restrict sum, const uint32_t* __restrict row, const uint32_t* __restrict gain,
                     int n) {
  for (int x = 0; x < n; ++x) sum[x] += (row[x] * uint64_t{gain[x]} + (1u << 13)) >> 14;
}

bool HasStage(const PipelineConfig& c, StageId id) {
  for (int i = 0; i < c.order_count; ++i)
    if (c.order[i] == id) return true;
  return false;
}

}  // namespace

bool SmearEnabled(const PipelineConfig& c) { return c.sensor.smear_row_transfer_us > 0; }

// The output, then each column's squared distance from the centre (the
// vignetting curve's dx2), then the column sums ([row parity][colour][x],
// uint64: 12 entries a column) and one entry that lets them start 8-byte
// aligned.
constexpr int kSumEntriesPerColumn = 2 * 3 * 2;
int SmearEntries(const PipelineConfig& c) { return (kMaxChannels + 1 + kSumEntriesPerColumn) * c.geometry.width + 1; }

void ComputeSmear(const PipelineConfig& config, const FrameInput& in, Span<uint32_t> out) {
  const SensorGeometry& g = config.geometry;
  const SensorConfig& s = config.sensor;
  CAMSIM_DCHECK(out.size >= static_cast<size_t>(SmearEntries(config)));
  const size_t width = static_cast<size_t>(g.width);
  for (size_t i = 0; i < kMaxChannels * width; ++i) out[i] = 0;
  if (!SmearEnabled(config)) return;
  // Radiance Q16.16 -> electrons Q24.8 for leak * t_row / t_exp of the light:
  // a factor per (colour, weight); IEEE * and / only (the same everywhere).
  const double base = s.smear_leak * (s.smear_row_transfer_us / config.exposure.exposure_time_us) *
                      ExposurePhotonsPerRadiance(config.exposure) / 256.0;  // 2^-16 radiance * 2^8 charge
  const auto factor = [&](double qe_weight) {
    Result<UScale> r = UScale::FromDouble(base * qe_weight, "sensor.smear_row_transfer_us");
    return r.ok() ? r.value() : UScale{};  // Configure bounds the factor; zero otherwise
  };
  const bool cfa = HasStage(config, StageId::kCfa);
  const double* w = config.cfa.mono_weights;
  const double wsum = w[0] + w[1] + w[2];
  UScale f3[3], fmono[3];
  for (int c = 0; c < 3; ++c) {
    f3[c] = factor(s.quantum_efficiency[c]);
    fmono[c] = factor(s.quantum_efficiency[kGreen] * w[c] / wsum);
  }
  // Vignetting (a stage before the sensor) scales the light each pixel gets:
  // the same Q2.14 gain the stage applies (curve or mask), times the Q16.16
  // radiance, rounded (ties up) back to Q16.16 before the column sum.
  const VignettingMode vmode = HasStage(config, StageId::kVignetting) ? config.vignetting.mode : VignettingMode::kOff;
  uint16_t curve[VignettingStage::kCurvePoints + 1];
  UScale rho_to_index;
  if (vmode == VignettingMode::kCos4 || vmode == VignettingMode::kTable)
    if (!BuildVignettingCurve(config.vignetting, g, curve, &rho_to_index).ok()) return;  // Configure checked it
  // The sums, row by row over the frame (contiguous loads); integer sums,
  // so the order changes nothing.
  uint32_t* const dx2 = out.data + kMaxChannels * width;  // (2x - (W - 1))^2, once per frame
  for (int x = 0; x < g.width; ++x) {
    const int64_t dx = 2 * static_cast<int64_t>(x) - (g.width - 1);
    dx2[x] = static_cast<uint32_t>(dx * dx);
  }
  uint32_t* const scratch = dx2 + width;
  const size_t skip = reinterpret_cast<uintptr_t>(scratch) % alignof(uint64_t) != 0 ? 1 : 0;
  AliasedU64* const sums = reinterpret_cast<AliasedU64*>(scratch + skip);
  std::memset(sums, 0, sizeof(uint64_t) * 2 * 3 * width);
  constexpr int kColumns = 64;  // gains computed per run of columns, shared by the colours
  for (int y = 0; y < g.height; ++y) {
    AliasedU64* const part = sums + static_cast<size_t>(y & 1) * 3 * width;
    if (vmode == VignettingMode::kOff) {
      for (int c = 0; c < 3; ++c) AddRow(part + c * width, in.radiance[c].row(y), g.width);
      continue;
    }
    for (int x0 = 0; x0 < g.width; x0 += kColumns) {
      const int n = g.width - x0 < kColumns ? g.width - x0 : kColumns;
      uint32_t gain[kColumns];
      if (vmode == VignettingMode::kMask) {
        for (int i = 0; i < n; ++i) gain[i] = in.vignetting_mask.row(y)[x0 + i];
      } else {
        const int64_t dy = 2 * static_cast<int64_t>(y) - (g.height - 1);
        VignettingCurveGains(curve, rho_to_index, dx2 + x0, static_cast<uint32_t>(dy * dy), n, gain);
      }
      for (int c = 0; c < 3; ++c) AddVignettedRow(part + c * width + x0, in.radiance[c].row(y) + x0, gain, n);
    }
  }
  const auto sum = [&](int parity, int c, int x) { return sums[(static_cast<size_t>(parity) * 3 + c) * width + x]; };
  for (int x = 0; x < g.width; ++x) {
    if (!cfa) {
      for (int c = 0; c < 3; ++c) out[static_cast<size_t>(c) * width + x] = MulScaleU64(sum(0, c, x) + sum(1, c, x), f3[c]);
    } else if (g.cfa == Cfa::kMono) {
      uint64_t e = 0;
      for (int c = 0; c < 3; ++c) e += MulScaleU64(sum(0, c, x) + sum(1, c, x), fmono[c]);
      out[x] = SatU32(e);
    } else {
      const Colour c0 = CfaColour(g.cfa, x, 0), c1 = CfaColour(g.cfa, x, 1);
      out[x] = SatU32(uint64_t{MulScaleU64(sum(0, c0, x), f3[c0])} + MulScaleU64(sum(1, c1, x), f3[c1]));
    }
  }
}

}  // namespace camsim
