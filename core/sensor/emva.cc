#include "core/sensor/emva.h"

#include "core/base/detmath.h"

namespace camsim {
namespace {

constexpr double kMaxFullWell = 1e6;  // keeps v * K inside int64 (see header)

double DarkElectrons(const SensorConfig& c, double exposure_time_us) {
  const double doublings = (c.temperature_c - c.dark_current_ref_c) / c.dark_current_doubling_c;
  return c.dark_current_e_per_s * (exposure_time_us * 1e-6) * detmath::Exp2(doublings);
}

double SystemGain(const SensorConfig& c) {
  return c.system_gain_dn_per_e * detmath::Pow(10.0, c.gain_db / 20.0);
}

bool InRange(double v, double lo, double hi) { return v >= lo && v <= hi; }  // false for NaN

}  // namespace

double ReferenceSensorMeanDn(const SensorConfig& c, const SensorGeometry& g, double exposure_time_us,
                             Colour colour, double photons) {
  const int qe_index = g.cfa == Cfa::kMono ? kGreen : colour;
  double e = photons * c.quantum_efficiency[qe_index] + DarkElectrons(c, exposure_time_us);
  if (e > c.full_well_e) e = c.full_well_e;
  const double dn = SystemGain(c) * e + c.black_level_dn;
  const double max_dn = (1 << g.adc_bits) - 1;
  return dn < 0 ? 0 : (dn > max_dn ? max_dn : dn);
}

Status SensorStage::Configure(const SensorConfig& c, const SensorGeometry& g, double exposure_time_us,
                              uint64_t seed) {
  for (double qe : c.quantum_efficiency)
    if (!InRange(qe, 0.0, 1.0)) return InvalidArgument("sensor.quantum_efficiency", "must be in [0, 1]");
  if (!InRange(c.full_well_e, 1.0, kMaxFullWell))
    return InvalidArgument("sensor.full_well_e", "must be in [1, 1e6] electrons");
  if (!InRange(c.system_gain_dn_per_e, 1e-3, 1e3))
    return InvalidArgument("sensor.system_gain_dn_per_e", "must be in [0.001, 1000] DN/e-");
  if (!InRange(c.gain_db, 0.0, 48.0)) return InvalidArgument("sensor.gain_db", "must be in [0, 48] dB");
  if (!InRange(c.dark_noise_e, 0.0, 1000.0))
    return InvalidArgument("sensor.dark_noise_e", "must be in [0, 1000] electrons");
  if (!InRange(c.dark_current_e_per_s, 0.0, 1e6))
    return InvalidArgument("sensor.dark_current_e_per_s", "must be in [0, 1e6] e-/s");
  if (!InRange(c.temperature_c, -100.0, 150.0))
    return InvalidArgument("sensor.temperature_c", "must be in [-100, 150] degrees C");
  if (!InRange(c.dark_current_ref_c, -100.0, 150.0))
    return InvalidArgument("sensor.dark_current_ref_c", "must be in [-100, 150] degrees C");
  if (!InRange(c.dark_current_doubling_c, 1.0, 100.0))
    return InvalidArgument("sensor.dark_current_doubling_c", "must be in [1, 100] kelvin");
  if (!InRange(c.dsnu_e, 0.0, 1000.0)) return InvalidArgument("sensor.dsnu_e", "must be in [0, 1000] electrons");
  if (!InRange(c.prnu_percent, 0.0, 50.0)) return InvalidArgument("sensor.prnu_percent", "must be in [0, 50] %");
  if (g.adc_bits < 8 || g.adc_bits > 16) return InvalidArgument("sensor.adc_bits", "must be 8 to 16");
  max_dn_ = (1 << g.adc_bits) - 1;
  if (!InRange(c.black_level_dn, 0.0, max_dn_ - 1.0))
    return InvalidArgument("sensor.black_level_dn", "must be in [0, 2^adc_bits - 2]");

  config_ = c;
  geometry_ = g;
  seed_ = seed;
  k_ = SystemGain(c);
  dark_e_ = DarkElectrons(c, exposure_time_us);
  if (!InRange(dark_e_, 0.0, kMaxFullWell))
    return InvalidArgument("sensor.dark_current_e_per_s", "dark charge per exposure exceeds 1e6 electrons");
  Result<UScale> k = UScale::FromDouble(k_, "sensor.system_gain_dn_per_e");
  if (!k.ok()) return k.status();
  k_scale_ = k.value();
  for (int i = 0; i < 3; ++i) qe_q16_[i] = Q<1, 16>::FromDouble(c.quantum_efficiency[i]).raw;
  prnu_q16_ = Q<15, 16>::FromDouble(c.prnu_percent / 100.0).raw;
  dsnu_q8_ = Q<23, 8>::FromDouble(c.dsnu_e).raw;
  read_q8_ = Q<23, 8>::FromDouble(c.dark_noise_e).raw;
  dark_q8_ = Q<24, 8>::FromDouble(dark_e_).raw;
  full_well_q8_ = Q<24, 8>::FromDouble(c.full_well_e).raw;
  black_ = Q<16, 0>::FromDouble(c.black_level_dn).raw;
  return Status::Ok();
}

Result<LineFormat> SensorStage::Plan(LineFormat in) const {
  if (in.domain != Domain::kPhotons) return InvalidArgument("sensor", "needs photons input");
  return LineFormat{Domain::kDigital, in.channels, in.mosaic};
}

void SensorStage::CountTables(WorkspaceCounter& counter) const {
  counter.Add<int32_t>(GaussianTable::kEntries);
  counter.Add<uint32_t>(PoissonTable::kEntries);
}

Status SensorStage::Init(Arena& tables) {
  int32_t* g = tables.Take<int32_t>(GaussianTable::kEntries);
  uint32_t* p = tables.Take<uint32_t>(PoissonTable::kEntries);
  if (g == nullptr || p == nullptr)
    return Status(StatusCode::kResourceExhausted, "workspace too small for sensor tables");
  CAMSIM_TRY(gauss_.Build(Span<int32_t>{g, GaussianTable::kEntries}));
  CAMSIM_TRY(poisson_.Build(Span<uint32_t>{p, PoissonTable::kEntries}));
  return Status::Ok();
}

void SensorStage::ProcessRow(const RowArgs& a) const {
  const int channels = a.out[1] != nullptr ? 3 : 1;
  const bool patterns = prnu_q16_ != 0 || dsnu_q8_ != 0;
  const uint32_t y = static_cast<uint32_t>(a.y);
  for (int c = 0; c < channels; ++c) {
    const uint32_t* in = a.rows[0].ch[c];
    uint32_t* out = a.out[c];
    int64_t electrons_sum[3] = {};
    for (int x = 0; x < a.width; ++x) {
      const Colour colour = channels == 3 ? static_cast<Colour>(c) : CfaColour(geometry_.cfa, x, a.y);
      const uint32_t ux = static_cast<uint32_t>(x);
      int32_t z_prnu = 0, z_dsnu = 0;
      if (patterns) {
        const RandomBits f = DrawBits(seed_, kStreamSensorFixedPattern, 0, ux, y, static_cast<uint32_t>(c));
        z_prnu = gauss_.Sample(f.v[0]);
        z_dsnu = gauss_.Sample(f.v[1]);
      }
      const RandomBits t = DrawBits(seed_, kStreamSensorTemporal, a.frame, ux, y, static_cast<uint32_t>(c));

      // Mean charge, Q24.8.
      uint64_t mu = RoundShiftU(static_cast<uint64_t>(in[x]) * qe_q16_[colour], 16);
      const int64_t prnu_gain = 65536 + RoundShift(prnu_q16_ * z_prnu, 16);  // Q1.16, > 0 below 50 % rms * 6.2
      mu = RoundShiftU(mu * static_cast<uint64_t>(prnu_gain < 0 ? 0 : prnu_gain), 16);
      const uint32_t mean_q8 = SatU32(mu + dark_q8_);

      // Collected charge, Q.8, clipped at the full well.
      uint64_t n_q8 = config_.shot_noise
                          ? static_cast<uint64_t>(poisson_.Sample(mean_q8, t.v[0], gauss_.Sample(t.v[1]))) << 8
                          : mean_q8;
      if (n_q8 > full_well_q8_) n_q8 = full_well_q8_;
      electrons_sum[colour] += static_cast<int64_t>(n_q8);

      // Readout: offset pattern and read noise (electrons, Q.8), then K and black level.
      const int64_t v = static_cast<int64_t>(n_q8) + RoundShift(dsnu_q8_ * z_dsnu, 16) +
                        RoundShift(read_q8_ * gauss_.Sample(t.v[2]), 16);
      const int64_t dn = RoundShift(v * static_cast<int64_t>(k_scale_.mant), k_scale_.shift + 8) + black_;
      out[x] = static_cast<uint32_t>(Clamp64(dn, 0, max_dn_));
    }
    if (a.stats != nullptr)
      for (int i = 0; i < 3; ++i) a.stats->aux_sum[i] += electrons_sum[i];
  }
}

}  // namespace camsim
