#include "core/sensor/smear.h"

#include "core/aperture/exposure.h"

namespace camsim {
namespace {

// round(v * s.mant / 2^s.shift), ties up, saturated to 32 bits: the 96-bit
// product in two 64-bit words.
uint32_t MulScale(uint64_t v, const UScale& s) {
  if (s.mant == 0 || v == 0) return 0;
  const uint64_t p_lo = (v & 0xFFFFFFFFu) * s.mant;
  const uint64_t p_hi = (v >> 32) * s.mant;
  uint64_t lo = p_lo + (p_hi << 32);
  uint64_t hi = (p_hi >> 32) + (lo < p_lo ? 1 : 0);
  const int shift = s.shift;
  if (shift > 0) {  // + 2^(shift - 1)
    if (shift - 1 < 64) {
      const uint64_t r = uint64_t{1} << (shift - 1);
      lo += r;
      hi += lo < r ? 1 : 0;
    } else {
      hi += uint64_t{1} << (shift - 1 - 64);
    }
  }
  uint64_t q;
  if (shift >= 64) {
    q = hi >> (shift - 64);
  } else {
    if (shift > 0 ? (hi >> shift) != 0 : hi != 0) return 0xFFFFFFFFu;
    q = shift > 0 ? (lo >> shift) | (hi << (64 - shift)) : lo;
  }
  return SatU32(q);
}

bool HasCfaStage(const PipelineConfig& c) {
  for (int i = 0; i < c.order_count; ++i)
    if (c.order[i] == StageId::kCfa) return true;
  return false;
}

}  // namespace

bool SmearEnabled(const PipelineConfig& c) { return c.sensor.smear_row_transfer_us > 0; }

int SmearEntries(const PipelineConfig& c) { return kMaxChannels * c.geometry.width; }

void ComputeSmear(const PipelineConfig& config, const FrameInput& in, Span<uint32_t> out) {
  const SensorGeometry& g = config.geometry;
  const SensorConfig& s = config.sensor;
  CAMSIM_DCHECK(out.size >= static_cast<size_t>(SmearEntries(config)));
  for (size_t i = 0; i < out.size; ++i) out[i] = 0;
  if (!SmearEnabled(config)) return;
  // Radiance Q16.16 -> electrons Q24.8 for leak * t_row / t_exp of the light:
  // a factor per (colour, weight); IEEE * and / only (the same everywhere).
  const double base = s.smear_leak * (s.smear_row_transfer_us / config.exposure.exposure_time_us) *
                      ExposurePhotonsPerRadiance(config.exposure) / 256.0;  // 2^-16 radiance * 2^8 charge
  const auto factor = [&](double qe_weight) {
    Result<UScale> r = UScale::FromDouble(base * qe_weight, "sensor.smear_row_transfer_us");
    return r.ok() ? r.value() : UScale{};  // Configure bounds the factor; zero otherwise
  };
  const bool cfa = HasCfaStage(config);
  const double* w = config.cfa.mono_weights;
  const double wsum = w[0] + w[1] + w[2];
  UScale f3[3], fmono[3];
  for (int c = 0; c < 3; ++c) {
    f3[c] = factor(s.quantum_efficiency[c]);
    fmono[c] = factor(s.quantum_efficiency[kGreen] * w[c] / wsum);
  }
  for (int x = 0; x < g.width; ++x) {
    uint64_t sum[2][3] = {};  // [row parity][colour]
    for (int y = 0; y < g.height; ++y)
      for (int c = 0; c < 3; ++c) sum[y & 1][c] += in.radiance[c].row(y)[x];
    if (!cfa) {
      for (int c = 0; c < 3; ++c) out[static_cast<size_t>(c) * g.width + x] = MulScale(sum[0][c] + sum[1][c], f3[c]);
    } else if (g.cfa == Cfa::kMono) {
      uint64_t e = 0;
      for (int c = 0; c < 3; ++c) e += MulScale(sum[0][c] + sum[1][c], fmono[c]);
      out[x] = SatU32(e);
    } else {
      const Colour c0 = CfaColour(g.cfa, x, 0), c1 = CfaColour(g.cfa, x, 1);
      out[x] = SatU32(uint64_t{MulScale(sum[0][c0], f3[c0])} + MulScale(sum[1][c1], f3[c1]));
    }
  }
}

}  // namespace camsim
