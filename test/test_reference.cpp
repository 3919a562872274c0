// The controller's reference (reference.h): toward a new target at the rate limit along the great
// circle, rate sources about the tip axes, overflowing commands, and a path followed at its own speed.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "hydrojet_control/control/reference.h"
#include "controller_fixtures.h"

using namespace hydrojet;
using control::Vec3;
using test::ArcPath;
using test::kDt;

// A new target is not a step: the reference moves along the great circle at most max_angular_rate.
TEST(Reference, MovesTowardANewTargetAlongTheGreatCircleAtTheRateLimit) {
  control::Reference ref(0.2, nullptr, nullptr);
  ref.hold();
  ref.start(Vec3::UnitZ(), 0.0);
  const Vec3 target = control::direction(0.4, 0.0);
  ref.aim(2.0 * target, control::Source::kDirection);  // not unit: normalised
  Vec3 prev = ref.direction();
  for (int k = 1; k <= 250; ++k) {
    const Vec3 d = ref.advance(k * kDt, kDt, control::Mat3::Identity());
    EXPECT_LE(control::geodesic_error(prev, d), 0.2 * kDt + 1e-12) << k;
    EXPECT_NEAR(d.y(), 0.0, 1e-12);  // on the great circle through z and the target
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    if (k == 100) {
      EXPECT_NEAR(control::bend_angle(d), 0.2, 1e-9);
    }
    prev = d;
  }
  EXPECT_LT(control::geodesic_error(ref.direction(), target), 1e-12);  // there after 0.4 / 0.2 = 2 s
  EXPECT_EQ(ref.source(), control::Source::kDirection);
}

// Rate sources turn about the tip frame's axes (up = +x, right = +y) and hold once they expire.
TEST(Reference, RatesTurnAboutTheTipAxesAndHoldWhenTheyExpire) {
  const control::Mat3 tip = Eigen::AngleAxisd(0.3, Vec3::UnitZ()).toRotationMatrix();  // camera rolled 0.3 rad
  for (int axis = 0; axis < 2; ++axis) {
    control::Reference ref(0.2, nullptr, nullptr);
    ref.start(Vec3::UnitZ(), 0.0);
    const Eigen::Vector2d rates = axis == 0 ? Eigen::Vector2d(0.1, 0.0) : Eigen::Vector2d(0.0, 0.1);
    ref.turn(rates, control::Source::kJoy, 1.0);
    for (int k = 1; k <= 100; ++k) ref.advance(k * kDt, kDt, tip);
    // Up turns z toward the tip's −y, right toward the tip's +x, by 0.1 rad/s × 1 s.
    const Vec3 expected = axis == 0 ? Vec3(-tip.col(1) * std::sin(0.1) + Vec3::UnitZ() * std::cos(0.1))
                                    : Vec3(tip.col(0) * std::sin(0.1) + Vec3::UnitZ() * std::cos(0.1));
    EXPECT_LT(control::geodesic_error(ref.direction(), expected), 1e-9) << axis;
    const Vec3 held = ref.direction();
    for (int k = 101; k <= 400; ++k) ref.advance(k * kDt, kDt, tip);  // no new message: expired at 1 s
    EXPECT_EQ(ref.source(), control::Source::kHold);
    EXPECT_LT(control::geodesic_error(ref.direction(), held), 0.1 * 2 * kDt);
  }
}

// Overflowing commands are directions and rates like any other, not infinities: a target of
// (1e308, 1e308, 1e308) aims along (1, 1, 1), a rate of 1e308 turns at the cap; NaN is refused.
TEST(Reference, HugeTargetsAndRatesAreNotTakenForSomethingElse) {
  control::Reference ref(0.2, nullptr, nullptr);
  ref.hold();
  ref.start(Vec3::UnitZ(), 0.0);
  ASSERT_TRUE(ref.aim(Vec3(1e308, 1e308, 1e308), control::Source::kDirection));
  for (int k = 1; k <= 1000; ++k) ref.advance(k * kDt, kDt, control::Mat3::Identity());
  EXPECT_LT(control::geodesic_error(ref.direction(), Vec3(1, 1, 1).normalized()), 1e-12);
  EXPECT_FALSE(ref.aim(Vec3(NAN, 0, 1), control::Source::kDirection));
  EXPECT_FALSE(ref.aim(Vec3::Zero(), control::Source::kDirection));
  EXPECT_EQ(ref.source(), control::Source::kDirection);  // the refused commands changed nothing

  control::Reference turning(0.2, nullptr, nullptr);
  turning.start(Vec3::UnitZ(), 0.0);
  turning.turn(Eigen::Vector2d(1e308, 0.0), control::Source::kKeyboard, 1.0);
  for (int k = 1; k <= 50; ++k) turning.advance(k * kDt, kDt, control::Mat3::Identity());
  // Up at the cap, 0.2 rad/s for 0.5 s: z turned toward −y by 0.1 rad.
  EXPECT_LT(control::geodesic_error(turning.direction(), Vec3(0, -std::sin(0.1), std::cos(0.1))), 1e-9);
}

// A path is followed as written once its clock runs, even faster than max_angular_rate; preview()
// looks ahead along it and is the reference itself otherwise.
TEST(Reference, APathIsFollowedAtItsOwnSpeedOnceItsClockRuns) {
  control::Reference ref(0.25, nullptr, nullptr);
  const auto path = std::make_shared<ArcPath>(0.6, 2.0);  // 0.6 rad/s > 0.25
  ref.follow(path, 0.0, control::Reference::PathStart::kJump);
  ref.start(Vec3::UnitZ(), 0.0);
  for (int k = 1; k <= 100; ++k) {
    const double t = 0.01 * k;
    const Vec3 d = ref.advance(t, 0.01, control::Mat3::Identity());
    EXPECT_NEAR(control::geodesic_error(d, path->direction_at(t)), 0.0, 1e-12) << t;
  }
  EXPECT_NEAR(control::geodesic_error(ref.preview(1.0, 0.1), path->direction_at(1.1)), 0.0, 1e-12);
  EXPECT_EQ(ref.preview(1.0, 0.0), ref.direction());
  EXPECT_EQ(ref.approach_time(), 0.0);  // a jump has no approach
}

// Approached from elsewhere: the reference moves to the path's first direction at most at
// max_angular_rate and waits there, the path's clock standing at 0, until begin_path(); from then the
// path runs as written from its start.
TEST(Reference, APathIsApproachedThenItsClockStarts) {
  control::Reference ref(0.25, nullptr, nullptr);
  ref.start(Vec3(std::sin(0.3), 0.0, std::cos(0.3)), 0.0);
  const auto path = std::make_shared<ArcPath>(0.6, 10.0);
  ref.follow(path, 0.0);  // PathStart::kApproach
  Vec3 prev = ref.direction();
  int k = 1;
  for (; k <= 300 && !ref.at_path_start(); ++k) {
    const Vec3 d = ref.advance(0.01 * k, 0.01, control::Mat3::Identity());
    EXPECT_LE(control::geodesic_error(prev, d), 0.25 * 0.01 + 1e-12) << k;  // rate-limited on the way
    EXPECT_TRUE(ref.approaching());
    EXPECT_EQ(ref.path_time(0.01 * k), 0.0);
    EXPECT_EQ(ref.preview(0.01 * k, 0.1), d);
    prev = d;
  }
  ASSERT_TRUE(ref.at_path_start());
  EXPECT_NEAR(k - 1, 120, 1);  // 0.3 rad at 0.0025 rad per step
  EXPECT_NEAR(control::geodesic_error(ref.direction(), path->direction_at(0.0)), 0.0, 1e-12);
  // Waiting there: the reference stays on the first direction; the path has not finished.
  for (int w = 0; w < 50; ++w) ref.advance(2.0 + 0.01 * w, 0.01, control::Mat3::Identity());
  EXPECT_NEAR(control::geodesic_error(ref.direction(), path->direction_at(0.0)), 0.0, 1e-12);
  EXPECT_FALSE(ref.path_finished(100.0));
  ref.begin_path(3.0);
  EXPECT_FALSE(ref.approaching());
  EXPECT_TRUE(ref.on_path());
  EXPECT_NEAR(ref.approach_time(), 3.0, 1e-12);
  EXPECT_NEAR(ref.path_time(4.0), 1.0, 1e-12);
  const Vec3 d = ref.advance(4.0, 0.01, control::Mat3::Identity());
  EXPECT_NEAR(control::geodesic_error(d, path->direction_at(1.0)), 0.0, 1e-12);
  EXPECT_TRUE(ref.path_finished(13.0));
}

// Time scaling: a path that turns faster than max_path_rate is followed as written, later. A lissajous
// of known peak speed (about 2.5 rad/s) under a 0.4 rad/s bound: no step of the reference turns faster
// than the bound, the path's end is reached, and the clock took the time the bound allows (the
// path's length over the bound where it is faster, its own time elsewhere).
TEST(Reference, APathFasterThanTheRateBoundIsSlowedAndNeverExceedsIt) {
  std::vector<control::Waypoint> w;
  for (int k = 0; k <= 40; ++k) w.push_back({0.1 * k, control::direction(0.3 + 0.2 * std::sin(0.9 * k), 0.25 * k)});
  const std::shared_ptr<const control::Path> path = control::make_waypoints(w);
  const double bound = 0.4;
  control::Reference ref(10.0, nullptr, nullptr);
  ref.set_max_path_rate(bound);
  ref.follow(path, 0.0, control::Reference::PathStart::kJump);
  ref.start(Vec3::UnitZ(), 0.0);
  Vec3 prev = ref.advance(0.0, kDt, control::Mat3::Identity());
  double length = 0.0, fast = 0.0;  // the path's length, and the time it spends faster than the bound
  for (double t = 0.0; t < path->duration(); t += 0.001) {
    const double step = control::geodesic_error(path->direction_at(t), path->direction_at(t + 0.001));
    length += step;
    if (step / 0.001 > bound) fast += 0.001;
  }
  int k = 0;
  while (++k < 100000) {
    const Vec3 d = ref.advance(k * kDt, kDt, control::Mat3::Identity());
    EXPECT_LE(control::geodesic_error(prev, d), bound * kDt * (1 + 1e-9)) << k;
    prev = d;
    if (ref.path_finished(k * kDt)) break;
  }
  ASSERT_TRUE(ref.path_finished(k * kDt));
  EXPECT_LT(control::geodesic_error(ref.direction(), path->direction_at(path->duration())), 1e-6);
  EXPECT_GT(ref.time_scale(), 2.0);
  // At least the length at the bound; at most that plus the path's own time where it is slow.
  EXPECT_GE(k * kDt, length / bound * 0.98);
  EXPECT_LE(k * kDt, length / bound + (path->duration() - fast) + 0.05);
}

// Without a bound (or under it) the clock is the path's own: bit for bit the time since its start.
TEST(Reference, APathWithinTheRateBoundRunsAsWritten) {
  auto path = std::make_shared<ArcPath>(0.3, 3.0);
  control::Reference ref(10.0, nullptr, nullptr);
  ref.set_max_path_rate(1.5);
  ref.follow(path, 0.0, control::Reference::PathStart::kJump);
  ref.start(Vec3::UnitZ(), 0.0);
  for (int k = 0; k <= 300; ++k) {
    const Vec3 d = ref.advance(k * kDt, kDt, control::Mat3::Identity());
    EXPECT_EQ(d, Vec3(path->direction_at(k * kDt - 0.0))) << k;
    EXPECT_EQ(ref.path_time(k * kDt), k * kDt - 0.0);
  }
  EXPECT_EQ(ref.time_scale(), 1.0);
}

// The learned reach: a jet saturated with the error staying outward for 0.2 s limits that azimuth to
// where the tip got, taking effect from where the target was at 0.1 rad/s (no jump); beyond the bin
// the limit widens by `slope` (0.3) rad per rad of azimuth; a target beyond it is pulled in radially and
// reported; the limit relaxes outward at 0.02 rad/s once no jet saturates.
TEST(LearnedReach, LimitsWhereTheJetsSaturateGraduallyAndRelaxesWhenTheyDoNot) {
  control::LearnedReach reach(Vec3::UnitZ(), 72);
  const Vec3 measured = control::direction(0.5, 0.3), desired = control::direction(0.6, 0.3);
  for (int k = 0; k < 19; ++k) reach.update(true, measured, desired, 0.01);
  EXPECT_FALSE(reach.learned());  // 0.19 s: not yet
  reach.update(false, measured, desired, 0.01);
  for (int k = 0; k < 20; ++k) reach.update(true, measured, desired, 0.01);
  ASSERT_TRUE(reach.learned());
  EXPECT_NEAR(reach.learned_limit(desired), 0.5, 1e-9);
  EXPECT_NEAR(reach.limit(desired), 0.6 - 0.01 * reach.options().tighten_rate,
              1e-9);  // from where the target was (one step tightened)
  for (int k = 0; k < 25; ++k) reach.update(true, measured, desired, 0.01);
  EXPECT_NEAR(reach.limit(desired), 0.6 - 0.26 * reach.options().tighten_rate, 1e-9);  // for 0.26 s
  for (int k = 0; k < 60; ++k) reach.update(true, measured, desired, 0.01);
  EXPECT_NEAR(reach.limit(desired), 0.5, 1e-9);  // there, and no further
  double moved = 0.0;
  const Vec3 clipped = reach.clip(control::direction(0.8, 0.3), &moved);
  EXPECT_NEAR(control::bend_angle(clipped), 0.5, 1e-9);
  EXPECT_NEAR(moved, 0.3, 1e-9);
  // Continuous in azimuth: 0.2 rad of azimuth beyond the bin's edge, slope · 0.2 rad wider.
  const double edge = M_PI / 72, slope = reach.options().slope;
  EXPECT_NEAR(reach.limit(control::direction(0.8, 0.3 + 0.2 + 2 * edge)), 0.5 + slope * 0.2, slope * 2 * edge + 1e-9);
  EXPECT_EQ(reach.clip(control::direction(0.8, 0.3 + M_PI)), control::direction(0.8, 0.3 + M_PI));  // far: free
  EXPECT_EQ(reach.clip(control::direction(0.4, 0.3), &moved), control::direction(0.4, 0.3));
  EXPECT_EQ(moved, 0.0);
  // Saturated but the error inward, or small: nothing learned there.
  control::LearnedReach other(Vec3::UnitZ(), 72);
  for (int k = 0; k < 100; ++k) other.update(true, desired, measured, 0.01);
  for (int k = 0; k < 100; ++k) other.update(true, measured, control::direction(0.51, 0.3), 0.01);
  EXPECT_FALSE(other.learned());
  // A second azimuth, 2 rad round: where the first bin's limit, widened, lies far beyond the target,
  // the new limit still takes effect from where the target is (not from 0.5 + 2 slope rad).
  control::LearnedReach two(Vec3::UnitZ(), 72);
  for (int k = 0; k < 200; ++k) two.update(true, measured, desired, 0.01);
  const Vec3 measured2 = control::direction(0.5, 2.3), desired2 = control::direction(0.6, 2.3);
  two.update(false, measured2, desired2, 0.01);
  EXPECT_GT(two.limit(desired2), 0.5 + 1.9 * slope);
  for (int k = 0; k < 20; ++k) two.update(true, measured2, desired2, 0.01);
  EXPECT_NEAR(two.limit(desired2), 0.6 - 0.01 * two.options().tighten_rate, 1e-9);
  for (int k = 0; k < 100; ++k) two.update(true, measured2, desired2, 0.01);
  EXPECT_NEAR(two.limit(desired2), 0.5, 1e-9);
  // Relaxes: 1 s without saturation gives back 0.02 rad.
  for (int k = 0; k < 100; ++k) reach.update(false, measured, measured, 0.01);
  EXPECT_NEAR(reach.limit(desired), 0.52, 1e-9);
}

// A plant that rings under the paper's law: from the desired direction's angle the reach closes in at
// ring_rate at every azimuth while it rings, and relaxes outward at relax_rate once it does not;
// reset forgets.
TEST(LearnedReach, ClosesInAtEveryAzimuthWhileThePlantRings) {
  control::LearnedReach reach(Vec3::UnitZ(), 72);
  const Vec3 desired = control::direction(0.6, 0.3);
  for (int k = 0; k < 100; ++k) reach.ring(false, desired, 0.01);
  EXPECT_FALSE(reach.learned());
  reach.ring(true, desired, 0.01);
  ASSERT_TRUE(reach.learned());
  EXPECT_NEAR(reach.ring_limit(), 0.6 - 0.01 * reach.options().ring_rate, 1e-12);  // from where the target was
  for (int k = 0; k < 49; ++k) reach.ring(true, desired, 0.01);
  const double after = 0.6 - 0.5 * reach.options().ring_rate;  // 0.5 s of ringing
  EXPECT_NEAR(reach.ring_limit(), after, 1e-9);
  reach.ring(false, desired, 0.01);  // calm: 0.01 s relaxed
  const double relaxed = after + 0.01 * reach.options().relax_rate;
  EXPECT_NEAR(reach.ring_limit(), relaxed, 1e-9);
  for (const double azimuth : {0.3, 1.9, -2.8}) {  // every azimuth, pulled in along its own
    double moved = 0.0;
    const Vec3 clipped = reach.clip(control::direction(0.9, azimuth), &moved);
    EXPECT_NEAR(control::bend_angle(clipped), relaxed, 1e-9) << azimuth;
    EXPECT_NEAR(moved, 0.9 - relaxed, 1e-9) << azimuth;
    EXPECT_EQ(reach.clip(control::direction(relaxed - 0.1, azimuth)), control::direction(relaxed - 0.1, azimuth));
  }
  for (int k = 0; k < 299; ++k) reach.ring(false, desired, 0.01);  // 3 s of calm in all
  EXPECT_NEAR(reach.ring_limit(), after + 3.0 * reach.options().relax_rate, 1e-9);
  // Ringing again further in closes in from that target; further out, from the limit.
  reach.ring(true, control::direction(0.2, 1.0), 0.01);
  EXPECT_NEAR(reach.ring_limit(), 0.2 - 0.01 * reach.options().ring_rate, 1e-9);
  reach.ring(false, desired, 0.01);
  reach.ring(true, control::direction(0.9, 1.0), 0.01);
  EXPECT_NEAR(reach.ring_limit(), 0.2 + 0.01 * reach.options().relax_rate - 0.02 * reach.options().ring_rate, 1e-9);
  // Reset while ringing: no limit, and the next ringing starts afresh from its target.
  reach.reset();
  EXPECT_FALSE(reach.learned());
  EXPECT_EQ(reach.clip(control::direction(0.9, 0.3)), control::direction(0.9, 0.3));
  reach.ring(true, desired, 0.01);
  EXPECT_NEAR(reach.ring_limit(), 0.6 - 0.01 * reach.options().ring_rate, 1e-9);
  // Relaxed past π: no limit.
  for (int k = 0; k < 20000; ++k) reach.ring(false, desired, 0.01);
  EXPECT_FALSE(reach.learned());
}
