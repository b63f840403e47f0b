// Auto exposure (paper eq. 8-10 as corrected in docs/model-notes.md): a
// controller in the log-exposure domain that, once per frame, turns a measured
// mean brightness into the exposure time, analog gain and f-number of the next
// frame. Host-or-device code (no heap, no I/O; detmath for log2/exp2 so every
// platform computes the same settings): `camsim run` carries its state through
// a sequence, and the emulated GigE camera's ExposureAuto = Once / Continuous
// can drive the same object.
//
// Exposure value (EV, stops of light reaching the ADC, relative to 1 us, 0 dB, f/1):
//   EV = log2(t / 1 us) + gain_db / (20 log10 2) - 2 log2(N)
// Error of frame n (stops): e_n = log2(target / y_n), y_n the weighted mean
// of the raw signal above black, as a fraction of the range above black.
// A black frame (y <= black_fraction) or a saturated one (y >= saturated_fraction)
// has an error of unknown size and known sign: the EV moves by a full
// +-max_step_ev (at least log2(saturated_fraction / target) stops are missing).
// Once both kinds have been seen with no measured frame between them (the
// highest EV that gave black below the lowest that gave saturated), the
// target lies between: the EV goes to the middle (bisection), so a step
// larger than log2(saturated_fraction / black_fraction) cannot swing from one
// extreme to the other for ever. A static scene is black and saturated only
// at EVs at least that far apart (its brightness changes at most as fast as
// the exposure); a side closer than that, less 1 EV, is from before a scene
// change and is forgotten (full steps again).
//
// Averaging: each frame asks for EV_n + e_n; the controller's error m_n is the
// mean of what the last average_frames frames asked for, minus the current EV
// (frames taken before a step count with what they say about the EV now).
// Frame-to-frame alternating flicker cancels in a mean of 2 (the default). A
// frame asking for more than 1 EV away from the previous mean is a scene
// change: the mean restarts from it, so steps are not slowed down.
//
// Controller: PI in velocity (incremental) form on the EV,
//   EV_{n+1} = clamp(EV_n + ki * m_n + kp * (m_n - m_{n-1}), EV_min, EV_max)
// with |step| <= max_step_ev. The EV itself is the integrator, so clamping it
// to the reachable range is the anti-windup: a black or saturated scene drives
// the EV to a limit and no further, and the first frame after the scene
// returns steps from there (the P term's e_{n-1} is reset then, so the return
// gives no kick). For a static scene the plant is EV -> log2(y) with slope 1
// and one frame of delay, so after a scene change e_{n+1} = (1 - ki) e_n for
// kp = 0 (default ki = 0.75, max_step_ev = 3): 8 -> 5 -> 2 -> 0.5 -> 0.125 EV.
// In general e_{n+1} = (1 - ki - kp) e_n + kp e_{n-1}, stable (Jury) only for
// ki > 0 and ki + 2 kp < 2, which Configure requires; kp > 0 adds a root
// below 0, an alternating part that dies out (slowly near the bound: at ki =
// 0.75, kp = 0.6 the root is -0.97).
//
// Deadband with hysteresis: the controller starts moving when |m| > start_ev
// and stops when |m| < settle_ev (> 0), so noise smaller than start_ev
// changes nothing once settled.
//
// Once ends (done) when it settles, or when at an end of the EV range the
// averaged error (a full average) or a black or saturated frame asks to go
// further (pinned: the target is out of reach).
//
// Split: the EV is spread over the actuators in `priority` order from the
// darkest setting (shortest time, least gain, largest f-number): the first
// actuator takes as much of the EV as its range allows, then the next.
// A change of f-number also changes depth of field, a change of time the
// length of motion blur: those stages read the updated settings.
#pragma once

#include <cstdint>

#include "core/base/status.h"

namespace camsim {

enum class AutoExposureMode : uint8_t { kOff, kOnce, kContinuous };
enum class Actuator : uint8_t { kTime, kGain, kAperture };

struct AutoExposureConfig {
  AutoExposureMode mode = AutoExposureMode::kOff;
  double target = 0.18;               // mean raw signal, fraction of the range above black (middle grey)
  double ki = 0.75;                   // integral gain, EV per EV of error per frame, (0, 1]
  double kp = 0.0;                    // proportional gain on the change of error, [0, 1], ki + 2 kp < 2
  double max_step_ev = 3.0;           // largest EV change per frame
  double start_ev = 0.25;             // deadband: start moving above this error
  double settle_ev = 1.0 / 12.0;      // ... stop below this one, (0, 2]
  int average_frames = 2;             // frames averaged into the controller's error m (1 .. 8)
  double black_fraction = 0.002;      // at or below: black frame
  double saturated_fraction = 0.9;    // at or above: saturated frame (below 1: a full well may clip before the ADC)
  double exposure_time_min_us = 20.0;
  double exposure_time_max_us = 100000.0;
  double gain_min_db = 0.0;
  double gain_max_db = 24.0;
  double f_number_min = 0.0;          // 0: the aperture is fixed at the configured f-number
  double f_number_max = 0.0;
  Actuator priority[3] = {Actuator::kTime, Actuator::kGain, Actuator::kAperture};
};

struct ExposureSettings {
  double exposure_time_us = 10000.0;
  double gain_db = 0.0;
  double f_number = 2.8;
};

// The EV of settings (see above).
double ExposureValue(const ExposureSettings& s);

class AutoExposure {
 public:
  // Validates the config; `initial` is the first frame's settings (also fixes
  // the aperture when no f-number range is configured). Only this can fail.
  Status Configure(const AutoExposureConfig& config, const ExposureSettings& initial);

  // One frame's measurement in, the next frame's settings out (unchanged when
  // off, settled or done). brightness: weighted mean raw signal as a fraction
  // of the range above black.
  ExposureSettings Update(double brightness);

  const ExposureSettings& settings() const { return settings_; }
  double ev() const { return ev_; }
  // log2(target / brightness) of the last frame (+: too dark); for a black
  // or saturated frame, +max_step_ev or -max_step_ev (its sign is known, its size not).
  double last_error_ev() const { return last_error_; }
  bool active() const { return active_; }  // moving (outside the deadband)
  bool done() const { return done_; }      // Once: settled or pinned (ExposureAuto returns to Off)
  bool pinned() const { return pinned_; }  // at an end of the EV range, the last decision asked to go further
  double ev_min() const { return ev_min_; }
  double ev_max() const { return ev_max_; }

 private:
  ExposureSettings Split(double ev) const;
  void NotePinned(double error);  // sets pinned_ for the frame just measured (at ev_), and done_ for Once

  AutoExposureConfig config_;
  ExposureSettings settings_;
  double ev_ = 0, ev_min_ = 0, ev_max_ = 0;
  double errors_[8] = {};  // the EV each of the last frames asked for (its EV + its error)
  int error_count_ = 0;
  double last_error_ = 0;
  double previous_error_ = 0;
  bool have_previous_ = false;
  // The bracket from extreme frames since the last measured one (see above).
  double black_ev_ = 0, saturated_ev_ = 0;
  double min_bracket_ev_ = 0;  // log2(saturated / black) - 1: closer sides are stale
  bool have_black_ = false, have_saturated_ = false;
  bool active_ = true;
  bool pinned_ = false;
  bool done_ = false;
};

}  // namespace camsim
