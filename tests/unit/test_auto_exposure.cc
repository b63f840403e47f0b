// Auto exposure against a plant model: the frame's brightness is
// min(1, L * 2^(EV - EV0)) * target for a scene of luminance L (L = 1: the
// target is met at EV0), i.e. the linear raw signal of an ideal sensor that
// clips at full scale. Figures measured here are the ones quoted in the notes.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/control/auto_exposure.h"

namespace camsim {
namespace {

constexpr double kTol = 1.0 / 6.0;  // convergence band, EV

struct Plant {
  double ev0;  // EV at which a scene of luminance 1 meets the target
  double target;
  double Brightness(const ExposureSettings& s, double luminance) const {
    const double y = target * luminance * std::exp2(ExposureValue(s) - ev0);
    return y > 1.0 ? 1.0 : y;
  }
};

struct Trace {
  std::vector<double> error;  // log2(y / target) of each frame (+ = too bright)
  std::vector<ExposureSettings> settings;
};

// Runs `frames` frames; luminance(n) gives the scene of frame n.
template <typename Scene>
Trace RunLoop(AutoExposure& ae, const Plant& p, int frames, Scene luminance) {
  Trace t;
  ExposureSettings s = ae.settings();
  for (int n = 0; n < frames; ++n) {
    const double y = p.Brightness(s, luminance(n));
    t.error.push_back(std::log2(y / p.target));
    t.settings.push_back(s);
    s = ae.Update(y);
  }
  return t;
}

AutoExposureConfig Continuous() {
  AutoExposureConfig c;
  c.mode = AutoExposureMode::kContinuous;
  return c;
}

// A controller settled on a scene of luminance 1 (EV0 = the initial settings' EV).
struct Settled {
  AutoExposure ae;
  Plant plant;
};
void Settle(Settled* s, const AutoExposureConfig& c) {
  const ExposureSettings initial{5000.0, 0.0, 2.8};
  ASSERT_TRUE(s->ae.Configure(c, initial).ok());
  s->plant = {ExposureValue(initial), c.target};
  RunLoop(s->ae, s->plant, 5, [](int) { return 1.0; });
  ASSERT_FALSE(s->ae.active());
}

// Frames until |error| <= 1/6 EV for good, and the largest error of the
// opposite sign afterwards (overshoot).
void StepFigures(const Trace& t, double step_sign, int* frames, double* overshoot) {
  *frames = -1;
  for (size_t n = 0; n < t.error.size(); ++n) {
    bool stays = true;
    for (size_t m = n; m < t.error.size(); ++m) stays &= std::abs(t.error[m]) <= kTol;
    if (stays) {
      *frames = static_cast<int>(n);
      break;
    }
  }
  *overshoot = 0;
  for (double e : t.error) *overshoot = std::max(*overshoot, -step_sign * e);
}

TEST(AutoExposure, EightStopStepsConvergeWithinFiveFramesWithoutOvershoot) {
  for (double step : {8.0, -8.0, 3.0, -3.0, 0.5}) {
    Settled s;
    ASSERT_NO_FATAL_FAILURE(Settle(&s, Continuous()));
    const double lum = std::exp2(step);
    const Trace t = RunLoop(s.ae, s.plant, 30, [lum](int) { return lum; });
    int frames = 0;
    double overshoot = 0;
    StepFigures(t, step > 0 ? 1 : -1, &frames, &overshoot);
    // Frame 0 is the step itself (old settings). +8 EV: 3 saturated frames
    // (-3 EV each) then 0.75 of the error per frame; -8 EV: one black frame.
    EXPECT_GE(frames, 0) << "step " << step;
    EXPECT_LE(frames, 5) << "step " << step;
    EXPECT_LE(overshoot, 0.05) << "step " << step;
    RecordProperty("step_" + std::to_string(step), "frames " + std::to_string(frames) + ", overshoot " +
                                                       std::to_string(overshoot) + " EV");
    // Settled afterwards: no more changes.
    EXPECT_EQ(t.settings[29].exposure_time_us, t.settings[25].exposure_time_us) << step;
  }
}

TEST(AutoExposure, BlackFrameDoesNotWindUpAndRecovers) {
  Settled s;
  ASSERT_NO_FATAL_FAILURE(Settle(&s, Continuous()));
  // 40 black frames: the EV goes to its maximum and stays there.
  const Trace black = RunLoop(s.ae, s.plant, 40, [](int) { return 0.0; });
  EXPECT_DOUBLE_EQ(s.ae.ev(), s.ae.ev_max());
  // The scene returns: the trajectory is that of a controller that starts at
  // the maximum EV afresh (nothing accumulated while black).
  const Trace back = RunLoop(s.ae, s.plant, 20, [](int) { return 1.0; });
  AutoExposure fresh;
  ASSERT_TRUE(fresh.Configure(Continuous(), black.settings.back()).ok());
  const Trace ref = RunLoop(fresh, s.plant, 20, [](int) { return 1.0; });
  for (int n = 0; n < 20; ++n) EXPECT_NEAR(back.error[n], ref.error[n], 1e-12) << n;
  int frames = 0;
  double overshoot = 0;
  StepFigures(back, 1, &frames, &overshoot);  // too bright at first
  // From the top of the range (16.3 stops: 20 us .. 100 ms and 24 dB) about
  // 9 stops too bright: saturated frames at -3 EV, then the PI.
  EXPECT_LE(frames, 6);
  EXPECT_LE(overshoot, 0.05);
  RecordProperty("black_recovery", "frames " + std::to_string(frames));
}

TEST(AutoExposure, SaturatedFrameDoesNotWindUpAndRecovers) {
  Settled s;
  ASSERT_NO_FATAL_FAILURE(Settle(&s, Continuous()));
  const Trace sat = RunLoop(s.ae, s.plant, 40, [](int) { return 1e9; });
  EXPECT_DOUBLE_EQ(s.ae.ev(), s.ae.ev_min());
  const Trace back = RunLoop(s.ae, s.plant, 20, [](int) { return 1.0; });
  AutoExposure fresh;
  ASSERT_TRUE(fresh.Configure(Continuous(), sat.settings.back()).ok());
  const Trace ref = RunLoop(fresh, s.plant, 20, [](int) { return 1.0; });
  for (int n = 0; n < 20; ++n) EXPECT_NEAR(back.error[n], ref.error[n], 1e-12) << n;
  int frames = 0;
  double overshoot = 0;
  StepFigures(back, -1, &frames, &overshoot);  // too dark at first
  EXPECT_LE(frames, 6);
  EXPECT_LE(overshoot, 0.05);
  RecordProperty("saturated_recovery", "frames " + std::to_string(frames));
}

TEST(AutoExposure, FlickerDoesNotMakeItOscillate) {
  // Frame-to-frame flicker of +-0.3 EV (mains light aliased by the frame rate)
  // from the first frame, starting 3 EV off: it converges and then holds.
  for (double amplitude : {0.1, 0.3, 0.45}) {
    AutoExposure ae;
    const ExposureSettings initial{5000.0, 0.0, 2.8};
    ASSERT_TRUE(ae.Configure(Continuous(), initial).ok());
    const Plant p{ExposureValue(initial) - 3.0, 0.18};  // the scene needs 3 EV less
    const Trace t = RunLoop(ae, p, 60, [amplitude](int n) { return std::exp2(n % 2 ? amplitude : -amplitude); });
    // No EV change in the last 40 frames, and the two-frame mean on target.
    for (int n = 20; n < 60; ++n) EXPECT_EQ(t.settings[n].exposure_time_us, t.settings[19].exposure_time_us) << n;
    EXPECT_LE(std::abs((t.error[58] + t.error[59]) / 2), kTol) << amplitude;
  }
}

TEST(AutoExposure, FlickerAfterSettlingChangesNothing) {
  Settled s;
  ASSERT_NO_FATAL_FAILURE(Settle(&s, Continuous()));
  const double ev = s.ae.ev();
  RunLoop(s.ae, s.plant, 50, [](int n) { return std::exp2(n % 2 ? 0.4 : -0.4); });
  EXPECT_EQ(s.ae.ev(), ev);
}

TEST(AutoExposure, LimitsAreRespectedAndTheSplitFollowsThePriority) {
  AutoExposureConfig c = Continuous();
  c.exposure_time_min_us = 100;
  c.exposure_time_max_us = 20000;
  c.gain_max_db = 12;
  c.f_number_min = 2.0;
  c.f_number_max = 8.0;
  c.priority[0] = Actuator::kTime;
  c.priority[1] = Actuator::kAperture;
  c.priority[2] = Actuator::kGain;
  AutoExposure ae;
  const ExposureSettings initial{1000.0, 0.0, 4.0};
  ASSERT_TRUE(ae.Configure(c, initial).ok());
  const Plant p{ExposureValue(initial), 0.18};
  // A darkening scene (1 EV per 5 frames, 12 EV in all) then a brightening one.
  const Trace t = RunLoop(ae, p, 120, [](int n) { return std::exp2(-std::min(n, 60) / 5.0 + std::max(0, n - 60) / 4.0); });
  for (const ExposureSettings& s : t.settings) {
    EXPECT_GE(s.exposure_time_us, 100 - 1e-9);
    EXPECT_LE(s.exposure_time_us, 20000 + 1e-9);
    EXPECT_GE(s.gain_db, 0);
    EXPECT_LE(s.gain_db, 12 + 1e-9);
    EXPECT_GE(s.f_number, 2.0 - 1e-9);
    EXPECT_LE(s.f_number, 8.0 + 1e-9);
    // Priority: the aperture opens only at the longest time, gain only at the widest aperture.
    if (s.f_number < 8.0 - 1e-9) {
      EXPECT_NEAR(s.exposure_time_us, 20000, 1e-6);
    }
    if (s.gain_db > 1e-9) {
      EXPECT_NEAR(s.f_number, 2.0, 1e-9);
    }
  }
  // At the darkest scene everything is at its maximum.
  EXPECT_NEAR(t.settings[60].gain_db, 12, 1e-9);
  EXPECT_NEAR(t.settings[60].exposure_time_us, 20000, 1e-6);
}

TEST(AutoExposure, OnceStopsWhenSettled) {
  AutoExposureConfig c = Continuous();
  c.mode = AutoExposureMode::kOnce;
  AutoExposure ae;
  const ExposureSettings initial{5000.0, 0.0, 2.8};
  ASSERT_TRUE(ae.Configure(c, initial).ok());
  const Plant p{ExposureValue(initial) + 4.0, 0.18};
  RunLoop(ae, p, 10, [](int) { return 1.0; });
  EXPECT_TRUE(ae.done());
  const double ev = ae.ev();
  RunLoop(ae, p, 10, [](int) { return 16.0; });  // the scene changes: Once does not follow
  EXPECT_EQ(ae.ev(), ev);
}

TEST(AutoExposure, OffChangesNothingAndBadConfigNamesTheKey) {
  AutoExposure ae;
  const ExposureSettings initial{5000.0, 3.0, 2.8};
  ASSERT_TRUE(ae.Configure(AutoExposureConfig{}, initial).ok());
  const ExposureSettings s = ae.Update(0.9);
  EXPECT_EQ(s.exposure_time_us, 5000.0);
  EXPECT_EQ(s.gain_db, 3.0);
  AutoExposureConfig bad = Continuous();
  bad.start_ev = 0.01;  // below settle_ev
  EXPECT_EQ(std::string(ae.Configure(bad, initial).field()), "auto_exposure.start_ev");
  // Only both limits at 0 mean a fixed aperture; a negative one is refused.
  AutoExposureConfig negative = Continuous();
  negative.f_number_min = -1.0;
  EXPECT_EQ(std::string(ae.Configure(negative, initial).field()), "auto_exposure.f_number_max");
  negative.f_number_min = 0.0;
  negative.f_number_max = -4.0;
  EXPECT_EQ(std::string(ae.Configure(negative, initial).field()), "auto_exposure.f_number_max");
}

// A target whose settle band counts as saturated (or black) would make the
// controller jump a full step every time it got there, forever: refused. A
// target just inside the limit settles.
TEST(AutoExposure, ATargetItCannotSettleOnIsRefused) {
  const ExposureSettings initial{5000.0, 0.0, 2.8};
  AutoExposure ae;
  AutoExposureConfig high = Continuous();
  high.target = 0.6;
  high.saturated_fraction = 0.55;
  EXPECT_EQ(std::string(ae.Configure(high, initial).field()), "auto_exposure.target");
  AutoExposureConfig low = Continuous();
  low.target = 0.05;
  low.black_fraction = 0.1;
  EXPECT_EQ(std::string(ae.Configure(low, initial).field()), "auto_exposure.target");
  AutoExposureConfig edge = Continuous();
  edge.mode = AutoExposureMode::kOnce;
  edge.target = 0.6;
  edge.saturated_fraction = 0.6 * std::exp2(-edge.settle_ev) + 0.01;
  ASSERT_TRUE(ae.Configure(edge, initial).ok());
  RunLoop(ae, Plant{ExposureValue(initial) + 4.0, edge.target}, 40, [](int) { return 1.0; });
  EXPECT_TRUE(ae.done());
}

// A step larger than log2(saturated / black) (8.8 EV by default) could jump
// from a saturated frame straight to a black one and back for ever; the
// bracket the two give is bisected instead, and it settles.
TEST(AutoExposure, AStepPastBothExtremesBisectsAndSettles) {
  for (double scene_ev : {6.0, -8.0}) {  // 6 EV up: saturated, then black at -13; 8 down: black first
    AutoExposureConfig c = Continuous();
    c.max_step_ev = 13;
    c.exposure_time_min_us = 1;  // room for 13 EV either way of 50 ms
    c.exposure_time_max_us = 1e8;
    AutoExposure ae;
    const ExposureSettings initial{50000.0, 0.0, 2.8};
    ASSERT_TRUE(ae.Configure(c, initial).ok());
    const Plant p{ExposureValue(initial), c.target};
    const double lum = std::exp2(scene_ev);
    const Trace t = RunLoop(ae, p, 30, [lum](int) { return lum; });
    int extremes = 0;
    for (double e : t.error) {
      const double y = p.target * std::exp2(e);
      extremes += y <= c.black_fraction || y >= c.saturated_fraction;
    }
    EXPECT_EQ(ExposureValue(t.settings[1]), ExposureValue(initial) + (scene_ev > 0 ? -13 : 13)) << "a full step first";
    EXPECT_LE(extremes, 3) << scene_ev;  // the step, the overshoot to the other extreme, then at most one more
    for (int n = 20; n < 30; ++n) EXPECT_LE(std::abs(t.error[n]), kTol) << scene_ev << " frame " << n;
    EXPECT_FALSE(ae.active()) << scene_ev;
  }
}

// The P term's sign and size: for a static scene the error follows
// m_1 = (1 - ki) m_0 (no P on the first step), then
// m_{n+1} = (1 - ki - kp) m_n + kp m_{n-1} (auto_exposure.h).
TEST(AutoExposure, ProportionalTermFollowsTheRecurrence) {
  AutoExposureConfig c = Continuous();
  c.ki = 0.5;
  c.kp = 0.3;
  c.max_step_ev = 16;
  Settled s;
  ASSERT_NO_FATAL_FAILURE(Settle(&s, c));
  const Trace t = RunLoop(s.ae, s.plant, 8, [](int) { return 0.25; });  // 2 EV too dark
  double m_prev = 2.0, m = 2.0;
  for (int n = 0; n < 8; ++n) {
    ASSERT_NEAR(-t.error[n], m, 1e-9) << n;
    if (std::abs(m) < c.settle_ev) break;
    const double next = n == 0 ? (1 - c.ki) * m : (1 - c.ki - c.kp) * m + c.kp * m_prev;
    m_prev = m;
    m = next;
  }
}

// Gains outside the stable region (ki + 2 kp >= 2) swing ever wider and are
// refused; a zero integral gain or settle band would never settle.
TEST(AutoExposure, GainsThatCannotSettleAreRefused) {
  const ExposureSettings initial{5000.0, 0.0, 2.8};
  AutoExposure ae;
  AutoExposureConfig c = Continuous();
  c.ki = 0.75;
  c.kp = 0.7;
  EXPECT_EQ(std::string(ae.Configure(c, initial).field()), "auto_exposure.kp");
  c.kp = 0.6;  // 1.95: stable, if ringing for long (a root at -0.97)
  EXPECT_TRUE(ae.Configure(c, initial).ok());
  c.kp = 0.3;  // roots 0.52 and -0.57
  ASSERT_TRUE(ae.Configure(c, initial).ok());
  const Plant p{ExposureValue(initial) + 3.0, c.target};
  const Trace t = RunLoop(ae, p, 40, [](int) { return 1.0; });
  EXPECT_LE(std::abs(t.error.back()), kTol);
  c = Continuous();
  c.ki = 0;
  EXPECT_EQ(std::string(ae.Configure(c, initial).field()), "auto_exposure.ki");
  c = Continuous();
  c.settle_ev = 0;
  EXPECT_EQ(std::string(ae.Configure(c, initial).field()), "auto_exposure.settle_ev");
}

// Once with the target out of reach ends at the end of the range (pinned),
// not never.
TEST(AutoExposure, OnceEndsWhenTheTargetIsOutOfReach) {
  AutoExposureConfig c = Continuous();
  c.mode = AutoExposureMode::kOnce;
  c.exposure_time_max_us = 10000;
  c.gain_max_db = 0;
  AutoExposure ae;
  const ExposureSettings initial{5000.0, 0.0, 2.8};
  ASSERT_TRUE(ae.Configure(c, initial).ok());
  const Plant p{ExposureValue(initial) + 4.0, 0.18};  // needs 4 EV more, 1 EV is there
  RunLoop(ae, p, 10, [](int) { return 1.0; });
  EXPECT_TRUE(ae.pinned());
  EXPECT_TRUE(ae.done());
  EXPECT_DOUBLE_EQ(ae.ev(), ae.ev_max());
  AutoExposure continuous;
  ASSERT_TRUE(continuous.Configure(Continuous(), initial).ok());
  EXPECT_FALSE(continuous.pinned());
}

// A bracket from before a scene change must not hold the EV: black frames
// (lights off) raise the EV, then the lights come on far brighter and every
// frame is saturated. The black side is too close to be the same scene's
// and is forgotten; full steps bring the EV down and it settles.
TEST(AutoExposure, AStaleBracketFromBeforeASceneChangeIsForgotten) {
  AutoExposure ae;
  const ExposureSettings initial{5000.0, 0.0, 2.8};
  ASSERT_TRUE(ae.Configure(Continuous(), initial).ok());
  const Plant p{ExposureValue(initial), 0.18};
  const Trace t = RunLoop(ae, p, 40, [](int n) { return n < 2 ? 0.0 : 64.0; });  // dark, then 6 EV above the target
  for (int n = 30; n < 40; ++n) EXPECT_LE(std::abs(t.error[n]), kTol) << n;
  EXPECT_FALSE(ae.active());
}

// Once at the end of its range is pinned on the averaged error: one frame of
// +-0.5 EV flicker that asks for more does not end it 0.3 EV off target.
TEST(AutoExposure, OnceIsNotPinnedByOneFlickeringFrame) {
  AutoExposureConfig c = Continuous();
  c.mode = AutoExposureMode::kOnce;
  AutoExposure ae;
  const ExposureSettings brightest{c.exposure_time_max_us, c.gain_max_db, 2.8};
  ASSERT_TRUE(ae.Configure(c, brightest).ok());
  ASSERT_DOUBLE_EQ(ae.ev(), ae.ev_max());
  const Plant p{ae.ev_max() - 0.3, c.target};  // the target lies 0.3 EV below the top
  const Trace t = RunLoop(ae, p, 30, [](int n) { return std::exp2(n % 2 ? 0.5 : -0.5); });
  EXPECT_FALSE(ae.pinned());
  EXPECT_TRUE(ae.done());
  EXPECT_NEAR(ae.ev(), ae.ev_max() - 0.3, 0.1);
}

}  // namespace
}  // namespace camsim
