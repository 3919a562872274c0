#include "hydrojet_control/control/modal_model.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <vector>

namespace hydrojet {
namespace control {
namespace {

using rod::Vec3;

/// The backbone (samples + 1 points) at the equilibrium under q and w; false when the solve fails.
bool solve_shape(rod::RodSolver& s, const rod::InputVector& q, const rod::TipWrench& w, int samples,
                 std::vector<Vec3>* backbone) {
  if (!s.solve(q, w).converged) return false;
  *backbone = s.shape(samples);
  return static_cast<int>(backbone->size()) == samples + 1;
}

/// ρA at arc length s [kg/m].
double density_at(const rod::RodModel& m, double s) {
  double end = 0.0;
  for (const rod::RodSegment& g : m.segments) {
    end += g.length;
    if (s <= end) return g.linear_density;
  }
  return m.segments.back().linear_density;
}

/// The backbone's displacement per unit force at arc length s (linear between the samples).
Eigen::Matrix<double, 3, 2> shape_at(const std::vector<Eigen::Matrix<double, 3, 2>>& phi, double s, double L) {
  const int K = static_cast<int>(phi.size()) - 1;
  const double x = std::clamp(s / L * K, 0.0, static_cast<double>(K));
  const int k = std::min(static_cast<int>(x), K - 1);
  const double f = x - k;
  return (1.0 - f) * phi[k] + f * phi[k + 1];
}

ModalModel failed(const std::string& why) {
  ModalModel m;
  m.error = why;
  return m;
}

/// The body's own mass (ρA and point masses) in force coordinates: the backbone's displacement per
/// lateral tip force by central differences of the static shape.
bool add_body_mass(rod::RodSolver& s, const rod::InputVector& q, const rod::TipWrench& w, const ModalOptions& o,
                   Eigen::Matrix2d* Mf) {
  const rod::RodModel& m = s.model();
  const double L = m.length();
  double ei = 0.0;
  for (const rod::RodSegment& g : m.segments) ei = std::max(ei, g.stiffness.head<2>().maxCoeff());
  const double h = o.probe * ei / (L * L);
  const int K = std::max(4, o.samples);
  std::vector<Eigen::Matrix<double, 3, 2>> phi(K + 1);
  for (int j = 0; j < 2; ++j) {
    std::vector<Vec3> plus, minus;
    rod::TipWrench wp = w, wm = w;
    wp.force[j] += h, wm.force[j] -= h;
    if (!solve_shape(s, q, wp, K, &plus) || !solve_shape(s, q, wm, K, &minus)) return false;
    for (int k = 0; k <= K; ++k) phi[k].col(j) = (plus[k] - minus[k]) / (2 * h);  // base frame
  }
  for (int k = 0; k <= K; ++k) {
    const double ds = L / K * ((k == 0 || k == K) ? 0.5 : 1.0), sk = L * k / K;
    *Mf += density_at(m, std::min(sk, L * (1 - 1e-12))) * ds * phi[k].transpose() * phi[k];
  }
  for (const rod::PointLoad& p : m.loads) {
    const Eigen::Matrix<double, 3, 2> at = shape_at(phi, p.at, L);
    *Mf += p.mass * at.transpose() * at;
  }
  return true;
}

/// The tip's mass and inertia in force coordinates f (x = C f), from C^b's lateral force columns.
Eigen::Matrix2d tip_mass_matrix(const rod::RodModel& m, const rod::Mat6& body, const ModalOptions& o) {
  const Eigen::Matrix<double, 3, 2> dtip = body.block<3, 2>(0, 0), dtheta = body.block<3, 2>(3, 0);
  return o.tip_mass_scale *
         (m.tip_mass * dtip.transpose() * dtip + dtheta.transpose() * o.tip_inertia.asDiagonal() * dtheta);
}

/// The modes of K = C⁻¹ (C the lateral block of C^b's tip translation) with the mass Mf in force
/// coordinates.
ModalModel modes_from(const rod::Mat6& body, const Eigen::Matrix2d& Mf) {
  ModalModel out;
  const Eigen::Matrix<double, 3, 2> dtip = body.block<3, 2>(0, 0), dtheta = body.block<3, 2>(3, 0);
  const Eigen::Matrix2d C = 0.5 * (dtip.topRows<2>() + dtip.topRows<2>().transpose());
  const Eigen::Matrix2d Ci = C.inverse();
  if (!Ci.allFinite()) return failed("the lateral compliance is singular");
  out.stiffness = Ci;
  out.mass = Ci.transpose() * Mf * Ci;
  out.mass = 0.5 * (out.mass + out.mass.transpose());
  out.rotation = dtheta * Ci;
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix2d> eig(out.stiffness, out.mass);
  if (eig.info() != Eigen::Success || !(eig.eigenvalues().minCoeff() > 0.0))
    return failed("no positive-definite modes (is the equilibrium stable and the rod massive?)");
  out.frequency = eig.eigenvalues().cwiseSqrt();
  out.modes = eig.eigenvectors();
  out.ok = true;
  return out;
}

}  // namespace

bool has_body_mass(const rod::RodModel& m) {
  for (const rod::RodSegment& g : m.segments)
    if (g.linear_density > 0.0) return true;
  for (const rod::PointLoad& p : m.loads)
    if (p.mass > 0.0) return true;
  return false;
}

ModalModel lateral_modes(const rod::RodSolver& solver, const rod::InputVector& q, const rod::TipWrench& w,
                         const ModalOptions& o) {
  rod::RodSolver s = solver;
  if (!s.solve(q, w).converged) return failed("the equilibrium did not converge");
  // The tip's translation and rotation per lateral tip force (tip frame): C^b's columns f_x, f_y.
  const rod::Compliance c = s.compliance();
  if (!c.ok) return failed("the compliance could not be computed");
  Eigen::Matrix2d Mf = tip_mass_matrix(s.model(), c.body, o);
  if (has_body_mass(s.model()) && !add_body_mass(s, q, w, o, &Mf)) return failed("a probe solve did not converge");
  return modes_from(c.body, Mf);
}

ModalModel lateral_modes(const rod::RodModel& model, const rod::Mat6& body_compliance, const ModalOptions& o) {
  if (has_body_mass(model)) return failed("the body has mass of its own: its modes need the solver's probe solves");
  if (!body_compliance.allFinite()) return failed("the compliance is not finite");
  return modes_from(body_compliance, tip_mass_matrix(model, body_compliance, o));
}

}  // namespace control
}  // namespace hydrojet
