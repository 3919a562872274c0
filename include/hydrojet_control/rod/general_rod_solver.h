// Static solve of any follower-actuated rod (general_rod.h: segments, point loads along the body,
// N actuators anywhere) by shooting from the tip to the base, with the body compliance C^b and the
// actuation Jacobian J_q = ∂(v, ω)_tip/∂q from forward-mode sensitivities of the converged solve.
// ROS-free (Eigen; SUNDIALS behind the cvode-* integrators).
//
// Why one unknown still suffices: the only distributed force is the body weight ρA·g (constant in
// the base frame per segment) and every point load or actuator is known once the frame R(s) at its
// arc length is, so integrating from the tip with a guessed R(L) gives n(s) and m(s) everywhere.
// The rod is cut at stations (segment ends, load and actuator arc lengths); between two stations the
// right-hand side is ShootingSolver's RodOde (eq. 14) with that segment's K, ũ, ρA; at a station
// s_k the internal wrench jumps by what is applied there (the jump conditions):
//   n(s_k⁻) = n(s_k⁺) + R(s_k) f_follower + f_dead + m_k g            (base frame)
//   M_b(s_k⁻) = M_b(s_k⁺) + l_follower + R(s_k)ᵀ l_dead                (body frame)
//   u(s_k⁻) = ũ⁻ + K⁻⁻¹ M_b(s_k⁻)                  (the moment is continuous across a material change)
// with f_follower, l_follower the follower loads and the actuators' q_i·(d_i, p_i × d_i). The tip is
// the station s = L with n(L⁺) = 0, M_b(L⁺) = 0 (eq. 16 with eq. 13 there). The sensitivities go
// through the same jumps, linearised: δn⁻ = δn⁺ + R(η × f_follower) + R δf, δM⁻ = δM⁺ − η × Rᵀ l_dead + δl.
//
// Robustness ladder of solve(): Newton from the warm solution (or the unloaded, piecewise-arc
// shape) → load continuation (src/rod/load_path.h, the same component as ShootingSolver's) →
// accuracy check (fixed-step integrators: Richardson estimate against accuracy_tolerance·L) →
// fold/branch report → for a cold solve, ShootingSolver's stability check (an equilibrium with
// indicator ≤ 0 on settings.cold_stability_check is loaded again from rest with a push, else warned).
// Multiple shooting (settings.shooting_segments as ShootingSolver's: 0 automatic, first when λL > 12
// and as the fallback when single shooting fails; 1 never; M ≥ 2 always, M segments): the node
// unknowns are the frame, internal force and curvature (general_rod_solver.cpp, "Multiple shooting").
// The KINSOL backend option is ignored (Eigen Newton).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

#include "hydrojet_control/rod/general_rod.h"
#include "hydrojet_control/rod/shooting_solver.h"

namespace hydrojet {
namespace rod {

class CvodeWorkspace;

/// Actuator inputs q [N] in the model's actuator order (at most kMaxActuators).
using ActuatorInputs = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxActuators, 1>;
/// J_q: 6 rows (tip body twist v, ω) × one column per actuator.
using ActuationJacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxActuators>;

/// C^b (tip body wrench → tip body twist, as Compliance) and J_q at one equilibrium.
struct GeneralCompliance {
  bool ok = false;
  Mat6 body = Mat6::Zero();                                     ///< C^b: rows (v, ω), columns (f_b, l_b) at the tip
  ActuationJacobian actuation = ActuationJacobian::Zero(6, 0);  ///< J_q [m/N; rad/N]: column i per unit input q_i
};

class GeneralRodSolver {
 public:
  /// The model must be valid (GeneralRodModel::validate() empty): std::invalid_argument otherwise.
  GeneralRodSolver(const GeneralRodModel& model, const ShootingOptions& settings);
  ~GeneralRodSolver();
  GeneralRodSolver(const GeneralRodSolver& other);
  GeneralRodSolver& operator=(const GeneralRodSolver& other);

  /// Solves for actuator inputs q (one per actuator, any value: bounds are the allocation's
  /// business) and an extra follower wrench at the tip, warm-started from the last converged solution.
  RodSolution solve(const ActuatorInputs& q, const TipWrench& tip = TipWrench());
  /// Forgets the warm start.
  void reset();

  /// C^b and J_q at the last converged solution (implicit function theorem on the shooting residual).
  GeneralCompliance compliance();
  /// K+1 backbone points [m] from base to tip (base frame) at the last converged solution, at equal
  /// arc-length spacing over the whole rod (all segments).
  std::vector<Vec3> shape(int points_minus_one) const;
  /// The frame of the backbone at arc length s ∈ [0, L] (base frame) at the last converged solution.
  bool frame_at(double s, Mat3* R, Vec3* p) const;

  const GeneralRodModel& model() const { return model_; }
  const ShootingOptions& settings() const { return settings_; }
  int actuator_count() const { return static_cast<int>(model_.actuators.size()); }
  bool has_solution() const { return have_solution_; }
  const RodSolution& last_solution() const { return last_; }
  /// λL = L·√(|n|max / EI_min) of the sensitivities' growth for these inputs (as ShootingSolver's).
  double growth_estimate(const ActuatorInputs& q, const TipWrench& tip) const;

  /// What loads the rod at one solve: the tip wrench, the inputs, and a scale of the fixed loads
  /// (gravity, point loads) that load continuation ramps from 0 to 1.
  struct Load {
    TipWrench wrench;
    ActuatorInputs q;
    double gravity_scale = 1.0;
  };
  /// The station list: where the rod is cut (exposed for tests and docs).
  struct Station {
    double s = 0.0;                                     ///< arc length [m]
    int segment_below = 0;                              ///< segment of the piece just below s (toward the base)
    Vec3 f_body = Vec3::Zero(), l_body = Vec3::Zero();  ///< fixed follower loads [N, N m], body frame
    Vec3 f_base = Vec3::Zero(), l_base = Vec3::Zero();  ///< fixed dead loads [N, N m], base frame
    double mass = 0.0;                                  ///< point masses here (tip mass at L) [kg]
    std::vector<int> actuators;                         ///< actuators applied here
  };
  const std::vector<Station>& stations() const { return stations_; }

 private:
  struct Eval {
    Vec3 r = Vec3::Zero();  ///< residual log R(0)
    Mat3 J = Mat3::Zero();  ///< ∂r/∂x
    Mat3 R0 = Mat3::Identity();
    Vec3 p0 = Vec3::Zero();
    Mat3 dp0 = Mat3::Zero();  ///< δp(0) per x-direction
    bool ok = false;
  };
  struct Shooting;  // the load_path.h Problem
  struct Sweep;     // one tip-to-base integration through the stations
  friend struct Sweep;

  void build_stations();
  void update_unloaded_shape();
  bool newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last);
  Eval evaluate(const Mat3& R_tip, const Load& load, int* rhs);
  double error_estimate(const Mat3& R_tip, const Load& load, const Eval& e);
  bool accurate_enough(RodSolution* sol) const;
  bool finish(Shooting* p, bool ok, internal::FoldTracker* folds, bool check_accuracy = true);
  // Multiple shooting (general_rod_solver.cpp, "Multiple shooting").
  struct MsNodes;
  bool ms_nodes(const Mat3& R_tip, const Load& load, int M, MsNodes* x);
  bool ms_evaluate(const MsNodes& x, const Load& load, Eigen::VectorXd* F, Eigen::MatrixXd* J, Vec3* sum_dp, Mat3* R0,
                   int* rhs);
  bool ms_newton(MsNodes* x, const Load& load, double* residual, RodSolution* sol, std::pair<Mat3, Vec3>* pose);
  static MsNodes ms_moved(const MsNodes& x, const Eigen::VectorXd& dX);
  bool multiple_shooting(const Load& target, RodSolution* sol, internal::FoldTracker* folds, int segments);
  double stability_indicator();
  void load_from_rest_if_unstable(const Load& target, RodSolution* sol);
  double load_bound(const ActuatorInputs& q, const TipWrench& tip) const;
  void commit(const Mat3& R_tip, const Load& load, const Eval& e, const RodSolution& sol);
  RodSolution remember(const RodSolution& sol);
  CvodeWorkspace* cvode();

  GeneralRodModel model_;
  ShootingOptions settings_;
  std::vector<Station> stations_;  ///< tip (s = L) first, then toward the base; s = 0 is not one
  Mat3 unloaded_tip_ = Mat3::Identity();
  Vec3 unloaded_pos_ = Vec3::Zero();
  double unloaded_det_ = 0.0;
  std::unique_ptr<CvodeWorkspace> cvode_;
  bool have_solution_ = false;
  Mat3 R_tip_ = Mat3::Identity();
  Load load_;
  Eval eval_;
  double det_ = 0.0;
  Vec3 tip_pos_ = Vec3::Zero();
  RodSolution last_;
};

}  // namespace rod
}  // namespace hydrojet
