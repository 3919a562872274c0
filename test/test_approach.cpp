// The approach to a path (control/approach.h): when the tip counts as settled on the path's first
// direction, and when it does not settle. Synthetic signals with known RMS, so that each verdict
// follows from the definition.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "hydrojet_control/control/approach.h"

namespace {

using hydrojet::control::ApproachMonitor;
using hydrojet::control::ApproachOptions;
using hydrojet::control::direction;
using Verdict = ApproachMonitor::Verdict;

constexpr double kDt = 0.01;

/// Feeds `seconds` of cycles: error e(t) and the tip at bend angle theta(t), azimuth 0; returns the
/// first verdict other than kSettling (or kSettling) and the time it came.
template <class Error, class Theta>
Verdict feed(ApproachMonitor* m, double t0, double seconds, Error e, Theta theta, double* when) {
  for (double t = t0; t < t0 + seconds - 1e-9; t += kDt) {
    const Verdict v = m->update(t, true, e(t), direction(theta(t), 0.0));
    if (v != Verdict::kSettling) {
      *when = t;
      return v;
    }
  }
  *when = t0 + seconds;
  return Verdict::kSettling;
}

TEST(Approach, SettlesAfterOneQuietWindow) {
  ApproachMonitor m;  // tolerance 0.02 rad, window 0.3 s
  std::mt19937 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  // Tracker-like noise: 0.007 rad RMS on the error and on the tip, well inside the tolerance.
  double when = 0.0;
  const Verdict v = feed(
      &m, 10.0, 2.0, [&](double) { return 0.007 * std::abs(n01(rng)); }, [&](double) { return 0.3 + 0.007 * n01(rng); },
      &when);
  EXPECT_EQ(v, Verdict::kSettled);
  EXPECT_NEAR(when, 10.3, 0.011);  // not before a whole window since the reference got there
}

TEST(Approach, ARingingTipOrAnOffsetDoesNotSettle) {
  // Ringing: 0.04 rad amplitude at 3 Hz (RMS spread 0.028 > 0.02), no error offset, decaying with
  // a 1 s time constant: it settles once the RMS spread falls below 0.02 — at ln(0.028/0.02) s ≈
  // 0.34 s plus about half a window.
  ApproachMonitor m;
  double when = 0.0;
  auto ring = [](double t) { return 0.3 + 0.04 * std::exp(-t) * std::sin(2 * M_PI * 3.0 * t); };
  EXPECT_EQ(feed(
                &m, 0.0, 5.0, [](double) { return 0.0; }, ring, &when),
            Verdict::kSettled);
  EXPECT_GT(when, 0.34);
  EXPECT_LT(when, 0.34 + 0.3);
  // A still tip 0.05 rad off: the error's RMS exceeds the tolerance; after the timeout, a failure
  // that says what it saw.
  ApproachOptions o;
  o.timeout = 1.0;
  ApproachMonitor off(o);
  EXPECT_EQ(feed(
                &off, 0.0, 3.0, [](double) { return 0.05; }, [](double) { return 0.3; }, &when),
            Verdict::kFailed);
  EXPECT_NEAR(when, 1.01, 0.011);
  EXPECT_NE(off.failure().find("RMS error 0.0500 rad"), std::string::npos) << off.failure();
}

TEST(Approach, MovingRestartsTheWindowAndOptionsAreChecked) {
  ApproachMonitor m;
  double when = 0.0;
  EXPECT_EQ(feed(
                &m, 0.0, 0.2, [](double) { return 0.0; }, [](double) { return 0.3; }, &when),
            Verdict::kSettling);
  EXPECT_EQ(m.update(0.2, false, 0.1, direction(0.3, 0.0)), Verdict::kMoving);  // the reference left again
  EXPECT_EQ(feed(
                &m, 0.21, 0.25, [](double) { return 0.0; }, [](double) { return 0.3; }, &when),
            Verdict::kSettling);
  EXPECT_EQ(m.update(0.51, true, 0.0, direction(0.3, 0.0)), Verdict::kSettled);  // 0.3 s after 0.21
  ApproachOptions o;
  EXPECT_EQ(o.validate(), "");
  o.tolerance = std::nan("");
  EXPECT_EQ(o.validate().rfind("tolerance:", 0), 0u);
  o = ApproachOptions();
  o.timeout = 0.0;
  EXPECT_EQ(o.validate().rfind("timeout:", 0), 0u);
}

}  // namespace
