// The calibration's parameter vector ζ (calibration/zeta.h): the paper's form (Table 1's moduli from
// a scene and back, the cross-section read from scene text, the parameter list) and the general
// form of any robot (its names, the scene at other values, the tip mount split off the rod).
#include <gtest/gtest.h>

#include <stdexcept>

#include "hydrojet_control/calibration/zeta.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"
#include "calibration_fixtures.h"

namespace {

using namespace hydrojet;
using namespace hydrojet::calibration;
using test::kI;
using test::shipped;
using test::truth_zeta;

TEST(Zeta, Table1ModuliAndRoundTrip) {
  const config::Scene s = shipped("hydrojet_0deg");
  const CrossSection cs;  // 8 mm / 6 mm
  EXPECT_NEAR(cs.second_moment(), kI, 1e-25);
  const Zeta zeta(s, cs);
  ASSERT_TRUE(zeta.paper_form());
  EXPECT_EQ(zeta.names(), "ux, uy, E, G, da, db, dg");
  const ZetaVector& z = zeta.start();
  EXPECT_NEAR(z[kE], 6.01e-4 / kI, 1e-6 * z[kE]);  // ≈ 4.37 MPa
  EXPECT_NEAR(z[kG], 2.23e-4 / (2 * kI), 1e-6 * z[kG]);
  EXPECT_EQ(z[kUx], 0.034);
  EXPECT_EQ(z[kUy], 0.88);
  EXPECT_EQ(z[kDa], 0.12);
  EXPECT_EQ(z[kDg], -0.08);
  const ZetaVector t = truth_zeta();
  const config::Scene a = zeta.apply(t);
  EXPECT_LT((Zeta(a, cs).start() - t).cwiseQuotient(t.cwiseAbs().cwiseMax(1.0)).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_EQ(a.rod.segments[0].precurvature.z(), s.rod.segments[0].precurvature.z());
  EXPECT_EQ(a.rod.tip_mass, s.rod.tip_mass);
  // The jets follow their misalignments (eq. 24): jet 1 at 30° + δβ in the tip xy-plane.
  const double a1 = M_PI / 6 + t[kDb];
  EXPECT_NEAR((a.rod.actuators[0].direction - Eigen::Vector3d(std::cos(a1), std::sin(a1), 0)).norm(), 0.0, 1e-15);
}

TEST(Zeta, CrossSectionFromSceneTextAndParamList) {
  const CrossSection fb;
  CrossSection cs = cross_section_from_scene_text("rod: {length: 0.09, bending_stiffness: [1, 1]}\n", fb);
  EXPECT_EQ(cs.outer_diameter, 0.008);
  cs = cross_section_from_scene_text("rod: {outer_diameter: 0.01, inner_diameter: 0.0}\n", fb);
  EXPECT_EQ(cs.outer_diameter, 0.01);
  EXPECT_EQ(cs.inner_diameter, 0.0);
  EXPECT_THROW(cross_section_from_scene_text("rod: {outer_diameter: 0.005, inner_diameter: 0.006}\n", fb),
               config::SceneError);
  const Zeta zeta(shipped("hydrojet_0deg"), fb);
  const ParamMask m = zeta.parse("ux, E,dg");
  EXPECT_TRUE(m[kUx] && m[kE] && m[kDg]);
  EXPECT_FALSE(m[kUy] || m[kG] || m[kDa] || m[kDb]);
  EXPECT_THROW(zeta.parse("ux,EI"), std::invalid_argument);
  EXPECT_THROW(zeta.parse("ux,ux"), std::invalid_argument);
  EXPECT_THROW(zeta.parse(""), std::invalid_argument);
  EXPECT_EQ(zeta.default_fit(), ParamMask(kNumParams, true));
}

TEST(Zeta, GeneralFormOfTheTwoSegmentRobot) {
  const config::Scene s = shipped("two_segment_thrusters");
  const Zeta zeta(s, CrossSection());
  EXPECT_FALSE(zeta.paper_form());
  EXPECT_EQ(zeta.names(), "ux1, uy1, bend1, ux2, uy2, bend2, bend, twist, da, db, dg");
  // The four tip thrusters ride the mount; the two mid-body ones stay on the rod.
  EXPECT_EQ(zeta.mount_inputs(), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(zeta.body_inputs(), (std::vector<int>{4, 5}));
  // Default: per-segment scales (not the common one); twist, because tip_ny_arm twists the tip.
  const ParamMask d = zeta.default_fit();
  EXPECT_FALSE(d[zeta.index("bend")]);
  EXPECT_TRUE(d[zeta.index("bend1")] && d[zeta.index("bend2")] && d[zeta.index("twist")]);
  EXPECT_THROW(zeta.parse("bend,bend2"), std::invalid_argument);
  const ParamMask c = zeta.with_common_bending_scale(d);
  EXPECT_TRUE(c[zeta.index("bend")] && !c[zeta.index("bend1")] && !c[zeta.index("bend2")]);
  // Precurvature resolution: 0.045 rad of unloaded tilt over each segment's length.
  EXPECT_NEAR(zeta[zeta.index("ux1")].resolution, 0.045 / 0.05, 1e-12);
  EXPECT_NEAR(zeta[zeta.index("uy2")].resolution, 0.045 / 0.04, 1e-12);

  // Start: the scene's precurvatures, scales 1, mount 0.
  const ZetaVector& z0 = zeta.start();
  EXPECT_EQ(z0[zeta.index("uy2")], 2.0);
  EXPECT_EQ(z0[zeta.index("bend1")], 1.0);
  EXPECT_EQ(z0[zeta.index("dg")], 0.0);

  ZetaVector z = z0;
  z[zeta.index("ux1")] = 0.3, z[zeta.index("bend1")] = 0.8, z[zeta.index("bend")] = 1.5;
  z[zeta.index("twist")] = 1.2, z[zeta.index("dg")] = 0.1;
  const config::Scene a = zeta.apply(z);
  EXPECT_EQ(a.rod.segments[0].precurvature.x(), 0.3);
  EXPECT_NEAR(a.rod.segments[0].stiffness.x(), 1.5e-3 * 0.8 * 1.5, 1e-18);
  EXPECT_NEAR(a.rod.segments[1].stiffness.y(), 4.0e-4 * 1.5, 1e-18);
  EXPECT_NEAR(a.rod.segments[1].stiffness.z(), 3.1e-4 * 1.2, 1e-18);
  // The mount turns about the tip z axis: tip_px now points at 0.1 rad; tip_ny_arm's arm turns too.
  EXPECT_NEAR((a.rod.actuators[0].direction - Eigen::Vector3d(std::cos(0.1), std::sin(0.1), 0)).norm(), 0, 1e-15);
  EXPECT_NEAR((a.rod.actuators[3].position - 0.004 * Eigen::Vector3d(std::cos(0.1), std::sin(0.1), 0)).norm(), 0,
              1e-15);
  EXPECT_EQ(a.rod.actuators[4].direction, s.rod.actuators[4].direction);  // mid-body: not on the mount
}

/// The fit's split (rod without the mount + the mount's tip wrench) is the scene at ζ: same tip.
TEST(Zeta, MountSplitSolvesAsTheWholeScene) {
  for (const char* name : {"two_segment_thrusters", "hydrojet_30deg"}) {
    SCOPED_TRACE(name);
    const config::Scene s = shipped(name);
    const Zeta zeta(s, CrossSection());
    ZetaVector z = zeta.start();
    for (int i = 0; i < zeta.size(); ++i)
      z[i] = zeta[i].kind == ParamKind::kMount ? z[i] + 0.05 * (i % 3 + 1) : z[i] * (1.0 + 0.1 * ((i % 2) ? 1 : -1));
    const config::Scene whole = zeta.apply(z);
    rod::InputVector q(whole.rod.input_count());
    for (int i = 0; i < q.size(); ++i) q[i] = 0.4 * whole.rod.actuators[i].max_force * (i + 1) / q.size();
    rod::RodSolver a(whole.rod, whole.solver);
    const rod::RodSolution sa = a.solve(q);
    ASSERT_TRUE(sa.converged);

    rod::InputVector q_body(static_cast<Eigen::Index>(zeta.body_inputs().size()));
    Eigen::VectorXd q_mount(zeta.mount_inputs().size());
    for (size_t k = 0; k < zeta.body_inputs().size(); ++k) q_body[k] = q[zeta.body_inputs()[k]];
    for (size_t k = 0; k < zeta.mount_inputs().size(); ++k) q_mount[k] = q[zeta.mount_inputs()[k]];
    Eigen::Vector3d delta;
    for (int k = 0; k < 3; ++k) delta[k] = z[zeta.index(std::string("d") + "abg"[k])];
    const rod::Vec6 w = zeta.mount_wrenches(delta) * q_mount;
    rod::TipWrench tw;
    tw.force = w.head<3>(), tw.moment = w.tail<3>();
    rod::RodSolver b(zeta.rod_without_mount(z), whole.solver);
    const rod::RodSolution sb = b.solve(q_body, tw);
    ASSERT_TRUE(sb.converged);
    EXPECT_LT(so3::log(sa.tip_rotation.transpose() * sb.tip_rotation).norm(), 1e-9);
    EXPECT_LT((sa.tip_position - sb.tip_position).norm(), 1e-11);
  }
}

TEST(Zeta, SceneWithoutActuatorsIsRefused) {
  const config::Scene s = config::parse_scene(
      "rod: {length: 0.09, bending_stiffness: [6e-4, 6e-4], torsional_stiffness: 2e-4}\n"
      "tip: {mass: 0.0}\ngravity: [0, 0, 9.81]\n");
  EXPECT_THROW(Zeta(s, CrossSection()), config::SceneError);
}

}  // namespace
