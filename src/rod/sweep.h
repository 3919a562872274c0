// Internal to hydrojet_rod: one tip-to-base integration ("sweep") through the stations of a
// RodSolver's model, with D sensitivity directions, and the jump conditions of rod_solver.h at each
// station. Sweep<D, T> is compiled once per model variant T (RodTerms) in src/rod/kernels/; the
// solver picks the model's variant once, at model load, so the integration loop has no branches on
// terms the model does not have. Not installed.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "hydrojet_control/rod/rod_model.h"
#include "hydrojet_control/rod/rod_solver.h"

namespace hydrojet {
namespace rod {
namespace internal {

/// One sensitivity direction of a sweep: where it starts and what it changes directly.
struct Direction {
  Vec3 eta_tip = Vec3::Zero();     ///< η at the start: a change of the start frame (Newton directions)
  Vec3 du0 = Vec3::Zero();         ///< δu at the start (multiple shooting's node directions)
  Vec3 dn0 = Vec3::Zero();         ///< δn at the start [N] (multiple shooting's node directions)
  Vec6 tip_wrench = Vec6::Zero();  ///< a change of the tip follower wrench (f_b, l_b)
  int actuator = -1;               ///< a unit change of this actuator's input
};

/// Arc lengths at which a sweep records the frame (descending), and what it recorded there.
struct Recorder {
  std::vector<double> at;  ///< descending, each in [0, L]
  std::vector<Mat3> R;
  std::vector<Vec3> p;
  std::vector<Vec3> u, n;  ///< u (body frame) and n (base frame) there, just above any station
};

/// A sweep's start inside the rod (multiple shooting): the state just above any station at s.
struct SweepStart {
  double s = 0.0;
  Mat3 R = Mat3::Identity();
  Vec3 u = Vec3::Zero();  ///< body frame [1/m]
  Vec3 n = Vec3::Zero();  ///< internal force, base (integration) frame [N]
};

template <int D>
using Block = Eigen::Matrix<double, 3, (D > 0 ? D : 1)>;

/// What a sweep that ends inside the rod hands on besides the state: n and the directions' δn there.
template <int D>
struct SweepEnd {
  Vec3 n = Vec3::Zero();
  Block<D> dn = Block<D>::Zero();
};

/// The state of a sweep: [p, R, u] and per direction [η, δu, δp] (the same for every variant).
template <int D>
using SweepState = typename RodOde<D, CosseratGeneral>::State;

/// One sweep's arguments. From the tip (R(L) = R_tip) or from `from` inside the rod, down to s_end
/// (0: the base); `to`, when given, receives n and δn at s_end; `rec` records frames on the way.
template <int D>
struct SweepCall {
  SweepCall(const RodSolver::Load& l, const IntegratorOptions& is, CvodeWorkspace* cv, SweepState<D>* state)
      : load(&l), integrator(is), cvode(cv), y(state) {}
  const RodSolver::Load* load = nullptr;
  IntegratorOptions integrator;
  CvodeWorkspace* cvode = nullptr;
  Mat3 R_tip = Mat3::Identity();
  const Direction* dirs = nullptr;
  SweepState<D>* y = nullptr;
  Recorder* rec = nullptr;
  const SweepStart* from = nullptr;
  double s_end = 0.0;
  SweepEnd<D>* to = nullptr;
  /// Steps of a fixed-step method on a piece: the rod's steps in proportion (≥ 1), times
  /// step_multiplier, divided by step_divisor (the Richardson estimate's other integration).
  int step_multiplier = 1, step_divisor = 1;
  int rhs = 0;  ///< right-hand-side evaluations (out)
};

/// Steps of a fixed-step method over a piece of length ds of a rod of length L with `steps` in all.
inline int piece_steps(int steps, double ds, double L) {
  return std::max(1, static_cast<int>(std::ceil(steps * ds / L - 1e-9)));
}

template <int D, class T>
struct Sweep {
  /// False when an integration failed (or the inputs do not match the actuators).
  static bool run(const RodSolver& solver, SweepCall<D>& c);
};

/// The sweeps of one compiled variant.
struct SweepKernels {
  bool (*s0)(const RodSolver&, SweepCall<0>&);
  bool (*s3)(const RodSolver&, SweepCall<3>&);
  bool (*s6)(const RodSolver&, SweepCall<6>&);
  bool (*s9)(const RodSolver&, SweepCall<9>&);
  const char* name;
  template <int D>
  bool run(const RodSolver& s, SweepCall<D>& c) const {
    if constexpr (D == 0) return s0(s, c);
    if constexpr (D == 3) return s3(s, c);
    if constexpr (D == 6) return s6(s, c);
    if constexpr (D == 9) return s9(s, c);
  }
};

}  // namespace internal

/// The solver's table entry: the variant's sweeps.
struct RodSolver::Kernels : internal::SweepKernels {};

}  // namespace rod
}  // namespace hydrojet
