#include "core/control/auto_exposure.h"

#include "core/base/detmath.h"

namespace camsim {
namespace {

constexpr double kDbPerStop = 6.020599913279624;  // 20 log10 2
// A frame asking for an EV this far from the average of the previous ones is
// a changed scene, not flicker: the average restarts from it (so steps are not
// slowed by averaging; flicker up to +-1 EV peak to peak is averaged out).
constexpr double kSceneChangeEv = 1.0;

bool InRange(double v, double lo, double hi) { return v >= lo && v <= hi; }  // false for NaN
double Clamp(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

}  // namespace

double ExposureValue(const ExposureSettings& s) {
  return detmath::Log2(s.exposure_time_us) + s.gain_db / kDbPerStop - 2.0 * detmath::Log2(s.f_number);
}

Status AutoExposure::Configure(const AutoExposureConfig& c, const ExposureSettings& initial) {
  if (!InRange(c.target, 0.005, 0.9)) return InvalidArgument("auto_exposure.target", "must be in [0.005, 0.9]");
  if (!(c.ki > 0 && c.ki <= 1)) return InvalidArgument("auto_exposure.ki", "must be in (0, 1]");
  if (!InRange(c.kp, 0.0, 1.0)) return InvalidArgument("auto_exposure.kp", "must be in [0, 1]");
  if (!(c.ki + 2 * c.kp < 2))
    return InvalidArgument("auto_exposure.kp", "ki + 2 kp must be below 2, or the exposure swings ever wider");
  if (!InRange(c.max_step_ev, 0.1, 16.0)) return InvalidArgument("auto_exposure.max_step_ev", "must be in [0.1, 16]");
  if (!(c.settle_ev > 0 && c.settle_ev <= 2))
    return InvalidArgument("auto_exposure.settle_ev", "must be in (0, 2]: with 0 it never settles");
  if (!InRange(c.start_ev, c.settle_ev, 4.0))
    return InvalidArgument("auto_exposure.start_ev", "must be in [settle_ev, 4]");
  if (c.average_frames < 1 || c.average_frames > 8)
    return InvalidArgument("auto_exposure.average_frames", "must be in [1, 8]");
  if (!InRange(c.black_fraction, 0.0, 0.1)) return InvalidArgument("auto_exposure.black_fraction", "must be in [0, 0.1]");
  if (!InRange(c.saturated_fraction, 0.5, 1.0))
    return InvalidArgument("auto_exposure.saturated_fraction", "must be in [0.5, 1]");
  if (!InRange(c.exposure_time_min_us, 1.0, 1e8) || !InRange(c.exposure_time_max_us, c.exposure_time_min_us, 1e8))
    return InvalidArgument("auto_exposure.exposure_time_max_us", "need 1 <= min <= max <= 1e8 us");
  if (!InRange(c.gain_min_db, 0.0, 48.0) || !InRange(c.gain_max_db, c.gain_min_db, 48.0))
    return InvalidArgument("auto_exposure.gain_max_db", "need 0 <= min <= max <= 48 dB");
  // A frame in the settle band must be able to count as a normal frame, not a
  // black or saturated one: else every frame that gets there is answered with
  // a full max_step_ev step, and the controller never settles (Once never ends).
  const double band_low = c.target * detmath::Exp2(-c.settle_ev), band_high = c.target * detmath::Exp2(c.settle_ev);
  if (!(band_low < c.saturated_fraction))
    return InvalidArgument("auto_exposure.target",
                           "target * 2^-settle_ev must be below saturated_fraction, or frames near the target count "
                           "as saturated and it never settles");
  if (!(band_high > c.black_fraction))
    return InvalidArgument("auto_exposure.target",
                           "target * 2^settle_ev must be above black_fraction, or frames near the target count as "
                           "black and it never settles");
  const bool aperture = c.f_number_min != 0 || c.f_number_max != 0;  // (a negative one is refused, not "fixed")
  if (aperture && (!InRange(c.f_number_min, 0.5, 128.0) || !InRange(c.f_number_max, c.f_number_min, 128.0)))
    return InvalidArgument("auto_exposure.f_number_max", "need 0.5 <= min <= max <= 128 (or both 0: fixed)");
  bool seen[3] = {};
  for (Actuator a : c.priority) {
    const int i = static_cast<int>(a);
    if (i < 0 || i > 2 || seen[i]) return InvalidArgument("auto_exposure.priority", "must name time, gain, aperture once each");
    seen[i] = true;
  }
  if (!InRange(initial.f_number, 0.5, 128.0)) return InvalidArgument("exposure.f_number", "must be in [0.5, 128]");
  config_ = c;
  if (!aperture) config_.f_number_min = config_.f_number_max = initial.f_number;
  // The reachable EV range.
  const ExposureSettings darkest{config_.exposure_time_min_us, config_.gain_min_db, config_.f_number_max};
  const ExposureSettings brightest{config_.exposure_time_max_us, config_.gain_max_db, config_.f_number_min};
  ev_min_ = ExposureValue(darkest);
  ev_max_ = ExposureValue(brightest);
  // With a margin of 1 EV for noise at the thresholds; no bracket when
  // black means y = 0 (a black scene is black at every EV).
  min_bracket_ev_ = c.black_fraction > 0 ? detmath::Log2(c.saturated_fraction / c.black_fraction) - 1.0 : 1e300;
  ev_ = Clamp(ExposureValue(initial), ev_min_, ev_max_);
  settings_ = c.mode == AutoExposureMode::kOff ? initial : Split(ev_);
  error_count_ = 0;
  have_previous_ = false;
  have_black_ = have_saturated_ = false;
  active_ = true;
  done_ = false;
  pinned_ = false;
  last_error_ = 0;
  return Status::Ok();
}

ExposureSettings AutoExposure::Split(double ev) const {
  // From the darkest setting, each actuator in priority order takes what it can.
  ExposureSettings s{config_.exposure_time_min_us, config_.gain_min_db, config_.f_number_max};
  double rest = ev - ev_min_;
  for (Actuator a : config_.priority) {
    if (rest <= 0) break;
    switch (a) {
      case Actuator::kTime: {
        const double range = detmath::Log2(config_.exposure_time_max_us / config_.exposure_time_min_us);
        const double take = rest < range ? rest : range;
        s.exposure_time_us = take < range ? config_.exposure_time_min_us * detmath::Exp2(take) : config_.exposure_time_max_us;
        rest -= take;
        break;
      }
      case Actuator::kGain: {
        const double range = (config_.gain_max_db - config_.gain_min_db) / kDbPerStop;
        const double take = rest < range ? rest : range;
        s.gain_db = take < range ? config_.gain_min_db + take * kDbPerStop : config_.gain_max_db;
        rest -= take;
        break;
      }
      case Actuator::kAperture: {
        const double range = 2.0 * detmath::Log2(config_.f_number_max / config_.f_number_min);
        const double take = rest < range ? rest : range;
        s.f_number = take < range ? config_.f_number_max * detmath::Exp2(-take / 2.0) : config_.f_number_min;
        rest -= take;
        break;
      }
    }
  }
  return s;
}

void AutoExposure::NotePinned(double error) {
  pinned_ = (ev_ <= ev_min_ && error < 0) || (ev_ >= ev_max_ && error > 0);
  if (pinned_ && config_.mode == AutoExposureMode::kOnce) done_ = true;  // the target is out of reach
}

ExposureSettings AutoExposure::Update(double y) {
  if (config_.mode == AutoExposureMode::kOff || done_) return settings_;
  // A black or saturated frame: the sign of the error is known, its size is
  // not: a full step, or half way into the bracket the extremes give.
  if (!(y > config_.black_fraction) || y >= config_.saturated_fraction) {  // NaN counts as black
    const bool saturated = y >= config_.saturated_fraction;
    const double e = saturated ? -config_.max_step_ev : config_.max_step_ev;
    last_error_ = e;
    error_count_ = 0;  // the decision average restarts
    have_previous_ = false;
    active_ = true;
    NotePinned(e);
    if (done_) return settings_;
    // A static scene's brightness changes at most as fast as the exposure
    // (clipping only slows it), so it is black and saturated only at EVs
    // at least log2(saturated / black) apart: a closer side is from before
    // the scene changed, and is forgotten.
    if (saturated) {
      if (have_black_ && !(ev_ - black_ev_ >= min_bracket_ev_)) have_black_ = false;
      saturated_ev_ = have_saturated_ && saturated_ev_ < ev_ ? saturated_ev_ : ev_;
      have_saturated_ = true;
    } else {
      if (have_saturated_ && !(saturated_ev_ - ev_ >= min_bracket_ev_)) have_saturated_ = false;
      black_ev_ = have_black_ && black_ev_ > ev_ ? black_ev_ : ev_;
      have_black_ = true;
    }
    double step = e;
    if (have_black_ && have_saturated_)
      step = Clamp((black_ev_ + saturated_ev_) / 2 - ev_, -config_.max_step_ev, config_.max_step_ev);
    ev_ = Clamp(ev_ + step, ev_min_, ev_max_);
    settings_ = Split(ev_);
    return settings_;
  }
  have_black_ = have_saturated_ = false;  // a measured error: the bracket is not needed
  pinned_ = false;
  const double e = detmath::Log2(config_.target / y);
  last_error_ = e;
  // Decisions (start / settle) on the mean error of the last average_frames
  // frames, each frame's error carried to the current EV: errors_ holds the EV
  // each frame asked for (its EV + its error), so frames taken before a step
  // count with what they say about the EV now.
  const int n = config_.average_frames;
  const double asked = ev_ + e;
  if (error_count_ > 0) {  // a scene change (not flicker) restarts the average
    double previous = 0;
    for (int i = 0; i < error_count_; ++i) previous += errors_[i];
    previous /= error_count_;
    if (asked - previous > kSceneChangeEv || previous - asked > kSceneChangeEv) error_count_ = 0;
  }
  for (int i = n - 1; i > 0; --i) errors_[i] = errors_[i - 1];
  errors_[0] = asked;
  if (error_count_ < n) ++error_count_;
  double mean = 0;
  for (int i = 0; i < error_count_; ++i) mean += errors_[i];
  mean = mean / error_count_ - ev_;
  // Pinned on the averaged error, once the average is full (one flickering
  // frame does not end Once).
  if (error_count_ == n) NotePinned(mean);
  if (done_) return settings_;
  const double mag = mean < 0 ? -mean : mean;
  if (active_ && error_count_ == n && mag < config_.settle_ev) {
    active_ = false;
    if (config_.mode == AutoExposureMode::kOnce) done_ = true;
  } else if (!active_ && mag > config_.start_ev) {
    active_ = true;
    have_previous_ = false;
  }
  if (!active_) return settings_;
  // Velocity-form PI on the averaged error.
  double step = config_.ki * mean;
  if (have_previous_) step += config_.kp * (mean - previous_error_);
  step = Clamp(step, -config_.max_step_ev, config_.max_step_ev);
  previous_error_ = mean;
  have_previous_ = true;
  ev_ = Clamp(ev_ + step, ev_min_, ev_max_);
  settings_ = Split(ev_);
  return settings_;
}

}  // namespace camsim
