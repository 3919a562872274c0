// The calibration's parameter vector ζ (calibration/zeta.h): Table 1's moduli from a scene and back,
// the cross-section read from scene text, and the parameter list.
#include <gtest/gtest.h>

#include <stdexcept>

#include "hydrojet_control/calibration/zeta.h"
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
  const ZetaVector z = zeta_from_scene(s, cs);
  EXPECT_NEAR(z[kE], 6.01e-4 / kI, 1e-6 * z[kE]);  // ≈ 4.37 MPa
  EXPECT_NEAR(z[kG], 2.23e-4 / (2 * kI), 1e-6 * z[kG]);
  EXPECT_EQ(z[kUx], 0.034);
  EXPECT_EQ(z[kUy], 0.88);
  EXPECT_EQ(z[kDa], 0.12);
  EXPECT_EQ(z[kDg], -0.08);
  const ZetaVector t = truth_zeta();
  const config::Scene a = apply_zeta(s, t, cs);
  EXPECT_LT((zeta_from_scene(a, cs) - t).cwiseQuotient(t.cwiseAbs().cwiseMax(1.0)).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_EQ(a.rod.segments[0].precurvature.z(), s.rod.segments[0].precurvature.z());
  EXPECT_EQ(a.rod.tip_mass, s.rod.tip_mass);
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
  const ParamMask m = parse_param_list("ux, E,dg");
  EXPECT_TRUE(m[kUx] && m[kE] && m[kDg]);
  EXPECT_FALSE(m[kUy] || m[kG] || m[kDa] || m[kDb]);
  EXPECT_THROW(parse_param_list("ux,EI"), std::invalid_argument);
  EXPECT_THROW(parse_param_list("ux,ux"), std::invalid_argument);
  EXPECT_THROW(parse_param_list(""), std::invalid_argument);
}

}  // namespace
