// Dynamic Cosserat rod (Till, Aloi & Rucker, IJRR 2019): BDF-α in time, shooting in space.
// See include/hydrojet_control/rod/dynamic_rod.h for the model and the numerical scheme.
#include "hydrojet_control/rod/dynamic_rod.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace rod {

namespace {

bool finite_nonneg(double x) { return std::isfinite(x) && x >= 0.0; }
bool finite_pos(double x) { return std::isfinite(x) && x > 0.0; }

std::string bad(const char* name, const char* what, double value) {
  return std::string(name) + " " + what + " (got " + util::num(value) + ")";
}

std::string bad_vec(const char* name, const char* what, const Vec3& v) {
  return std::string(name) + " " + what + " (got [" + util::num(v.x()) + ", " + util::num(v.y()) + ", " +
         util::num(v.z()) + "])";
}

}  // namespace

std::string DynamicRodModel::validate() const {
  if (const std::string why = rod.validate(); !why.empty()) return "rod." + why;
  if (!finite_pos(shear_stiffness)) return bad("shear_stiffness", "must be positive and finite", shear_stiffness);
  if (!finite_pos(axial_stiffness)) return bad("axial_stiffness", "must be positive and finite", axial_stiffness);
  if (!finite_nonneg(kelvin_voigt_time))
    return bad("kelvin_voigt_time", "must be non-negative and finite", kelvin_voigt_time);
  if (!finite_nonneg(linear_drag)) return bad("linear_drag", "must be non-negative and finite", linear_drag);
  if (!finite_nonneg(quadratic_drag)) return bad("quadratic_drag", "must be non-negative and finite", quadratic_drag);
  if (!finite_nonneg(tip_drag)) return bad("tip_drag", "must be non-negative and finite", tip_drag);
  if (!finite_nonneg(tip_quadratic_drag))
    return bad("tip_quadratic_drag", "must be non-negative and finite", tip_quadratic_drag);
  if (!finite_nonneg(tip_angular_drag))
    return bad("tip_angular_drag", "must be non-negative and finite", tip_angular_drag);
  if (!tip_inertia.allFinite() || (tip_inertia.array() < 0.0).any())
    return bad_vec("tip_inertia", "must be non-negative and finite", tip_inertia);
  if (!finite_nonneg(rotational_inertia_per_length))
    return bad("rotational_inertia_per_length", "must be non-negative and finite", rotational_inertia_per_length);
  if (nodes < 2 || nodes > 2000) return bad("nodes", "must be in [2, 2000]", nodes);
  if (!std::isfinite(alpha) || alpha < -0.5 || alpha > 0.0) return bad("alpha", "must be in [-0.5, 0]", alpha);
  if (!finite_pos(tolerance)) return bad("tolerance", "must be positive and finite", tolerance);
  if (max_iterations < 1) return bad("max_iterations", "must be at least 1", max_iterations);
  if (max_substep_halvings < 0 || max_substep_halvings > 10)
    return bad("max_substep_halvings", "must be in [0, 10]", max_substep_halvings);
  return std::string();
}

DynamicRod::DynamicRod(const DynamicRodModel& model) : model_(model) {
  const std::string err = model_.validate();
  if (!err.empty()) throw std::invalid_argument("DynamicRodModel: " + err);
  k_se_ = Vec3(model_.shear_stiffness, model_.shear_stiffness, model_.axial_stiffness);
  kse_vstar_ = Vec3(0.0, 0.0, model_.axial_stiffness);  // K_se v*, v* = e_z
  b_se_ = model_.kelvin_voigt_time * k_se_;
  rho_j_ = model_.rotational_inertia_per_length * Vec3(1.0, 1.0, 2.0);
  inputs_ = rod::InputVector::Zero(static_cast<int>(model_.rod.actuators.size()));
  build_grid();
  slots_ = 4 * steps_ + 1;  // four RK4 stages per step, plus the tip

  z1_.setZero(12, slots_);
  z2_.setZero(12, slots_);
  zt1_.setZero(12, slots_);
  zh_.setZero(12, slots_);
  rec_.setZero(12, slots_);
  rec_trial_.setZero(12, slots_);
  nodes_.assign(steps_ + 1, Vec24::Zero());
  nodes_solve_.assign(steps_ + 1, Vec24::Zero());
  nodes_trial_.assign(steps_ + 1, Vec24::Zero());
  snap_z1_.setZero(12, slots_);
  snap_z2_.setZero(12, slots_);
  snap_zt1_.setZero(12, slots_);
  snap_nodes_.assign(steps_ + 1, Vec24::Zero());

  reset_to_static(rod::TipWrench());
}

void DynamicRod::set_coefficients(const Coefficients& c) {
  coef_ = c;
  // Till's semi-discretised constitutive law: (K + c0 B) is diagonal.
  inv_se_ = (k_se_ + c.c0 * b_se_).cwiseInverse();
  for (Piece& p : pieces_) p.inv_bt = (p.k_bt + c.c0 * p.b_bt).cwiseInverse();
}

void DynamicRod::build_grid() {
  const rod::RodModel& body = model_.rod;
  length_ = body.length();
  // Breakpoints: base, segment ends, loads, actuators, tip.
  std::vector<double> cuts = {0.0, length_};
  double end = 0.0;
  for (const rod::RodSegment& sg : body.segments) cuts.push_back(end += sg.length);
  for (const rod::PointLoad& ld : body.loads) cuts.push_back(ld.at);
  for (const rod::Actuator& a : body.actuators) cuts.push_back(a.at);
  std::sort(cuts.begin(), cuts.end());
  std::vector<double> knots;
  for (double c : cuts)
    if (knots.empty() || c > knots.back() + 1e-9 * length_) knots.push_back(std::min(c, length_));
  knots.back() = length_;
  // Pieces between knots, each with the material of the segment it lies in and steps in proportion.
  pieces_.clear();
  step_piece_.clear();
  step_h_.clear();
  node_s_.assign(1, 0.0);
  force_scale_ = 0.0;
  for (size_t k = 0; k + 1 < knots.size(); ++k) {
    const double a = knots[k], b = knots[k + 1], mid = 0.5 * (a + b);
    size_t seg = 0;
    for (double s0 = 0.0; seg + 1 < body.segments.size() && s0 + body.segments[seg].length < mid; ++seg)
      s0 += body.segments[seg].length;
    const rod::RodSegment& sg = body.segments[seg];
    Piece p;
    p.k_bt = sg.stiffness;
    p.kbt_ustar = sg.stiffness.cwiseProduct(sg.precurvature);
    p.b_bt = model_.kelvin_voigt_time * sg.stiffness;
    p.rho_a = sg.linear_density;
    force_scale_ = std::max(force_scale_, sg.stiffness.maxCoeff() / (length_ * length_));
    const int n = std::max(1, static_cast<int>(std::lround((model_.nodes - 1) * (b - a) / length_)));
    for (int i = 0; i < n; ++i) {
      step_piece_.push_back(static_cast<int>(pieces_.size()));
      step_h_.push_back((b - a) / n);
      node_s_.push_back(i + 1 == n ? b : a + (b - a) * (i + 1) / n);
    }
    pieces_.push_back(p);
  }
  steps_ = static_cast<int>(step_h_.size());
  // Loads and actuators at their nodes.
  node_load_.assign(steps_ + 1, -1);
  node_loads_.clear();
  auto load_at = [&](double s) -> NodeLoad& {
    int k = 0;
    for (int j = 1; j <= steps_; ++j)
      if (std::abs(node_s_[j] - s) < std::abs(node_s_[k] - s)) k = j;
    if (node_load_[k] < 0) {
      node_load_[k] = static_cast<int>(node_loads_.size());
      node_loads_.emplace_back();
    }
    return node_loads_[node_load_[k]];
  };
  for (const rod::PointLoad& ld : body.loads) {
    NodeLoad& nl = load_at(ld.at);
    nl.mass += ld.mass;
    (ld.frame == rod::LoadFrame::kBody ? nl.f_body : nl.f_base) += ld.force;
    (ld.frame == rod::LoadFrame::kBody ? nl.l_body : nl.l_base) += ld.moment;
  }
  for (size_t i = 0; i < body.actuators.size(); ++i)
    load_at(body.actuators[i].at).actuators.push_back(static_cast<int>(i));
}

void DynamicRod::node_wrench(const NodeLoad& load, const Vec24& y, int slot, Vec3* F, Vec3* M) const {
  const Eigen::Map<const Mat3> R(y.data() + 3);
  Vec3 fb = load.f_body, lb = load.l_body;
  for (int i : load.actuators) {
    const Vec6 unit = model_.rod.actuators[i].unit_wrench();
    fb += inputs_[i] * unit.head<3>();
    lb += inputs_[i] * unit.tail<3>();
  }
  *F = R * fb + load.f_base + load.mass * model_.rod.gravity;
  *M = R * lb + load.l_base;
  if (load.mass > 0.0) {  // the point mass's inertia: −m R(ω̂q + q_t)
    const Vec3 q = y.segment<3>(18), w = y.segment<3>(21);
    *F -= load.mass * (R * (w.cross(q) + coef_.c0 * q + zh_.col(slot).segment<3>(6)));
  }
}

void DynamicRod::update_distributed_weight() {
  for (Piece& p : pieces_) p.dist_weight = p.rho_a * model_.rod.gravity;
}

// Right-hand side of the semi-discretised rod ODE at one evaluation slot (Till eqs. for p_s, R_s,
// n_s, m_s, q_s, ω_s with y_t = c0 y + y_h substituted). State y = [p, R (col-major), n, m, q, ω].
template <bool kRecord>
void DynamicRod::rhs(const Vec24& y, int slot, Vec24& dy, Mat12X* rec) const {
  const Eigen::Map<const Mat3> R(y.data() + 3);
  const Vec3 n = y.segment<3>(12);
  const Vec3 m = y.segment<3>(15);
  const Vec3 q = y.segment<3>(18);
  const Vec3 w = y.segment<3>(21);
  const Vec12 zh = zh_.col(slot);
  const Vec3 vh = zh.segment<3>(0), uh = zh.segment<3>(3), qh = zh.segment<3>(6), wh = zh.segment<3>(9);
  const double c0 = coef_.c0;
  const Piece& pc = pieces_[step_piece_[std::min(slot / 4, steps_ - 1)]];
  // Constitutive law with Kelvin–Voigt damping, solved for the strains (diagonal).
  const Vec3 v = inv_se_.cwiseProduct(R.transpose() * n + kse_vstar_ - b_se_.cwiseProduct(vh));
  const Vec3 u = pc.inv_bt.cwiseProduct(R.transpose() * m + pc.kbt_ustar - pc.b_bt.cwiseProduct(uh));
  // BDF-α time derivatives.
  const Vec3 vt = c0 * v + vh;
  const Vec3 ut = c0 * u + uh;
  const Vec3 qt = c0 * q + qh;
  const Vec3 wt = c0 * w + wh;

  const Vec3 ps = R * v;  // p_s = R v
  dy.segment<3>(0) = ps;
  Eigen::Map<Mat3> dR(dy.data() + 3);  // R_s = R û
  dR.col(0) = R.col(1) * u.z() - R.col(2) * u.y();
  dR.col(1) = R.col(2) * u.x() - R.col(0) * u.z();
  dR.col(2) = R.col(0) * u.y() - R.col(1) * u.x();
  // n_s = ρA R(ω̂q + q_t) − ρA g + R c_d(q) q   (drag is the body-frame force −c_d q per length)
  Vec3 fb = pc.rho_a * (w.cross(q) + qt);
  if (drag_active_) fb += (model_.linear_drag + model_.quadratic_drag * q.norm()) * q;
  dy.segment<3>(12) = R * fb - pc.dist_weight;
  // m_s = R(ω̂ ρJ ω + ρJ ω_t) − p_s × n
  dy.segment<3>(15) = R * (w.cross(rho_j_.cwiseProduct(w)) + rho_j_.cwiseProduct(wt)) - ps.cross(n);
  // Kinematic compatibility: q_s = v_t − û q + ω̂ v,  ω_s = u_t − û ω
  dy.segment<3>(18) = vt - u.cross(q) + w.cross(v);
  dy.segment<3>(21) = ut - u.cross(w);
  if (kRecord) {
    auto col = rec->col(slot);
    col.segment<3>(0) = v;
    col.segment<3>(3) = u;
    col.segment<3>(6) = q;
    col.segment<3>(9) = w;
  }
}

Vec6 DynamicRod::pass(const Vec6& x, const rod::TipWrench& wr, Mat12X* rec, std::vector<Vec24>* nodes) {
  ++last_evaluations_;
  // Base boundary condition: p(0) = 0, R(0) = I, q(0) = ω(0) = 0; n(0), m(0) are the unknowns.
  Vec24 y = Vec24::Zero();
  y[3] = y[7] = y[11] = 1.0;
  y.segment<3>(12) = x.head<3>();
  y.segment<3>(15) = length_ * x.tail<3>();
  if (nodes) (*nodes)[0] = y;
  Vec24 k1, k2, k3, k4, t;
  double h = 0.0;
  // The four RK4 stages at slots sl..sl+3; `record` (std::true_type / std::false_type) picks at
  // compile time whether the right-hand side records z into `rec`.
  auto stages = [&](auto record, int sl) {
    constexpr bool kRecord = decltype(record)::value;
    rhs<kRecord>(y, sl, k1, rec);
    t = y + (0.5 * h) * k1;
    rhs<kRecord>(t, sl + 1, k2, rec);
    t = y + (0.5 * h) * k2;
    rhs<kRecord>(t, sl + 2, k3, rec);
    t = y + h * k3;
    rhs<kRecord>(t, sl + 3, k4, rec);
  };
  for (int j = 0; j < steps_; ++j) {
    h = step_h_[j];
    if (rec)
      stages(std::true_type{}, 4 * j);
    else
      stages(std::false_type{}, 4 * j);
    y += (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4);
    if (j + 1 < steps_ && node_load_[j + 1] >= 0) {  // a load inside: n and m drop by its wrench
      Vec3 F, M;
      node_wrench(node_loads_[node_load_[j + 1]], y, 4 * (j + 1), &F, &M);
      y.segment<3>(12) -= F;
      y.segment<3>(15) -= M;
    }
    if (nodes) (*nodes)[j + 1] = y;
  }

  // Tip boundary condition: the capsule as a rigid body.
  const Eigen::Map<const Mat3> R(y.data() + 3);
  const Vec3 n = y.segment<3>(12);
  const Vec3 m = y.segment<3>(15);
  const Vec3 q = y.segment<3>(18);
  const Vec3 w = y.segment<3>(21);
  const int tip = slots_ - 1;
  const Vec12 zh = zh_.col(tip);
  const double c0 = coef_.c0;
  const Vec3 qt = c0 * q + zh.segment<3>(6);
  const Vec3 wt = c0 * w + zh.segment<3>(9);
  const double mt = model_.rod.tip_mass;
  const Vec3& Jt = model_.tip_inertia;
  // n(L) = R f_b + m_t g − m_t R(ω̂q + q_t) − R c_t(q) q
  const Vec3 f_body = wr.force - mt * (w.cross(q) + qt) - (model_.tip_drag + model_.tip_quadratic_drag * q.norm()) * q;
  // m(L) = R l_b − R(ω̂ J_t ω + J_t ω_t) − R c_ω ω
  const Vec3 l_body = wr.moment - w.cross(Jt.cwiseProduct(w)) - Jt.cwiseProduct(wt) - model_.tip_angular_drag * w;
  Vec3 F = Vec3::Zero(), M = Vec3::Zero();  // loads and actuators at s = L
  if (node_load_[steps_] >= 0) node_wrench(node_loads_[node_load_[steps_]], y, tip, &F, &M);
  Vec6 r;
  r.head<3>() = n - R * f_body - mt * model_.rod.gravity - F;
  r.tail<3>() = (m - R * l_body - M) / length_;
  // Size of the largest terms that cancel in r (sets the round-off floor of the residual).
  residual_scale_ = n.norm() + mt * (qt.norm() + w.norm() * q.norm()) + wr.force.norm() + F.norm() +
                    (m.norm() + Jt.norm() * (wt.norm() + w.squaredNorm()) + wr.moment.norm() + M.norm()) / length_;
  if (rec) {
    auto col = rec->col(tip);
    col.segment<3>(0) = inv_se_.cwiseProduct(R.transpose() * n + kse_vstar_ - b_se_.cwiseProduct(zh.segment<3>(0)));
    const Piece& pc = pieces_[step_piece_[steps_ - 1]];
    col.segment<3>(3) =
        pc.inv_bt.cwiseProduct(R.transpose() * m + pc.kbt_ustar - pc.b_bt.cwiseProduct(zh.segment<3>(3)));
    col.segment<3>(6) = q;
    col.segment<3>(9) = w;
  }
  if (!y.allFinite()) r.setConstant(std::numeric_limits<double>::quiet_NaN());
  return r;
}

bool DynamicRod::fail(const std::string& message) {
  last_error_ = message;
  return false;
}

bool DynamicRod::refresh_jacobian(const Vec6& x, const Vec6& r, const rod::TipWrench& w) {
  // Forward differences; the unknowns and residuals are all in newtons (moments scaled by 1/L).
  for (int j = 0; j < 6; ++j) {
    const double dx = 1e-7 * (force_scale_ + std::abs(x[j]));
    Vec6 xp = x;
    xp[j] += dx;
    jac_.col(j) = (pass(xp, w, nullptr, nullptr) - r) / dx;
  }
  jac_valid_ = jac_.allFinite();
  if (jac_valid_) {
    lu_.compute(jac_);
    jac_valid_ = std::isfinite(lu_.determinant()) && lu_.determinant() != 0.0;
  }
  jac_fresh_ = jac_valid_;
  jac_c0_ = coef_.c0;
  return jac_valid_ || fail("singular or non-finite shooting Jacobian");
}

double DynamicRod::best_start(Vec6* x, const rod::TipWrench& w, const Vec6* alternatives, int n_alternatives, Vec6* r,
                              double* scale) {
  *r = pass(*x, w, &rec_, &nodes_solve_);
  double rn = r->norm();
  *scale = residual_scale_;
  // A poor predictor (violent motion: the base forces vary faster than the extrapolation can
  // follow) is replaced by the best of the alternative starting points.
  if (std::isfinite(rn) && rn > 10.0 * force_scale_) {
    for (int k = 0; k < n_alternatives; ++k) {
      const Vec6 ra = pass(alternatives[k], w, &rec_trial_, &nodes_trial_);
      if (ra.allFinite() && ra.norm() < rn) {
        *x = alternatives[k];
        *r = ra;
        rn = ra.norm();
        *scale = residual_scale_;
        std::swap(rec_, rec_trial_);
        std::swap(nodes_solve_, nodes_trial_);
      }
    }
  }
  return rn;
}

double DynamicRod::newton_tolerance(double scale) const {
  // Relative to F0, but never below the round-off floor of the residual, whose terms (e.g. m_t q_t
  // at large c0 = O(1/Δt)) can be much larger than F0 in violent motion.
  return model_.tolerance * force_scale_ + 1e-13 * scale;
}

bool DynamicRod::prepare_jacobian(const Vec6& x, const Vec6& r, const rod::TipWrench& w, bool full_newton) {
  const bool c0_changed = std::abs(coef_.c0 - jac_c0_) > 1e-12 * std::max(1.0, std::abs(coef_.c0));
  if (full_newton || !jac_valid_ || c0_changed) return refresh_jacobian(x, r, w);
  jac_fresh_ = false;
  return true;
}

bool DynamicRod::line_search(const Vec6& x, const Vec6& dx, double rn, const rod::TipWrench& w, Vec6* xt, Vec6* rt,
                             double* lambda) {
  // A trial is accepted when the residual decreases or when Deuflhard's affine-invariant natural
  // monotonicity test holds, |J⁻¹ r(x + λΔx)| ≤ (1 − λ/4)|Δx| (the residual's components have very
  // different sensitivities, so |r| alone is a poor merit).
  const double dx_norm = dx.norm();
  *lambda = 1.0;
  for (int k = 0; k < 12; ++k, *lambda *= 0.5) {
    *xt = x + *lambda * dx;
    *rt = pass(*xt, w, &rec_trial_, &nodes_trial_);
    if (rt->allFinite() &&
        (rt->norm() < (1.0 - 1e-4 * *lambda) * rn || lu_.solve(*rt).norm() <= (1.0 - 0.25 * *lambda) * dx_norm))
      return true;
    if (!jac_fresh_) return false;  // an outdated Jacobian: refresh rather than backtrack
  }
  return false;
}

void DynamicRod::broyden_update(const Vec6& x, const Vec6& xt, const Vec6& r, const Vec6& rt) {
  // Skipped when the step is so small that the secant would mostly carry round-off.
  const Vec6 s = xt - x;
  if (s.norm() > 1e-8 * (force_scale_ + x.norm())) {
    jac_ += ((rt - r) - jac_ * s) * s.transpose() / s.squaredNorm();
    lu_.compute(jac_);
    jac_fresh_ = false;
  }
}

bool DynamicRod::newton(Vec6* x, const rod::TipWrench& w, bool full_newton, const Vec6* alternatives,
                        int n_alternatives) {
  Vec6 r;
  double scale = 0.0;
  double rn = best_start(x, w, alternatives, n_alternatives, &r, &scale);
  double tol = newton_tolerance(scale);  // [N]
  if (!std::isfinite(rn)) return fail("shooting pass produced a non-finite state at the initial guess");
  if (rn <= tol) return true;
  if (!prepare_jacobian(*x, r, w, full_newton)) return false;
  int iterations = 0;
  while (rn > tol) {
    if (iterations >= model_.max_iterations) {
      std::ostringstream os;
      os << "Newton did not converge in " << model_.max_iterations << " iterations (|residual| = " << rn
         << " N, tolerance " << tol << " N)";
      return fail(os.str());
    }
    const Vec6 dx = -lu_.solve(r);
    if (!std::isfinite(dx.norm())) return fail("non-finite Newton step");
    Vec6 xt, rt;
    double lambda = 1.0;
    const bool accepted = line_search(*x, dx, rn, w, &xt, &rt, &lambda);
    ++iterations;
    ++last_iterations_;
    if (!accepted) {
      if (!jac_fresh_) {
        if (!refresh_jacobian(*x, r, w)) return false;
        continue;
      }
      if (rn <= 1e3 * tol) return true;  // at the round-off floor: accept
      std::ostringstream os;
      os << "line search failed (|residual| = " << rn << " N)";
      return fail(os.str());
    }
    broyden_update(*x, xt, r, rt);
    const double ratio = rt.norm() / rn;
    *x = xt;
    r = rt;
    rn = rt.norm();
    tol = newton_tolerance(residual_scale_);  // the accepted trial was the last pass
    std::swap(rec_, rec_trial_);
    std::swap(nodes_solve_, nodes_trial_);
    if (rn > tol && (full_newton || ratio > 0.3 || lambda < 1.0) && !refresh_jacobian(*x, r, w)) return false;
  }
  return true;
}

// The rod's static Kirchhoff solution (rod::RodSolver), then n(0), m(0) from the force and moment
// balance of everything the rod carries: tip wrench and mass, the loads and actuators at their
// nodes, the distributed weight.
Vec6 DynamicRod::static_guess(const rod::TipWrench& w, bool* ok) {
  rod::RodModel g = model_.rod;
  g.kind = rod::RodKind::kKirchhoff;
  rod::ShootingOptions st;
  st.integrator.type = rod::IntegratorType::kRk8;
  st.residual_tolerance = 1e-12;
  rod::RodSolver solver(g, st);
  *ok = solver.solve(inputs_, w).converged;
  auto frame = [&](double s, Mat3* R, Vec3* p) {
    if (!*ok || !solver.frame_at(s, R, p)) *R = Mat3::Identity(), *p = s * Vec3::UnitZ();
  };
  Vec3 n0 = Vec3::Zero(), m0 = Vec3::Zero();
  auto add = [&](const Vec3& F, const Vec3& M, const Vec3& p) {
    n0 += F;
    m0 += M + p.cross(F);
  };
  Mat3 R;
  Vec3 p;
  frame(length_, &R, &p);
  add(R * w.force + g.tip_mass * g.gravity, R * w.moment, p);
  for (int k = 1; k <= steps_; ++k) {
    if (node_load_[k] < 0) continue;
    frame(node_s_[k], &R, &p);
    Vec24 y = Vec24::Zero();
    Eigen::Map<Mat3>(y.data() + 3) = R;
    Vec3 F, M;
    node_wrench(node_loads_[node_load_[k]], y, 4 * k, &F, &M);
    add(F, M, p);
  }
  for (int j = 0; j < steps_; ++j) {
    frame(0.5 * (node_s_[j] + node_s_[j + 1]), &R, &p);
    add(pieces_[step_piece_[j]].rho_a * step_h_[j] * g.gravity, Vec3::Zero(), p);
  }
  Vec6 x;
  x << n0, m0 / length_;
  return x;
}

bool DynamicRod::reset_to_static(const rod::TipWrench& w) {
  last_iterations_ = 0;
  last_evaluations_ = 0;
  if (!w.force.allFinite()) {
    last_error_ = "non-finite tip wrench: force";
    return false;
  }
  if (!w.moment.allFinite()) {
    last_error_ = "non-finite tip wrench: moment";
    return false;
  }
  last_error_.clear();
  bool kirchhoff_ok = false;
  // Static problem: all time derivatives zero (c0 = 0, y_h = 0) -> q ≡ ω ≡ 0.
  set_coefficients(Coefficients());
  zh_.setZero();
  Vec6 x = static_guess(w, &kirchhoff_ok);
  update_distributed_weight();
  drag_active_ = model_.linear_drag > 0.0 || model_.quadratic_drag > 0.0;
  const bool ok = newton(&x, w, true);
  jac_valid_ = false;  // the static Jacobian (c0 = 0) is not the dynamic one
  if (!ok) {
    last_error_ = "reset_to_static: " + last_error_ +
                  (kirchhoff_ok ? "" : " (the quasi-static RodSolver did not converge either)");
    return false;
  }
  z1_ = rec_;
  z2_ = rec_;
  zt1_.setZero();
  nodes_.swap(nodes_solve_);
  x_ = x;
  x_prev_ = x;
  x_prev2_ = x;
  at_rest_history_ = true;
  dt_prev_ = 0.0;
  dt_prev2_ = 0.0;
  time_ = 0.0;
  initialised_ = true;
  return true;
}

bool DynamicRod::step(const rod::TipWrench& w, double dt) {
  last_iterations_ = 0;
  last_evaluations_ = 0;
  if (!initialised_) {
    last_error_ = "not initialised: reset_to_static() has not succeeded";
    return false;
  }
  if (!w.force.allFinite()) {
    last_error_ = "non-finite tip wrench: force";
    return false;
  }
  if (!w.moment.allFinite()) {
    last_error_ = "non-finite tip wrench: moment";
    return false;
  }
  if (!finite_pos(dt)) {
    std::ostringstream os;
    os << "dt must be positive and finite (got " << dt << ")";
    last_error_ = os.str();
    return false;
  }
  last_error_.clear();
  last_substeps_ = 1;
  if (advance(w, dt)) return true;

  // Fallback: the same interval in 2, 4, ... equal substeps (the wrench held over all of them).
  // The snapshot copies are into preallocated storage of the same size (no allocation).
  const std::string first = last_error_;
  snap_z1_ = z1_;
  snap_z2_ = z2_;
  snap_zt1_ = zt1_;
  snap_nodes_ = nodes_;
  const Vec6 sx = x_, sx1 = x_prev_, sx2 = x_prev2_;
  const double sdt1 = dt_prev_, sdt2 = dt_prev2_, st = time_;
  const bool srest = at_rest_history_;
  auto restore = [&]() {
    z1_ = snap_z1_;
    z2_ = snap_z2_;
    zt1_ = snap_zt1_;
    nodes_ = snap_nodes_;
    x_ = sx, x_prev_ = sx1, x_prev2_ = sx2;
    dt_prev_ = sdt1, dt_prev2_ = sdt2, time_ = st;
    at_rest_history_ = srest;
  };
  for (int level = 1; level <= model_.max_substep_halvings; ++level) {
    const int n = 1 << level;
    bool ok = true;
    for (int i = 0; i < n && ok; ++i) ok = advance(w, dt / n);
    if (ok) {
      time_ = st + dt;
      last_substeps_ = n;
      last_error_.clear();
      return true;
    }
    restore();
  }
  std::ostringstream os;
  os << "step: the boundary-value problem did not converge (" << first;
  if (model_.max_substep_halvings > 0)
    os << "; also failed with " << (1 << model_.max_substep_halvings) << " substeps: " << last_error_;
  os << ")";
  last_error_ = os.str();
  return false;
}

bool DynamicRod::advance(const rod::TipWrench& w, double dt) {
  // Till's BDF-α coefficients; the θ-method for a step whose Δt differs from the last one.
  const double a = model_.alpha;
  Coefficients c;
  c.d1 = a / (1.0 + a);
  if (at_rest_history_ || std::abs(dt - dt_prev_) <= 1e-12 * dt) {
    c.c0 = (1.5 + a) / (dt * (1.0 + a));
    c.c1 = -2.0 / dt;
    c.c2 = (0.5 + a) / (dt * (1.0 + a));
  } else {
    const double theta = 1.0 / (1.0 - c.d1);  // ρ∞ = (1 − θ)/θ = |d1|
    c.c0 = 1.0 / (theta * dt);
    c.c1 = -c.c0;
    c.c2 = 0.0;
    c.d1 = -(1.0 - theta) / theta;
  }
  set_coefficients(c);
  zh_.noalias() = c.c1 * z1_;
  zh_.noalias() += c.c2 * z2_;
  zh_.noalias() += c.d1 * zt1_;
  update_distributed_weight();
  drag_active_ = model_.linear_drag > 0.0 || model_.quadratic_drag > 0.0;

  // Warm start: extrapolate the base unknowns from the last steps (quadratic when the last two
  // steps had this dt, linear otherwise). After a reset the history is "at rest" (x_prev_ =
  // x_prev2_ = x_, dt_prev_ = dt_prev2_ = 0 stands for any dt), which extrapolates to x_.
  auto same_dt = [dt](double d) { return d == 0.0 || std::abs(dt - d) <= 1e-12 * dt; };
  Vec6 x = x_;
  Vec6 alternatives[2] = {x_, x_};  // linear extrapolation, previous values
  if (dt_prev_ > 0.0) alternatives[0] += (x_ - x_prev_) * (dt / dt_prev_);
  if (same_dt(dt_prev_) && same_dt(dt_prev2_)) {
    x = 3.0 * x_ - 3.0 * x_prev_ + x_prev2_;
  } else {
    x = alternatives[0];
  }
  if (!newton(&x, w, false, alternatives, 2)) {
    // Retry from the previous step's values with a fresh Jacobian.
    x = x_;
    jac_valid_ = false;
    if (!newton(&x, w, false)) {
      jac_valid_ = false;
      return false;
    }
  }

  // Commit: shift the history, z_t(i) = c0 z(i) + z_h.
  z2_.swap(z1_);
  z1_ = rec_;
  zt1_.noalias() = c.c0 * rec_;
  zt1_ += zh_;
  nodes_.swap(nodes_solve_);
  x_prev2_ = x_prev_;
  x_prev_ = x_;
  x_ = x;
  at_rest_history_ = false;
  dt_prev2_ = dt_prev_;
  dt_prev_ = dt;
  time_ += dt;
  return true;
}

bool DynamicRod::set_inputs(const rod::InputVector& q) {
  if (q.size() != inputs_.size()) {
    std::ostringstream os;
    os << "set_inputs: " << q.size() << " inputs for " << inputs_.size() << " actuators";
    return fail(os.str());
  }
  if (!q.allFinite()) return fail("set_inputs: non-finite input");
  inputs_ = q;
  return true;
}

void DynamicRod::set_gravity(const Vec3& g) {
  if (!g.allFinite()) {
    last_error_ = "set_gravity: non-finite gravity ignored";
    return;
  }
  model_.rod.gravity = g;
}

Mat3 DynamicRod::tip_rotation() const { return so3::orthonormalise(Eigen::Map<const Mat3>(nodes_.back().data() + 3)); }

Vec3 DynamicRod::tip_position() const { return nodes_.back().segment<3>(0); }

Vec3 DynamicRod::tip_velocity() const {
  return Eigen::Map<const Mat3>(nodes_.back().data() + 3) * nodes_.back().segment<3>(18);
}

Vec3 DynamicRod::tip_angular_velocity() const {
  return Eigen::Map<const Mat3>(nodes_.back().data() + 3) * nodes_.back().segment<3>(21);
}

std::vector<Vec3> DynamicRod::backbone() const {
  std::vector<Vec3> pts;
  pts.reserve(nodes_.size());
  for (const Vec24& y : nodes_) pts.push_back(y.segment<3>(0));
  return pts;
}

Vec3 DynamicRod::base_force() const { return nodes_.front().segment<3>(12); }
Vec3 DynamicRod::base_moment() const { return nodes_.front().segment<3>(15); }

}  // namespace rod
}  // namespace hydrojet
