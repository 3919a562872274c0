// Keep-out regions (control/keep_out.h) against the geometry of an independent solve: the model is
// steered to each clipped direction by its own inputs (a bounded Gauss–Newton on the jets, not the
// sweep the regions are fitted on), and the capsule there is measured against the surface.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include <yaml-cpp/yaml.h>

#include "hydrojet_control/actuation/bounded_allocation.h"
#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/control/keep_out.h"
#include "hydrojet_control/control/reference.h"
#include "hydrojet_control/rod/so3.h"
#include "controller_fixtures.h"
#include "test_helpers.h"

namespace hydrojet {
namespace {

using control::KeepOut;
using control::KeepOutRegion;
using control::Vec3;
using geometry::SurfaceType;

struct Robot {
  control::RobotModel model = config::make_controller_model(test::scene("hydrojet_0deg"), test::flow_gains());
  std::shared_ptr<const control::ReachableSet> set =
      std::make_shared<const control::ReachableSet>(control::ReachableSet::compute(model, {}));
};

const Robot& robot() {
  static const Robot r;
  return r;
}

/// The model's tip position at tip direction d, found by steering the model there: Gauss–Newton on the
/// jets within their bounds (each step a bounded least-squares of the direction's change per input).
bool steer_to(control::ActuatedModel& m, const Vec3& d, Vec3* position) {
  control::InputVector q = control::InputVector::Zero(m.input_count());
  for (int it = 0; it < 60; ++it) {
    const rod::RodSolution s = m.solve(q);
    if (!s.converged) return false;
    const Vec3 now = s.tip_rotation.col(2);
    *position = s.tip_position;
    if (control::geodesic_error(d, now) < 1e-8) return true;
    const control::ActuatedModel::Linearisation lin = m.linearise();
    Vec3 e1 = (d - d.dot(now) * now);
    if (e1.norm() < 1e-14) return true;
    e1.normalize();
    const Vec3 e2 = now.cross(e1);
    const Eigen::MatrixXd M = -so3::hat(now) * s.tip_rotation * lin.actuation.bottomRows<3>();
    actuation::InputMatrix S(2, m.input_count());
    S.row(0) = e1.transpose() * M;
    S.row(1) = e2.transpose() * M;
    actuation::AllocVector w(2);
    w << control::geodesic_error(d, now), 0.0;
    w += S * q;
    const actuation::BoundedAllocationResult a = actuation::allocate_bounded(S, w, m.lower(), m.upper(), 1e-12);
    if (!a.ok) return false;
    q = a.q;
  }
  return false;
}

KeepOutRegion plane(const Vec3& point, const Vec3& normal, double margin) {
  KeepOutRegion r;
  r.surface.type = SurfaceType::kPlane;
  r.surface.point = point;
  r.surface.normal = normal;
  r.margin = margin;
  return r;
}

/// A sphere (radii all alike) or an ellipsoid about `centre`.
KeepOutRegion body(SurfaceType type, const Vec3& centre, const Vec3& radii, double margin, bool inside = false) {
  KeepOutRegion r;
  r.surface.type = type;
  r.surface.point = centre;
  r.surface.radii = radii;
  r.surface.inside = inside;
  r.margin = margin;
  return r;
}

/// Directions of the set on a polar grid about its centre (inside it).
std::vector<Vec3> directions_in_set(const control::ReachableSet& set, int rings, int spokes) {
  const Vec3 c = set.center();
  Vec3 e1 = Vec3::UnitX() - c.x() * c;
  e1.normalize();
  const Vec3 e2 = c.cross(e1);
  std::vector<Vec3> out;
  for (int i = 1; i <= rings; ++i)
    for (int j = 0; j < spokes; ++j) {
      const double a = 1.2 * i / rings, phi = 2 * M_PI * j / spokes;
      const Vec3 d = std::cos(a) * c + std::sin(a) * (std::cos(phi) * e1 + std::sin(phi) * e2);
      if (set.contains(d)) out.push_back(d);
    }
  return out;
}

double geometric_clearance(const KeepOutRegion& r, const Vec3& p, double tip_radius) {
  return geometry::nearest_point(r.surface, p).distance - tip_radius - r.margin - KeepOut::kTrackingAllowance;
}

TEST(KeepOut, TheModelsTipPositionMatchesAnIndependentSolve) {
  const Robot& b = robot();
  const KeepOut k({}, b.model.rod.tip_radius, b.set);
  control::ActuatedModel m(b.model);
  double worst = 0.0, worst_inner = 0.0;
  int n = 0;
  for (const Vec3& d : directions_in_set(*b.set, 6, 12)) {
    Vec3 p;
    if (!steer_to(m, d, &p)) continue;
    const double error = (k.tip_position(d) - p).norm();
    worst = std::max(worst, error);
    if (control::geodesic_error(b.set->center(), d) <= 0.8) worst_inner = std::max(worst_inner, error);
    ++n;
  }
  EXPECT_GE(n, 50);
  // The grid's spacing (1.4°) against the rod's curvature of position per direction: ~0.1 mm. Toward
  // the rim the jets' common mode (which the direction does not fix: the sweep's inputs are the least
  // ones, the solve's others) moves the tip along the rod by up to ~0.5 mm.
  EXPECT_LT(worst_inner, 2e-4) << "within 0.8 rad of the centre, over " << n << " directions";
  EXPECT_LT(worst, 6e-4) << "over " << n << " directions";
}

TEST(KeepOut, ClipsTargetsOntoTheRegionsEdgeAndLeavesTheRestAlone) {
  const Robot& b = robot();
  const double r = b.model.rod.tip_radius;
  const std::vector<KeepOutRegion> regions = {plane({0.02, 0.0, 0.0}, {-1.0, 0.0, 0.0}, 0.002)};
  const KeepOut k(regions, r, b.set);
  control::ActuatedModel m(b.model);
  int clipped = 0, free = 0;
  for (const Vec3& d : directions_in_set(*b.set, 8, 16)) {
    double moved = -1.0;
    const Vec3 out = k.clip(d, &moved);
    Vec3 p_in, p_out;
    ASSERT_TRUE(steer_to(m, d, &p_in));
    ASSERT_TRUE(steer_to(m, out, &p_out));
    const double before = geometric_clearance(regions[0], p_in, r), after = geometric_clearance(regions[0], p_out, r);
    if (before > 3e-4) {  // clearly allowed: unchanged
      EXPECT_EQ(moved, 0.0);
      EXPECT_LT(control::geodesic_error(d, out), 1e-12);
      ++free;
    } else if (before < -3e-4) {  // clearly inside: onto the edge (to the fit's 0.6 mm at the rim)
      EXPECT_GT(moved, 0.0);
      EXPECT_NEAR(after, 0.0, 6e-4) << "target clearance " << before;
      EXPECT_TRUE(b.set->contains(out));
      ++clipped;
    }
  }
  EXPECT_GE(clipped, 10);
  EXPECT_GE(free, 10);
}

TEST(KeepOut, MovesATargetNoFurtherThanTheNearestAllowedDirection) {
  // Brute force: the nearest allowed direction among a fine polar grid of the set (checked by the
  // same clearance, so this tests the search, not the position map).
  const Robot& b = robot();
  const KeepOutRegion ball = body(SurfaceType::kSphere, {0.025, 0.01, 0.07}, Vec3::Constant(0.01), 0.002);
  const KeepOut k({ball, plane({0.0, -0.03, 0.0}, {0.0, 1.0, 0.0}, 0.003)}, b.model.rod.tip_radius, b.set);
  const std::vector<Vec3> fine = directions_in_set(*b.set, 120, 240);
  std::vector<Vec3> allowed;
  for (const Vec3& d : fine)
    if (k.allows(d)) allowed.push_back(d);
  ASSERT_GT(allowed.size(), 100u);
  int checked = 0;
  for (const Vec3& d : directions_in_set(*b.set, 10, 20)) {
    if (k.allows(d)) continue;
    double moved = 0.0;
    const Vec3 out = k.clip(d, &moved);
    EXPECT_GE(k.clearance(out), -1e-9);
    double nearest = M_PI;
    for (const Vec3& a : allowed) nearest = std::min(nearest, control::geodesic_error(d, a));
    // The grid's step about the brute force's: 1.2/120 rad in angle, and the chart's distortion.
    EXPECT_LE(moved, nearest * 1.05 + 0.011) << "moved " << moved << " nearest " << nearest;
    ++checked;
  }
  EXPECT_GE(checked, 5);
}

TEST(KeepOut, AStomachKeepsTheCapsuleInside) {
  // An ellipsoid lived in: allowed exactly where the capsule stays inside by the margin.
  const Robot& b = robot();
  const KeepOutRegion stomach = body(SurfaceType::kEllipsoid, {0.0, 0.0, 0.06}, {0.045, 0.06, 0.05}, 0.002, true);
  const KeepOut k({stomach}, b.model.rod.tip_radius, b.set);
  control::ActuatedModel m(b.model);
  int out_count = 0;
  for (const Vec3& d : directions_in_set(*b.set, 8, 16)) {
    const Vec3 kept = k.clip(d);
    Vec3 p;
    ASSERT_TRUE(steer_to(m, kept, &p));
    // Where the model, steered there by itself, puts the capsule: inside by the margin (to the fit's 0.6 mm).
    EXPECT_GE(geometric_clearance(stomach, p, b.model.rod.tip_radius), -6e-4) << d.transpose();
    out_count += !k.allows(d);
  }
  EXPECT_GT(out_count, 0);
}

TEST(KeepOut, RefusesBrokenRegionsNamingTheKey) {
  const Robot& b = robot();
  auto refused = [&](KeepOutRegion r, const std::string& key) {
    try {
      KeepOut k({plane({0.1, 0, 0}, {-1, 0, 0}, 0.0), r}, 0.007, b.set);
      ADD_FAILURE() << "accepted, expected " << key;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(key + ":", 0), 0u) << e.what();
    }
  };
  refused(plane({NAN, 0, 0}, {1, 0, 0}, 0.0), "keep_out[1]/point");
  refused(plane({0, 0, 0}, {0, 0, 0}, 0.0), "keep_out[1]/normal");
  refused(plane({0, 0, 0}, {1, 0, 0}, -0.001), "keep_out[1]/margin");
  refused(body(SurfaceType::kSphere, Vec3::Zero(), Vec3::Zero(), 0.002), "keep_out[1]/radius");
  // A region that holds every direction the robot reaches: refused, not a robot that cannot move.
  refused(body(SurfaceType::kSphere, {0, 0, 0.05}, Vec3::Constant(0.5), 0.002), "keep_out");
}

TEST(KeepOut, AReferenceFollowingAPathNeverEntersTheRegion) {
  const Robot& b = robot();
  const std::vector<KeepOutRegion> regions = {plane({0.015, 0.0, 0.0}, {-1.0, 0.0, 0.0}, 0.002)};
  auto k = std::make_shared<const KeepOut>(regions, b.model.rod.tip_radius, b.set);
  control::Reference ref(0.25, b.set, b.set);
  ref.set_keep_out(k);
  control::PathOptions spiral;
  spiral.theta_end = 0.9;
  spiral.phi_end = 14.0;
  spiral.duration = 60.0;
  ref.follow(std::shared_ptr<const control::Path>(control::make_spiral(spiral)), 0.0,
             control::Reference::PathStart::kJump);
  ref.start(b.set->center(), 0.0);
  int kept = 0;
  double t = 0.0;
  for (int i = 0; i < 6000; ++i, t += 0.01) {
    const Vec3& d = ref.advance(t, 0.01, control::Mat3::Identity());
    EXPECT_GE(k->clearance(d), -1e-9) << "t " << t;
    kept += ref.kept_out();
  }
  EXPECT_GT(kept, 500);  // the spiral's outer turns cross the plane
}

// A fixed target beyond a ball: the reference, moving at its rate limit, stops at the ball's edge
// rather than crossing it (going round is the operator's: the reference takes the shortest way);
// with an offset (the plant's tip off the model's) the edge moves with it. A region set after the
// target clips it at once.
TEST(KeepOut, TheMovingReferenceSlidesAlongTheEdge) {
  const Robot& b = robot();
  KeepOutRegion ball = body(SurfaceType::kSphere, Vec3::Zero(), Vec3::Constant(0.008), 0.002);
  const Vec3 c = b.set->center();
  const Vec3 start = (c + 0.5 * Vec3::UnitY()).normalized(), goal = (c - 0.5 * Vec3::UnitY()).normalized();
  const KeepOut probe({}, b.model.rod.tip_radius, b.set);
  ball.surface.point = probe.tip_position((c + 0.05 * Vec3::UnitX()).normalized());  // on the way, a little aside
  auto k = std::make_shared<const KeepOut>(std::vector<KeepOutRegion>{ball}, b.model.rod.tip_radius, b.set);
  for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(0.002, -0.001, 0.0)}) {
    control::Reference ref(0.25, b.set, b.set);
    ref.set_keep_out(k);
    ref.set_keep_out_offset(offset);
    ref.start(start, 0.0);
    ASSERT_TRUE(ref.aim(goal, control::Source::kDirection));
    double t = 0.0;
    int slid = 0;
    for (int i = 0; i < 1500; ++i, t += 0.01) {
      const Vec3& d = ref.advance(t, 0.01, control::Mat3::Identity());
      ASSERT_GE(k->clearance(d, offset), -1e-6) << "entered the ball at t " << t;
      slid += ref.kept_out();
    }
    EXPECT_GT(slid, 10);
    EXPECT_LT(k->clearance(ref.direction(), offset), 1e-4) << "not at the edge";
  }
  control::Reference late(0.25, b.set, b.set);
  late.start(start, 0.0);
  ASSERT_TRUE(late.aim(c, control::Source::kDirection));
  late.set_keep_out(k);
  double t = 0.0;
  for (int i = 0; i < 600; ++i, t += 0.01)
    ASSERT_GE(k->clearance(late.advance(t, 0.01, control::Mat3::Identity())), -1e-6);
  EXPECT_GT(control::geodesic_error(late.direction(), c), 0.01);
}

TEST(KeepOut, TheControllerFileReadsItAndNamesBrokenKeys) {
  const config::ControllerNodeOptions o = config::parse_controller_options(
      YAML::Load("keep_out:\n"
                 "  - {type: plane, point: [0.02, 0, 0], normal: [-1, 0, 0], margin: 0.003}\n"
                 "  - {type: ellipsoid, centre: [0, 0, 0.06], radii: [0.05, 0.06, 0.05], inside: true}\n"));
  ASSERT_EQ(o.controller.keep_out.size(), 2u);
  EXPECT_EQ(o.controller.keep_out[0].margin, 0.003);
  EXPECT_EQ(o.controller.keep_out[1].margin, 0.002);
  EXPECT_TRUE(o.controller.keep_out[1].surface.inside);
  for (const test::RefusedOptions& c : std::vector<test::RefusedOptions>{
           {"keep_out: {type: plane}", "keep_out", "list"},
           {"keep_out: [{type: cube}]", "keep_out[0]/type", "plane, sphere or ellipsoid"},
           {"keep_out: [{type: plane, point: [0, 0, 0], normal: [0, 0, 0]}]", "keep_out[0]/normal", "not zero"},
           {"keep_out: [{type: sphere, centre: [0, 0, 0.1], radius: -1}]", "keep_out[0]/radius", "> 0"},
           {"keep_out: [{type: plane, point: [0, 0, 0], normal: [1, 0, 0], margin: .nan}]", "keep_out[0]/margin", ""},
           {"keep_out: [{type: plane, point: [0, 0, 0], normal: [1, 0, 0], stiffness: 3}]", "keep_out[0]/stiffness",
            "unknown key"}})
    test::expect_refused(c);
}

}  // namespace
}  // namespace hydrojet
