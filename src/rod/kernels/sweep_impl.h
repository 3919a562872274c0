// Internal to hydrojet_rod: the definition of Sweep<D, T>::run (sweep.h), included by the kernel_*.cpp
// files only. Why one translation unit per variant: with all of them in one, GCC's inlining budget
// ran out and the hot loop became 2× slower. Not installed.
#pragma once

#include "../rod_integration.h"
#include "../sweep.h"

namespace hydrojet {
namespace rod {
namespace internal {

template <int D, class T>
struct SweepBody {
  using Ode = RodOde<D, T>;
  const RodSolver& solver;
  SweepCall<D>& c;

  int steps(double ds) const {
    return piece_steps(c.integrator.steps, ds, solver.model().length()) * c.step_multiplier / c.step_divisor;
  }

  /// Adds what station `st` applies to the internal wrench (n base frame, M body frame) and to the
  /// directions' (δn, δM), at the frame R and the directions' η held in y.
  void apply_station(const RodSolver::Station& st, bool tip, Vec3* n, Vec3* M, Block<D>* dn, Block<D>* dM) const {
    const RodModel& m = solver.model();
    const RodSolver::Load& load = *c.load;
    const Eigen::Map<const Mat3> R(c.y->data() + 3);
    const double g = load.gravity_scale;
    Vec3 f_fol = g * st.f_body, l_fol = g * st.l_body;
    for (int j : st.actuators) {
      const Vec6 w = m.actuators[j].unit_wrench();
      f_fol += load.q[j] * w.template head<3>();
      l_fol += load.q[j] * w.template tail<3>();
    }
    if (tip) {
      f_fol += load.wrench.force;
      l_fol += load.wrench.moment;
    }
    const Vec3 f_dead = g * (st.f_base + st.mass * m.gravity);
    const Vec3 l_dead_body = R.transpose() * (g * st.l_base);
    *n += R * f_fol + f_dead;
    *M += l_fol + l_dead_body;
    for (int d = 0; d < D; ++d) {
      const Direction& dir = c.dirs[d];
      const Vec3 eta = c.y->template segment<3>(Ode::kBase + Ode::kPerDir * d);
      dn->col(d) += R * eta.cross(f_fol);
      dM->col(d) -= eta.cross(l_dead_body);
      if (dir.actuator >= 0 &&
          std::find(st.actuators.begin(), st.actuators.end(), dir.actuator) != st.actuators.end()) {
        const Vec6 w = m.actuators[dir.actuator].unit_wrench();
        dn->col(d) += R * w.template head<3>();
        dM->col(d) += w.template tail<3>();
      }
      if (tip) {
        dn->col(d) += R * dir.tip_wrench.template head<3>();
        dM->col(d) += dir.tip_wrench.template tail<3>();
      }
    }
  }

  /// The piece [s_lo, s_hi] of one segment: y integrated down, n by its closed form (n(σ) = n(s) +
  /// w_dist (s − σ)); the recorder's points inside cut it further.
  bool piece(const RodSegment& sg, double s_hi, double s_lo, Vec3* n, const Block<D>& dn, size_t* r) {
    const RodModel& m = solver.model();
    Ode ode;
    ode.k_diag = sg.stiffness;
    ode.k_inv = sg.stiffness.cwiseInverse();
    ode.u_tilde = sg.precurvature;
    ode.kse_inv = sg.shear_extension_compliance(m.kind);
    ode.w_dist = c.load->gravity_scale * sg.linear_density * m.gravity;
    if constexpr (D > 0) ode.dn = dn;
    Recorder* rec = c.rec;
    double s = s_hi;
    while (true) {
      double next = s_lo;
      const bool record = rec && *r < rec->at.size() && rec->at[*r] >= s_lo - 1e-15 && rec->at[*r] <= s + 1e-15;
      if (record) next = std::max(s_lo, std::min(s, rec->at[*r]));
      if (next < s) {
        ode.length = s;  // n(σ) = n(s) + w_dist (s − σ) on [next, s]
        ode.n_tip = *n;
        IntegratorOptions is = c.integrator;
        is.steps = steps(s - next);
        const IntegrationStats st = integrate_rod(is, c.cvode, ode, s, next, c.y);
        c.rhs += st.rhs_evaluations;
        if (!st.ok || !c.y->allFinite()) return false;
        *n += ode.w_dist * (s - next);
        s = next;
      }
      if (!record) return true;
      rec->R.push_back(Eigen::Map<const Mat3>(c.y->data() + 3));
      rec->p.push_back(c.y->template segment<3>(0));
      rec->u.push_back(c.y->template segment<3>(12));
      rec->n.push_back(*n);
      ++*r;
    }
  }

  bool finish_at(const Vec3& n, const Block<D>& dn) const {
    if (c.to) {
      c.to->n = n;
      c.to->dn = dn;
    }
    return true;
  }

  bool run() {
    const RodModel& m = solver.model();
    const auto& sts = solver.stations();
    const double tol = 1e-12 * m.length();
    // One input per actuator (a load built without them would read past q: refuse instead).
    if (c.load->q.size() != static_cast<Eigen::Index>(m.actuators.size())) return false;
    SweepState<D>& y = *c.y;
    y.setZero();
    Eigen::Map<Mat3>(y.data() + 3) = c.from ? c.from->R : c.R_tip;
    Vec3 n = Vec3::Zero(), M = Vec3::Zero();
    Block<D> dn = Block<D>::Zero(), dM = Block<D>::Zero();
    for (int d = 0; d < D; ++d) {
      y.template segment<3>(Ode::kBase + Ode::kPerDir * d) = c.dirs[d].eta_tip;
      y.template segment<3>(Ode::kBase + Ode::kPerDir * d + 3) = c.dirs[d].du0;
      dn.col(d) = c.dirs[d].dn0;
    }
    size_t i = 0, r = 0;
    if (c.from) {  // the stations at or below the start; the piece down to the first of them
      y.template segment<3>(12) = c.from->u;
      n = c.from->n;
      while (i < sts.size() && sts[i].s > c.from->s + tol) ++i;
      if (i == 0) return false;  // not below the tip
      const double s_lo = std::max(i < sts.size() ? sts[i].s : 0.0, c.s_end);
      if (!piece(m.segments[sts[i - 1].segment_below], c.from->s, s_lo, &n, dn, &r)) return false;
      if (s_lo <= c.s_end + tol) return finish_at(n, dn);
    }
    for (; i < sts.size(); ++i) {
      const RodSegment& below = m.segments[sts[i].segment_below];
      if (i > 0) {  // the moment arriving from above, M_b = K (u − ũ) of the segment above
        const RodSegment& above = m.segments[sts[i - 1].segment_below];
        M = above.stiffness.cwiseProduct(y.template segment<3>(12) - above.precurvature);
        for (int d = 0; d < D; ++d)
          dM.col(d) = above.stiffness.cwiseProduct(y.template segment<3>(Ode::kBase + Ode::kPerDir * d + 3));
      }
      apply_station(sts[i], i == 0, &n, &M, &dn, &dM);
      const Vec3 k_inv = below.stiffness.cwiseInverse();
      y.template segment<3>(12) = below.precurvature + k_inv.cwiseProduct(M);
      for (int d = 0; d < D; ++d)
        y.template segment<3>(Ode::kBase + Ode::kPerDir * d + 3) = k_inv.cwiseProduct(dM.col(d));
      // The piece from this station down to the next (or the base, or s_end).
      const double s_lo = std::max(i + 1 < sts.size() ? sts[i + 1].s : 0.0, c.s_end);
      if (!piece(below, sts[i].s, s_lo, &n, dn, &r)) return false;
      if (s_lo <= c.s_end + tol) break;
    }
    return finish_at(n, dn);
  }
};

template <int D, class T>
bool Sweep<D, T>::run(const RodSolver& solver, SweepCall<D>& c) {
  return SweepBody<D, T>{solver, c}.run();
}

}  // namespace internal
}  // namespace rod
}  // namespace hydrojet

/// Explicit instantiation of one variant's hot sweeps (in a kernel_*.cpp): the Newton evaluation (3
/// directions), C^b (6) and the state alone (0). Multiple shooting's node sweeps (9) live in
/// kernel_nodes.cpp: in the same unit they cost the hot loop GCC's inlining budget (2× slower).
#define HYDROJET_ROD_KERNELS(C, W, P)          \
  namespace hydrojet {                         \
  namespace rod {                              \
  namespace internal {                         \
  template struct Sweep<0, RodTerms<C, W, P>>; \
  template struct Sweep<3, RodTerms<C, W, P>>; \
  template struct Sweep<6, RodTerms<C, W, P>>; \
  }                                            \
  }                                            \
  }
