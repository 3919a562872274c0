// The external tip force's estimate and the contact detector (control/contact.h), against the rod
// solver's own equilibrium under a known tip force; the controller file's `contact:` group.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include <yaml-cpp/yaml.h>

#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/control/contact.h"
#include "controller_fixtures.h"
#include "test_helpers.h"

using namespace hydrojet;
using control::ContactCycle;
using control::ContactEstimator;
using control::ContactOptions;
using control::Mat3;
using control::Vec3;

namespace {

/// The HydroJet's model and a plant that is the model plus a known tip force (fixed in the tip frame).
struct Rig {
  Rig()
      : model(config::make_controller_model(test::scene("hydrojet_0deg"), test::flow_gains())), truth(model.solver()) {}
  control::ActuatedModel model;
  rod::RodSolver truth;

  /// One cycle at time t with inputs q: the model's pose and C^b, and the pose the tracker measures with
  /// `force` [N, tip frame] on the tip, plus the tracker's noise from `rng` (null: none).
  ContactCycle cycle(double t, const control::InputVector& q, const Vec3& force, std::mt19937* rng = nullptr) {
    ContactCycle c;
    const rod::RodSolution s = model.solve(q);
    c.t = c.stamp = t;
    c.new_sample = true;
    c.model_rotation = s.tip_rotation;
    c.model_position = s.tip_position;
    c.compliance = model.linearise().body_compliance;
    c.inputs = q;
    rod::TipWrench w;
    w.force = force;
    const rod::RodSolution m = truth.solve(q, w);
    c.measured_rotation = m.tip_rotation;
    c.measured_position = m.tip_position;
    if (rng) {
      std::normal_distribution<double> angle(0.0, ContactEstimator::kDirectionSigma);
      std::normal_distribution<double> position(0.0, ContactEstimator::kPositionSigma);
      const Vec3 turn(angle(*rng), angle(*rng), angle(*rng));
      c.measured_rotation = c.measured_rotation * Eigen::AngleAxisd(turn.norm(), turn.normalized()).toRotationMatrix();
      c.measured_position += Vec3(position(*rng), position(*rng), position(*rng));
    }
    return c;
  }
  /// The same with the tip against a surface that pushes with `surface` [N, tip frame]: the tip
  /// stays where `force` alone puts it while the model goes on into the surface by the push's turn.
  ContactCycle against(double t, const control::InputVector& q, const Vec3& surface, const Vec3& force,
                       std::mt19937* rng) {
    ContactCycle c = cycle(t, q, force, rng);
    rod::TipWrench w;
    w.force = -surface;
    const rod::RodSolution m = truth.solve(q, w);
    c.model_rotation = m.tip_rotation;
    c.model_position = m.tip_position;
    return c;
  }
};

control::InputVector inputs(double a, double b, double c) {
  control::InputVector q(3);
  q << a, b, c;
  return q;
}

}  // namespace

// One sample of a known lateral tip force on the solver's equilibrium: the estimate is the force in the
// base frame across the tip's axis, to the linearisation's error (a few percent at 20 mN), with no
// noise and nothing learned.
TEST(ContactEstimator, OneSampleRecoversAKnownTipForce) {
  Rig rig;
  for (const Vec3& force : {Vec3(0.02, 0.0, 0.0), Vec3(0.0, -0.015, 0.0), Vec3(0.012, 0.012, 0.0)})
    for (const control::InputVector& q : {inputs(0, 0, 0), inputs(0.08, 0.0, 0.02)}) {
      ContactEstimator e(ContactOptions(), 3, 0.15);
      const ContactCycle c = rig.cycle(0.0, q, force);
      const control::ContactState& s = e.update(c);
      ASSERT_TRUE(s.ready);
      // The follower force in the base frame, across the tip's axis (along it the rod is stiff and
      // the estimate says nothing).
      const Vec3 truth = c.measured_rotation * force;
      const Vec3 axis = c.measured_rotation.col(2);
      const Vec3 miss = (s.force - truth) - (s.force - truth).dot(axis) * axis;
      EXPECT_LT(miss.norm(), 0.05 * force.norm() + 2e-4)
          << "force " << force.transpose() << " q " << q.transpose() << ": estimate " << s.force.transpose()
          << ", truth " << truth.transpose();
      // Its deflection is the measured turn of the tip's direction (to 8 %: turns of up to 0.12 rad,
      // where C^b's linearisation is a few percent off).
      const Vec3 turn = c.measured_rotation.col(2) - c.model_rotation.col(2);
      EXPECT_LT((s.deflection - turn).norm(), 0.08 * turn.norm() + 1e-4);
    }
}

// Free space with the tracker's noise: no flag, and the estimate's spread is the noise's. A 30 mN push
// is flagged within 0.1 s (the filter and two samples), its size to 10 %; released within 0.15–0.4 s
// of its end (hysteresis), and not before.
TEST(ContactEstimator, TheDetectorFlagsAPushAndReleasesWithHysteresis) {
  Rig rig;
  std::mt19937 rng(3);
  ContactEstimator e(ContactOptions(), 3, 0.15);
  const control::InputVector q = inputs(0.05, 0.01, 0.03);
  const double dt = 0.01;
  double t = 0.0;
  double worst = 0.0;
  for (; t < 3.0; t += dt) {
    const control::ContactState& s = e.update(rig.cycle(t, q, Vec3::Zero(), &rng));
    ASSERT_FALSE(s.in_contact) << "free space flagged at t = " << t;
    if (t > 1.0) worst = std::max(worst, s.force.norm());
  }
  EXPECT_LT(worst, 0.5 * ContactOptions().force_threshold);
  const double push = t;
  const Vec3 force(0.03, 0.0, 0.0);
  double flagged = -1.0;
  for (; t < push + 1.0; t += dt) {
    const control::ContactState& s = e.update(rig.against(t, q, force, Vec3::Zero(), &rng));
    if (s.in_contact && flagged < 0.0) flagged = t;
  }
  ASSERT_GE(flagged, 0.0) << "a 30 mN push was not flagged";
  EXPECT_LE(flagged - push, 0.1);
  EXPECT_NEAR(e.state().force.norm(), force.norm(), 0.1 * force.norm());
  EXPECT_GT(e.state().normal.dot(Vec3::UnitX()), 0.98);
  const double end = t;
  double released = -1.0;
  for (; t < end + 1.0; t += dt) {
    const control::ContactState& s = e.update(rig.cycle(t, q, Vec3::Zero(), &rng));
    if (!s.in_contact && released < 0.0) released = t;
  }
  ASSERT_GE(released, 0.0);
  EXPECT_GE(released - end, ContactEstimator::kReleaseTime);
  EXPECT_LE(released - end, 0.4);
}

// While the law's supervisor has stepped in (the tip rings: its swing reads as a force) a push
// is flagged only above kRingingThreshold times the threshold: 15 mN (1.25x) is not, 24 mN (2x) is;
// the same 15 mN is flagged when the tip does not ring.
TEST(ContactEstimator, WhileTheTipRingsOnlyAStrongerPushIsFlagged) {
  Rig rig;
  const control::InputVector q = inputs(0.05, 0.01, 0.03);
  const double dt = 0.01, threshold = ContactOptions().force_threshold;
  for (const auto& [size, ringing] :
       {std::pair<double, bool>{1.25 * threshold, true}, {2.0 * threshold, true}, {1.25 * threshold, false}}) {
    std::mt19937 rng(4);
    ContactEstimator e(ContactOptions(), 3, 0.15);
    double t = 0.0;
    for (; t < 3.0; t += dt) e.update(rig.cycle(t, q, Vec3::Zero(), &rng));
    bool flagged = false;
    for (const double push = t; t < push + 0.5; t += dt) {
      ContactCycle c = rig.against(t, q, Vec3(size, 0.0, 0.0), Vec3::Zero(), &rng);
      c.ringing = ringing;
      flagged = flagged || e.update(c).in_contact;
    }
    EXPECT_EQ(flagged, !ringing || size > ContactEstimator::kRingingThreshold * threshold)
        << size << " N, ringing " << ringing;
  }
}

// While the reference is held back from the surface a weak estimate releases only after
// kHeldRelease; a push handed over as a load is kept as the load: no flag while it stays, and the
// estimate reads it (not learned away as mismatch).
TEST(ContactEstimator, TheHeldReleaseWaitsAndALoadIsLearned) {
  Rig rig;
  std::mt19937 rng(4);
  ContactEstimator e(ContactOptions(), 3, 0.15);
  const control::InputVector q = inputs(0.04, 0.02, 0.03);
  const double dt = 0.01;
  double t = 0.0;
  auto step = [&](const Vec3& force, bool pressing) {  // a surface's push
    ContactCycle c = rig.against(t, q, force, Vec3::Zero(), &rng);
    c.pressing = pressing;
    t += dt;
    return e.update(c).in_contact;
  };
  while (t < 3.0) ASSERT_FALSE(step(Vec3::Zero(), false));
  const Vec3 push(0.0, 0.03, 0.0);
  for (const double end = t + 1.0; t < end;) step(push, true);
  ASSERT_TRUE(e.state().in_contact);
  const double end = t;
  while (step(Vec3::Zero(), true) && t < end + 2.0) {
  }
  EXPECT_GE(t - end, ContactEstimator::kHeldRelease);
  EXPECT_LE(t - end, ContactEstimator::kHeldRelease + 0.2);
  for (const double until = t + 1.5; t < until;) step(Vec3::Zero(), false);  // free again, learning
  for (const double until = t + 1.0; t < until;) step(push, false);
  ASSERT_TRUE(e.state().in_contact);
  e.take_as_load(t);
  EXPECT_FALSE(e.state().in_contact);
  for (const double until = t + 4.0; t < until;) EXPECT_FALSE(step(push, false)) << "the load flagged again at " << t;
  const Mat3 tip = rig.model.solve(q).tip_rotation;
  const Vec3 truth = tip * push;  // base frame; compared across the tip's axis (along it nothing is read)
  const auto across = [&](const Vec3& v) { return Vec3(v - v.dot(tip.col(2)) * tip.col(2)); };
  EXPECT_LT(across(e.state().load - truth).norm(), 0.005) << e.state().load.transpose();
  EXPECT_LT(across(e.state().force - truth).norm(), 0.005) << e.state().force.transpose();
}

// A surface stops the tip while the model goes on into it (inputs along a direction the mismatch
// model has seen); a load moves the tip while the model stays. The first is flagged; the second (its force rising over
// 0.1 s, as the tip gives way at the rod's own pace) is not, and is read as a load within 5 mN.
TEST(ContactEstimator, ATipThatGivesWayIsALoadAndATipThatStopsIsASurface) {
  Rig rig;
  const control::InputVector q = inputs(0.04, 0.02, 0.03);
  const double dt = 0.01;
  {
    std::mt19937 rng(6);
    ContactEstimator e(ContactOptions(), 3, 0.15);
    double t = 0.0;
    for (; t < 3.0; t += dt) ASSERT_FALSE(e.update(rig.cycle(t, q, Vec3::Zero(), &rng)).in_contact);
    const Vec3 push(0.0, 0.025, 0.0);
    const double onset = t;
    for (; t < onset + 2.0; t += dt) {
      const double ramp = std::min(1.0, (t - onset) / 0.1);
      EXPECT_FALSE(e.update(rig.cycle(t, q, ramp * push, &rng)).in_contact) << "a load flagged at " << t - onset;
    }
    const Vec3 truth = rig.model.solve(q).tip_rotation * push;
    EXPECT_LT((e.state().load - truth).norm(), 0.005) << e.state().load.transpose();
    EXPECT_LT((e.state().force - truth).norm(), 0.005) << e.state().force.transpose();
  }
  {
    std::mt19937 rng(7);
    ContactEstimator e(ContactOptions(), 3, 0.15);
    double t = 0.0;
    auto sweep = [&](double at) { return inputs(0.04 + 0.03 * std::sin(2.0 * M_PI * at / 1.5), 0.02, 0.03); };
    for (; t < 3.0; t += dt) ASSERT_FALSE(e.update(rig.cycle(t, sweep(t), Vec3::Zero(), &rng)).in_contact);
    const ContactCycle held = rig.cycle(t, sweep(t), Vec3::Zero());  // where the surface stops the tip
    const double onset = t;
    double flagged = -1.0;
    for (; t < onset + 1.0 && flagged < 0.0; t += dt) {
      ContactCycle c = rig.cycle(t, inputs(0.04 + 0.1 * (t - onset), 0.02, 0.03), Vec3::Zero(), &rng);
      c.measured_rotation = held.measured_rotation;  // the model goes on along jet 1; the tip stays
      c.measured_position = held.measured_position;
      if (e.update(c).in_contact) flagged = t;
    }
    ASSERT_GE(flagged, 0.0) << "the surface was never flagged";
    EXPECT_LT(flagged - onset, 0.3);
    EXPECT_LT(e.state().load.norm(), 1e-12);
  }
}

// A push the tip gives way to that keeps growing (a soft wall the law presses into, read as a load
// at first) is held as a load only up to kMaxLoad × max_force: past it, the load goes back to the
// detector and the push is flagged; the load held never exceeds that bound by more than a sample's
// settling.
TEST(ContactEstimator, APushHeldHarderThanALoadIsFlagged) {
  Rig rig;
  const control::InputVector q = inputs(0.04, 0.02, 0.03);
  const double dt = 0.01, rate = 0.1;  // [N/s] the push's growth
  const ContactOptions options;
  const double most = ContactEstimator::kMaxLoad * options.max_force;
  std::mt19937 rng(8);
  ContactEstimator e(options, 3, 0.15);
  double t = 0.0;
  for (; t < 3.0; t += dt) ASSERT_FALSE(e.update(rig.cycle(t, q, Vec3::Zero(), &rng)).in_contact);
  const double onset = t;
  double flagged_at = -1.0, held = 0.0;
  for (; t < onset + 2.0 && flagged_at < 0.0; t += dt) {
    const double push = rate * (t - onset);
    const control::ContactState& s = e.update(rig.cycle(t, q, Vec3(0.0, push, 0.0), &rng));
    ASSERT_LE(s.load.norm(), most + 0.005) << "at a push of " << push << " N";
    held = std::max(held, s.load.norm());
    if (s.in_contact) flagged_at = push;
  }
  EXPECT_GT(held, 0.5 * most) << "the push was never held as a load: the bound was not what flagged it";
  ASSERT_GE(flagged_at, 0.0) << "a push grown to " << rate * 2.0 << " N was never flagged";
  EXPECT_LT(flagged_at, most + 0.02);  // the reading's lag behind the push: 0.03 s filter and two samples
}

// A model mismatch (a constant 20 mN in the tip frame, as a precurvature offset reads) over moving
// inputs is learned in free space: no flag, the estimate near zero; a contact on top of it is then
// read at its own size, the mismatch frozen meanwhile.
TEST(ContactEstimator, TheMismatchIsLearnedInFreeSpaceAndFrozenInContact) {
  Rig rig;
  std::mt19937 rng(5);
  ContactEstimator e(ContactOptions(), 3, 0.15);
  const Vec3 mismatch(0.02, -0.01, 0.0);
  const double dt = 0.01;
  double t = 0.0;
  auto q_at = [](double t) {
    return inputs(0.04 + 0.03 * std::sin(0.7 * t), 0.04 + 0.03 * std::sin(0.7 * t + 2.1),
                  0.04 + 0.03 * std::sin(0.7 * t + 4.2));
  };
  for (; t < 8.0; t += dt) {
    const control::ContactState& s = e.update(rig.cycle(t, q_at(t), mismatch, &rng));
    ASSERT_FALSE(s.in_contact) << "the mismatch was flagged at t = " << t;
  }
  EXPECT_LT(e.state().force.norm(), 0.004);
  const Vec3 push(0.0, 0.03, 0.0);
  ContactCycle last;
  for (const double end = t + 1.5; t < end; t += dt) e.update(last = rig.against(t, q_at(t), push, mismatch, &rng));
  ASSERT_TRUE(e.state().in_contact);
  EXPECT_LT((e.state().force - last.measured_rotation * push).norm(), 0.006)
      << "estimate " << e.state().force.transpose();
}

// A surface grazed under the threshold is learned as mismatch (nothing tells it apart while it
// grows slowly: here 40 mN over 2 s, the model going on into it); left, the learned push reads as
// a pull. A snapshot of the model from before the graze reads that as free space, so the estimator
// goes back to it: no flag, and the estimate near zero again. The graze is learned by more than
// the threshold (checked), so the model that learned it would flag the leaving (it did, 0.28 s
// after, before the snapshots). A surface met a second later is flagged and read as before.
TEST(ContactEstimator, ASurfaceGrazedAndLeftIsNotFlagged) {
  Rig rig;
  std::mt19937 rng(11);
  ContactEstimator e(ContactOptions(), 3, 0.15);
  const double dt = 0.01, threshold = ContactOptions().force_threshold;
  auto q_at = [](double t) {
    return inputs(0.04 + 0.02 * std::sin(0.5 * t), 0.04 + 0.02 * std::sin(0.5 * t + 2.1),
                  0.04 + 0.02 * std::sin(0.5 * t + 4.2));
  };
  double t = 0.0;
  for (; t < 4.0; t += dt) {
    ASSERT_FALSE(e.update(rig.cycle(t, q_at(t), Vec3::Zero(), &rng)).in_contact);
  }
  const Vec3 direction(0.0, 1.0, 0.0);
  ContactCycle last;
  for (const double start = t; t < start + 2.2; t += dt) {
    const Vec3 push = std::min(1.0, (t - start) / 2.0) * 0.04 * direction;
    ASSERT_FALSE(e.update(last = rig.against(t, q_at(t), push, Vec3::Zero(), &rng)).in_contact)
        << "the graze was flagged at t = " << t;
  }
  const Vec3 truth = last.measured_rotation * (0.04 * direction);
  ASSERT_GT((truth - e.state().force).norm(), threshold) << "the graze was read " << e.state().force.transpose();
  for (const double left = t; t < left + 1.0; t += dt) {
    const control::ContactState& s = e.update(rig.cycle(t, q_at(t), Vec3::Zero(), &rng));
    ASSERT_FALSE(s.in_contact) << "the leaving was flagged at t = " << t << ", force " << s.force.transpose();
    if (t > left + 0.2) {
      EXPECT_LT(s.force.norm(), 0.5 * threshold) << "at t = " << t;
    }
  }
  // A surface met next (within the snapshots' reach) is flagged as ever, its push read as it is.
  const Vec3 push(0.03, 0.0, 0.0);
  double flagged = -1.0;
  for (const double met = t; t < met + 0.5; t += dt) {
    const control::ContactState& s = e.update(last = rig.against(t, q_at(t), push, Vec3::Zero(), &rng));
    if (s.in_contact && flagged < 0.0) flagged = t - met;
  }
  ASSERT_GE(flagged, 0.0) << "a surface met after the graze was not flagged";
  EXPECT_LE(flagged, 0.1);
  EXPECT_LT((e.state().force - last.measured_rotation * push).norm(), 0.006) << e.state().force.transpose();
}

// A cycle with a non-finite input or model pose (a flow sensor's NaN, a solve gone wrong) is not
// remembered (its sample is compared with the last good pose): the estimate stays finite and, the
// cycles good again, reads a push as before.
TEST(ContactEstimator, ANonFiniteCycleLeavesTheEstimateFinite) {
  Rig rig;
  std::mt19937 rng(9);
  ContactEstimator e(ContactOptions(), 3, 0.15);
  const control::InputVector q = inputs(0.04, 0.02, 0.03);
  const double dt = 0.01;
  double t = 0.0;
  for (; t < 2.0; t += dt) e.update(rig.cycle(t, q, Vec3::Zero(), &rng));
  for (const double end = t + 0.5; t < end; t += dt) {
    ContactCycle c = rig.cycle(t, q, Vec3::Zero(), &rng);
    if (static_cast<int>(t / dt) % 2)
      c.inputs[1] = std::nan("");
    else
      c.model_rotation(0, 0) = std::numeric_limits<double>::infinity();
    const control::ContactState& s = e.update(c);
    ASSERT_TRUE(s.force.allFinite() && s.load.allFinite() && s.covariance.allFinite()) << "at t = " << t;
    EXPECT_FALSE(s.in_contact);
  }
  const Vec3 push(0.0, 0.03, 0.0);
  ContactCycle last;
  for (const double end = t + 1.0; t < end; t += dt) e.update(last = rig.against(t, q, push, Vec3::Zero(), &rng));
  ASSERT_TRUE(e.state().in_contact);
  EXPECT_LT((e.state().force - last.measured_rotation * push).norm(), 0.006) << e.state().force.transpose();
}

// A plant stiffer or softer than its model (bending ×1.25, ×0.8): a tip force that the jets take up
// (the pose held, as the law holds it) reads C_m⁻¹ C_plant times its size through the mismatch
// model learned in free space (0.8 or 1.25 of it). Given the inputs' wrenches, the estimator takes
// that ratio from its own mismatch model (reading_gain) and reports the force at its size, to 8 %
// (the linearisations' own error at these turns); the detector still compares the reading.
TEST(ContactEstimator, AForceTheJetsTakeUpIsReadAtItsSizeOnAStifferOrSofterPlant) {
  for (const double stiffness : {1.25, 0.8}) {
    Rig rig;
    rod::RodModel stiffer = rig.model.solver().model();
    for (rod::RodSegment& sg : stiffer.segments) sg.stiffness.head<2>() *= stiffness;
    rig.truth.set_model(stiffer);
    std::mt19937 rng(11);
    ContactEstimator e(ContactOptions(), 3, 0.15);
    auto q_at = [](double t) {
      return inputs(0.05 + 0.03 * std::sin(0.9 * t), 0.05 + 0.03 * std::sin(0.9 * t + 2.1),
                    0.05 + 0.03 * std::sin(0.9 * t + 4.2));
    };
    const double dt = 0.01;
    double t = 0.0;
    auto cycle = [&](const control::InputVector& q, const Vec3& force) {
      ContactCycle c = rig.cycle(t, q, force, &rng);
      c.input_wrenches = rig.model.linearise().wrenches;  // at q: cycle() solved the model there
      return c;
    };
    for (; t < 10.0; t += dt) ASSERT_FALSE(e.update(cycle(q_at(t), Vec3::Zero())).in_contact) << "at " << t;
    // A 25 mN push across the tip, taken up by the jets: the tip stays where q0 alone puts it.
    const control::InputVector q0 = q_at(t);
    rig.model.solve(q0);
    const Eigen::MatrixXd B = rig.model.linearise().wrenches.topRows<3>();
    const Vec3 push(0.015, -0.02, 0.0);
    const control::InputVector q = q0 - B.completeOrthogonalDecomposition().solve(push);
    for (const double end = t + 1.0; t < end; t += dt) e.update(cycle(q, push));
    const Mat3 tip = rig.truth.solve(q0).tip_rotation;
    const Vec3 truth = tip * push;
    const auto across = [&](const Vec3& v) { return Vec3(v - v.dot(tip.col(2)) * tip.col(2)); };
    std::printf("stiffness x%.2f: the estimate %.1f mN off a %.1f mN push\n", stiffness,
                1e3 * across(e.state().force - truth).norm(), 1e3 * push.norm());
    EXPECT_LT(across(e.state().force - truth).norm(), 0.08 * push.norm())
        << "stiffness x" << stiffness << ": estimate " << e.state().force.transpose() << ", truth "
        << truth.transpose();
  }
}

// The controller file's `contact:` group: the defaults, each key read, and bad values refused naming the key.
TEST(ContactOptions, TheGroupIsReadAndBadValuesNameTheirKey) {
  const config::ControllerNodeOptions o = config::parse_controller_options(
      YAML::Load("{contact: {force_threshold: 0.02, reaction: retreat, max_force: 0.08}}"));
  EXPECT_EQ(o.controller.contact.force_threshold, 0.02);
  EXPECT_EQ(o.controller.contact.reaction, control::ContactReaction::kRetreat);
  EXPECT_EQ(o.controller.contact.max_force, 0.08);
  const test::RefusedOptions refused[] = {
      {"{contact: {force_threshold: .nan}}", "contact/force_threshold", "must be finite"},
      {"{contact: {force_threshold: -0.01}}", "contact/force_threshold", "must lie in"},
      {"{contact: {max_force: 0.025}}", "contact/max_force", "at least 2.5 force_threshold"},
      {"{contact: {reaction: push}}", "contact/reaction", "'comply', 'hold', 'retreat'"},
      {"{contact: {force_treshold: 0.01}}", "contact/force_treshold", "unknown key"}};
  for (const auto& c : refused) test::expect_refused(c);
}
