// What the simulated tip meets (plant/environment.h) against independent truths: the penalty force
// of the capsule pressed into a plane, into a sphere and into an ellipsoid from inside against their
// closed forms, the ellipsoid's nearest point against a dense sampling of its surface, friction
// against Coulomb's law, the plant file's surfaces and loads with their errors naming the key, and
// the plant held against a wall by a known load against the static balance of the rod's compliance
// (measured by a second run without the wall) in series with the wall's.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/plant/environment.h"
#include "hydrojet_control/plant/plant.h"
#include "hydrojet_control/sim/closed_loop_run.h"

namespace {

using Eigen::Vector3d;
using hydrojet::plant::contact;
using hydrojet::plant::Environment;
using hydrojet::plant::nearest_point;
using hydrojet::plant::Surface;
using hydrojet::plant::SurfaceType;

Environment one(const Surface& s, double tip_radius = 0.007) {
  Environment e;
  e.tip_radius = tip_radius;
  e.surfaces.push_back(s);
  return e;
}

// A sphere of radius r at height h < r above a plane: F = k (r − h) n, at the foot of the centre.
TEST(Environment, ASpherePressedIntoAPlaneMeetsTheClosedForm) {
  Surface wall;
  wall.point = Vector3d(0.01, -0.02, 0.03);
  wall.normal = Vector3d(1, 2, 2) / 3.0;
  wall.stiffness = 2500.0;
  const double r = 0.007, h = 0.005;
  const Vector3d p = wall.point + Vector3d(0.004, 0.004, -0.006) + h * wall.normal;  // (the offset lies in the plane)
  ASSERT_NEAR(Vector3d(0.004, 0.004, -0.006).dot(wall.normal), 0.0, 1e-15);
  const auto c = contact(one(wall, r), p, Vector3d::Zero());
  EXPECT_TRUE(c.touching);
  EXPECT_NEAR(c.normal_force, 2500.0 * (r - h), 1e-12);
  EXPECT_LT((c.force - 2500.0 * (r - h) * wall.normal).norm(), 1e-12);
  EXPECT_LT((c.point - (p - h * wall.normal)).norm(), 1e-12);
  EXPECT_NEAR(c.clearance, h - r, 1e-12);
  // Clear of it: no force, the clearance the gap.
  const auto free = contact(one(wall, r), p + 0.01 * wall.normal, Vector3d::Zero());
  EXPECT_FALSE(free.touching);
  EXPECT_EQ(free.force, Vector3d::Zero());
  EXPECT_NEAR(free.clearance, h + 0.01 - r, 1e-12);
}

// Damping opposes the approach (never pulls); friction is μ F_n against the sliding velocity once
// it is well above the regularisation speed.
TEST(Environment, DampingNeverPullsAndFrictionIsCoulombs) {
  Surface wall;
  wall.stiffness = 1000.0;
  wall.damping = 2.0;
  wall.friction = 0.4;
  const Vector3d p(0, 0, 0.006);  // 1 mm in
  const auto approaching = contact(one(wall), p, Vector3d(0, 0, -0.01));
  EXPECT_NEAR(approaching.normal_force, 1000.0 * 0.001 + 2.0 * 0.01, 1e-12);
  const auto leaving_fast = contact(one(wall), p, Vector3d(0, 0, 1.0));
  EXPECT_EQ(leaving_fast.normal_force, 0.0);  // k δ − c v_n < 0: no force, not a pull
  const auto sliding = contact(one(wall), p, Vector3d(0.3, 0.4, 0.0));
  EXPECT_NEAR(sliding.force.z(), 1.0, 1e-12);
  const Vector3d tangential = sliding.force - sliding.force.z() * Vector3d::UnitZ();
  EXPECT_NEAR(tangential.norm(), 0.4 * 1.0, 0.4 * 1e-5);  // |v_t| = 0.5 m/s ≫ 1e-3 m/s
  EXPECT_NEAR(tangential.normalized().dot(Vector3d(-0.6, -0.8, 0)), 1.0, 1e-12);
}

// Inside a sphere of radius R at ρ from its centre: F = k (r − (R − ρ)) toward the centre; outside a
// sphere the same with the gap ρ − R, away from it.
TEST(Environment, ASphereInsideAndOutside) {
  Surface ball;
  ball.type = SurfaceType::kSphere;
  ball.point = Vector3d(0.0, 0.0, 0.08);
  ball.radii = Vector3d::Constant(0.03);
  ball.stiffness = 800.0;
  ball.inside = true;
  const Vector3d dir = Vector3d(2, -1, 2) / 3.0;
  const auto in = contact(one(ball), ball.point + 0.025 * dir, Vector3d::Zero());
  EXPECT_NEAR(in.normal_force, 800.0 * (0.007 - 0.005), 1e-12);
  EXPECT_LT((in.normal + dir).norm(), 1e-12);
  ball.inside = false;
  const auto out = contact(one(ball), ball.point + 0.034 * dir, Vector3d::Zero());
  EXPECT_NEAR(out.normal_force, 800.0 * (0.007 - 0.004), 1e-12);
  EXPECT_LT((out.normal - dir).norm(), 1e-12);
}

// From inside an ellipsoid on its longest axis near the vertex (x > a − c²/a), the nearest point is
// the vertex: the gap is a − x and the force points back along the axis.
TEST(Environment, AnEllipsoidFromInsideMeetsTheClosedFormOnItsAxis) {
  Surface stomach;
  stomach.type = SurfaceType::kEllipsoid;
  stomach.point = Vector3d(0.001, 0.002, 0.06);
  stomach.radii = Vector3d(0.05, 0.04, 0.03);
  stomach.inside = true;
  stomach.stiffness = 300.0;
  const double x = 0.045;  // > 0.05 − 0.03² / 0.05 = 0.032
  const auto c = contact(one(stomach), stomach.point + Vector3d(x, 0, 0), Vector3d::Zero());
  EXPECT_NEAR(c.normal_force, 300.0 * (0.007 - (0.05 - x)), 1e-9);
  EXPECT_LT((c.normal + Vector3d::UnitX()).norm(), 1e-9);
  EXPECT_LT((c.point - (stomach.point + Vector3d(0.05, 0, 0))).norm(), 1e-9);
}

// Anywhere, inside or out (the centre and an axis too, with two semi-axes equal), the nearest point against the least
// distance to 400 × 800 points of the surface (the sampling's spacing, ~0.4 mm, bounds the error of the sampled
// distance).
TEST(Environment, TheEllipsoidsNearestPointAgreesWithADenseSampling) {
  Surface e;
  e.type = SurfaceType::kEllipsoid;
  const std::pair<Vector3d, Vector3d> cases[] = {
      {Vector3d(0.05, 0.035, 0.02), Vector3d(0.01, 0.005, 0.002)},
      {Vector3d(0.05, 0.035, 0.02), Vector3d(-0.03, 0.02, -0.01)},
      {Vector3d(0.05, 0.035, 0.02), Vector3d(0.06, 0.03, 0.02)},
      {Vector3d(0.05, 0.035, 0.02), Vector3d(0.0, 0.0, 0.0)},
      {Vector3d(0.05, 0.035, 0.02), Vector3d(0.0, 0.03, 0.0)},
      {Vector3d(0.05, 0.035, 0.02), Vector3d(-0.02, -0.04, 0.03)},
      {Vector3d(0.05, 0.035, 0.02), Vector3d(0.049, 0.0, 0.001)},
      {Vector3d(0.05, 0.02, 0.02), Vector3d(0.0, 0.0, 0.0)},
      {Vector3d(0.05, 0.02, 0.02), Vector3d(0.01, 0.0, 0.0)},
      {Vector3d(0.05, 0.02, 0.02), Vector3d(0.01, 1e-9, 2e-9)},
  };
  for (const auto& [radii, p] : cases) {
    e.radii = radii;
    double best = 1e9;
    for (int i = 0; i <= 400; ++i) {
      const double th = M_PI * i / 400;
      for (int j = 0; j < 800; ++j) {
        const double ph = 2 * M_PI * j / 800;
        const Vector3d s(e.radii.x() * std::sin(th) * std::cos(ph), e.radii.y() * std::sin(th) * std::sin(ph),
                         e.radii.z() * std::cos(th));
        best = std::min(best, (s - p).norm());
      }
    }
    const auto sp = nearest_point(e, p);
    const bool outside = p.cwiseQuotient(e.radii).squaredNorm() > 1.0;
    EXPECT_NEAR(std::abs(sp.distance), best, 4e-4) << p.transpose();
    EXPECT_LE(std::abs(sp.distance), best + 1e-12) << p.transpose();  // no sampled point is nearer
    EXPECT_EQ(sp.distance > 0.0, outside) << p.transpose();
    EXPECT_NEAR(sp.point.cwiseQuotient(e.radii).squaredNorm(), 1.0, 1e-9) << p.transpose();  // on the surface
    EXPECT_NEAR((sp.point - p).norm(), std::abs(sp.distance), 1e-12) << p.transpose();
  }
}

TEST(Environment, ABrokenSurfaceOrLoadIsRefusedNamingTheKey) {
  const auto scene =
      hydrojet::config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/hydrojet_0deg.yaml");
  auto error_of = [&](const std::string& yaml) {
    try {
      hydrojet::config::make_plant(scene, yaml);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error_of("plant: {environment: {surfaces: [{type: plane, point: [0, 0, 0.1], normal: [0, 0, -1], "
                     "stiffness: 1000}]}, external_loads: [{start: 5, force: [0.01, 0, 0], frame: base}]}"),
            "");
  const std::pair<const char*, const char*> bad[] = {
      {"plant: {environment: {surfaces: [{type: plane, point: [0, 0, 0.1], normal: [0, 0, 0]}]}}",
       "plant.environment.surfaces[0].normal"},
      {"plant: {environment: {surfaces: [{type: plane, point: [0, .nan, 0.1], normal: [0, 0, 1]}]}}",
       "plant.environment.surfaces[0].point"},
      {"plant: {environment: {surfaces: [{type: sphere, centre: [0, 0, 0], radius: 0}]}}",
       "plant.environment.surfaces[0].radius"},
      {"plant: {environment: {surfaces: [{type: ellipsoid, centre: [0, 0, 0], radii: [0.1, -0.1, 0.1]}]}}",
       "plant.environment.surfaces[0].radii"},
      {"plant: {environment: {surfaces: [{type: plane, point: [0, 0, 0], normal: [0, 0, 1], stiffness: -5}]}}",
       "plant.environment.surfaces[0].stiffness"},
      {"plant: {environment: {surfaces: [{type: cube}]}}", "plant.environment.surfaces[0].type"},
      {"plant: {environment: {surfaces: [{type: plane, point: [0, 0, 0], normal: [0, 0, 1], radius: 1}]}}",
       "plant.environment.surfaces[0].radius"},
      {"plant: {environment: {tip_radius: -0.01}}", "plant.environment.tip_radius"},
      {"plant: {external_loads: [{start: 5, end: 2}]}", "plant.external_loads[0].end"},
      {"plant: {external_loads: [{force: [0, 0, .inf]}]}", "plant.external_loads[0].force"},
      {"plant: {external_loads: [{frame: world}]}", "plant.external_loads[0].frame"},
  };
  for (const auto& [yaml, key] : bad) {
    const std::string e = error_of(yaml);
    EXPECT_NE(e.find(key), std::string::npos) << yaml << " -> " << e;
  }
}

/// The shipped scene's plant, sensors exact, jets off, with the text added to its plant section.
hydrojet::plant::Plant quiet_plant(const std::string& extra) {
  const auto scene =
      hydrojet::config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/hydrojet_0deg.yaml");
  auto model = hydrojet::config::make_plant(scene, "plant: {sensor_noise: false" + extra + "}");
  return hydrojet::plant::Plant(model, 1);
}

// A lateral load F on the tip pushes it toward a wall a gap g away. Without the wall it moves x = C F
// (C measured by that run); with a wall of stiffness k the wall takes (C F − g) / (C + 1/k) at rest:
// the rod's compliance in series with the wall's. Stiff walls are stepped in substeps: no failure,
// no ringing left after 2 s.
TEST(Environment, APlantHeldAgainstAWallByALoadBalancesTheRodsCompliance) {
  hydrojet::plant::Plant free = quiet_plant("");
  ASSERT_TRUE(free.reset()) << free.error();
  const Vector3d p0 = free.tip_position();
  const double F = 0.02, g = 0.001, r = 0.007;
  char load[160];
  std::snprintf(load, sizeof(load), ", external_loads: [{force: [%g, 0, 0], frame: base}]", F);
  hydrojet::plant::Plant pushed = quiet_plant(load);
  ASSERT_TRUE(pushed.reset());
  ASSERT_TRUE(pushed.advance_to(3.0)) << pushed.error();
  const double C = (pushed.tip_position().x() - p0.x()) / F;
  ASSERT_GT(C * F, 2 * g);  // the load alone would carry the capsule past the wall
  for (double k : {100.0, 1000.0, 10000.0}) {
    char env[320];
    std::snprintf(env, sizeof(env),
                  ", environment: {tip_radius: %g, surfaces: [{type: plane, point: [%.9g, 0, 0], normal: [-1, 0, 0], "
                  "stiffness: %g, damping: 0.5}]}%s",
                  r, p0.x() + r + g, k, load);
    hydrojet::plant::Plant walled = quiet_plant(env);
    ASSERT_TRUE(walled.reset());
    ASSERT_TRUE(walled.advance_to(3.0)) << walled.error();
    const double expected = (C * F - g) / (C + 1.0 / k);
    std::printf("wall %g N/m: normal force %.5f N, expected %.5f N; clearance %.2e m\n", k,
                walled.contact().normal_force, expected, walled.contact().clearance);
    EXPECT_TRUE(walled.contact().touching);
    EXPECT_NEAR(walled.contact().normal_force, expected, 0.05 * expected) << k;
    EXPECT_NEAR(walled.contact().clearance, -expected / k, 0.05 * expected / k + 1e-6) << k;
    EXPECT_NEAR(walled.external_force().x() - F, -walled.contact().normal_force, 1e-12) << k;
  }
}

// The experiment's contact figures on a scripted run whose answers are counted by hand: quiet to
// 1 s, a contact from 1.00 s (0.01 N, then 0.05 N from 1.01 s, 0.08 N over 1.20-1.39 s, 0.04 N from
// 1.40 s) to 2.00 s; the flag up over 1.10-2.19 s and again over 3.00-3.49 s with nothing there; the
// estimate 5 mN off throughout.
TEST(Environment, TheContactFiguresOfAScriptedRun) {
  std::vector<hydrojet::sim::RunSample> run;
  for (int k = 0; k < 400; ++k) {
    hydrojet::sim::RunSample s;
    s.t = 0.01 * k;
    const double t = s.t + 1e-9;
    s.contact_force = t < 1.0 || t >= 2.0     ? 0.0
                      : t < 1.01              ? 0.01
                      : (t >= 1.2 && t < 1.4) ? 0.08
                      : t < 1.2               ? 0.05
                                              : 0.04;
    s.clearance = s.contact_force > 0 ? -s.contact_force / 1000.0 : 0.002;
    s.contact_flag = (t >= 1.1 && t < 2.2) || (t >= 3.0 && t < 3.5);
    s.external_force = Vector3d(s.contact_force, 0, 0);
    s.external_force_estimate = s.external_force + Vector3d(0.003, 0.004, 0.0);
    run.push_back(s);
  }
  const auto c = hydrojet::sim::summarise_contact(run, 0.01);
  EXPECT_EQ(c.onsets, 1);
  EXPECT_NEAR(c.detection_delay_s, 1.10 - 1.01, 1e-9);
  EXPECT_NEAR(c.missed_contact_s, 0.09, 1e-9);  // 1.01 ... 1.09
  EXPECT_NEAR(c.false_contact_s, 0.50, 1e-9);   // 3.00 ... 3.49 (quiet since 2.00)
  EXPECT_DOUBLE_EQ(c.max_contact_force_n, 0.08);
  EXPECT_DOUBLE_EQ(c.max_contact_force_after_detection_n, 0.04);  // from 1.40 s
  EXPECT_NEAR(c.external_force_rms_error_n, 0.005, 1e-12);
  EXPECT_DOUBLE_EQ(c.min_clearance_m, -0.08 / 1000.0);
  // The flag up before the contact (from 0.95 s): detected at once, the window from 1.30 s holds 0.08 N.
  for (auto& s : run) s.contact_flag = s.contact_flag || (s.t + 1e-9 >= 0.95 && s.t + 1e-9 < 1.1);
  const auto early = hydrojet::sim::summarise_contact(run, 0.01);
  EXPECT_NEAR(early.detection_delay_s, 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(early.max_contact_force_after_detection_n, 0.08);
  EXPECT_NEAR(early.missed_contact_s, 0.0, 1e-12);
  // A tap under the onset's 0.02 N that bounces off (1.00 s, gone over 1.01-1.05 s) before the
  // contact proper (0.05 N from 1.06 s): one onset, at 1.06 s (the tap does not disarm it).
  std::vector<hydrojet::sim::RunSample> tapped = run;
  for (auto& s : tapped) {
    const double t = s.t + 1e-9;
    if (t >= 1.01 && t < 1.06) s.contact_force = 0.0;
    s.contact_flag = t >= 1.16 && t < 2.2;
  }
  const auto tap = hydrojet::sim::summarise_contact(tapped, 0.01);
  EXPECT_EQ(tap.onsets, 1);
  EXPECT_NEAR(tap.detection_delay_s, 1.16 - 1.06, 1e-9);
  // No contact at all: no onset, nothing detected; the flag never up, nothing missed or false.
  for (auto& s : run) s.contact_force = 0.0, s.contact_flag = false;
  const auto none = hydrojet::sim::summarise_contact(run, 0.01);
  EXPECT_EQ(none.onsets, 0);
  EXPECT_TRUE(std::isnan(none.detection_delay_s));
  EXPECT_TRUE(std::isnan(none.max_contact_force_after_detection_n));
  EXPECT_EQ(none.missed_contact_s + none.false_contact_s, 0.0);
}

}  // namespace
