// The static solve of a follower-actuated rod (rod_model.h: segments, point loads, actuators) by
// shooting from the tip to the base (§7.2), with the body compliance C^b of §4 and the actuation
// Jacobian J_q = ∂(v, ω)_tip/∂q from forward-mode sensitivities of the converged solve. One solver
// for every robot: the HydroJet (one uniform segment, three jets at the tip) and any other.
// ROS-free (Eigen; SUNDIALS behind the cvode-* integrators and the KINSOL Newton option).
//
// Why one unknown suffices: the only distributed force is the body weight ρA·g (constant in the base
// frame per segment) and every point load or actuator is known once the frame R(s) at its arc length
// is, so integrating from the tip with a guessed R(L) gives n(s) and m(s) everywhere. The rod is cut
// at stations (segment ends, load and actuator arc lengths); between two stations the right-hand side
// is RodOde (eq. 14) with that segment's K, ũ, ρA; at a station s_k the internal wrench jumps by what
// is applied there (the jump conditions):
//   n(s_k⁻) = n(s_k⁺) + R(s_k) f_follower + f_dead + m_k g            (base frame)
//   M_b(s_k⁻) = M_b(s_k⁺) + l_follower + R(s_k)ᵀ l_dead                (body frame)
//   u(s_k⁻) = ũ⁻ + K⁻⁻¹ M_b(s_k⁻)                  (the moment is continuous across a material change)
// with f_follower, l_follower the follower loads and the actuators' q_i·(d_i, p_i × d_i). The tip is
// the station s = L with n(L⁺) = 0, M_b(L⁺) = 0 (eq. 16 with eq. 13 there).
//
// The fast path is chosen inside, at model load: the right-hand side is compiled for the model's
// terms only (RodTerms), and when every actuator sits at the tip of one uniform segment (the
// HydroJet) J_q = C^b W comes without sensitivity directions of its own.
//
// Robustness ladder of solve(): damped Newton from the warm start (or the unloaded shape) → load
// continuation from the warm solution → from the unloaded shape (src/rod/load_path.h) → accuracy
// check (fixed-step integrators) → multiple shooting (shooting_segments = 0: automatic) on the same
// load path → fold/branch report → for a cold solve, the stability check (an equilibrium the rod
// cannot hold is loaded again from rest with a push). Multiple shooting cuts the rod into M pieces
// whose node states become unknowns, so that the growth exp(λL), λ ≈ √(|n|/EI), of single shooting's
// sensitivities is split into exp(λL/M) pieces; long (L × 10) and very soft (EI × 1e-3) rods need it.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "hydrojet_control/rod/integrators.h"
#include "hydrojet_control/rod/rod_model.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace rod {

class CvodeWorkspace;
class KinsolWorkspace;
namespace internal {
struct FoldTracker;
}  // namespace internal

/// Which Newton iteration solves the 3-unknown shooting problem.
enum class NewtonBackend {
  kEigen,   ///< damped Newton with backtracking (the default: measured faster, same robustness)
  kKinsol,  ///< SUNDIALS KINSOL (line search, exact Jacobian from the sensitivities)
};

struct ShootingOptions {
  IntegratorOptions integrator;
  double residual_tolerance = 1e-10;  ///< |log R(0)| [rad] at which the solve counts as converged
  int max_iterations = 30;            ///< Newton iterations per attempt
  double max_step = 0.8;              ///< largest Newton step in the tip rotation [rad]
  int max_continuation_steps = 256;   ///< load-continuation steps allowed when a start fails
  /// Right-hand side compiled for the model's terms only (RodTerms chosen by needed_terms()).
  /// false: the general variant (every term, Cosserat form) — for benchmarks and checks.
  bool specialise_model = true;
  /// 0: automatic (single shooting; multiple shooting when that fails); 1: single shooting only;
  /// M ≥ 2: always multiple shooting with M equal segments.
  int shooting_segments = 0;
  NewtonBackend newton = NewtonBackend::kEigen;
  /// A cold solve (no warm start) whose direct Newton lands on an equilibrium with stability
  /// indicator ≤ 0 on these components (stability(C^b, ...).eig_min; the scene's tip.actuated) is
  /// done again: loaded from rest with a small push along the softest direction, the push then
  /// taken away along the load path (this reaches the stable, buckled branch of a column loaded
  /// past buckling); if that also ends unstable, the solution says so in `warning`. All false: no
  /// check (cold solves then cost no C^b).
  ActuatedSet cold_stability_check = lateral_force_actuation();
  /// Fixed-step methods (rk4, rk8) only: after convergence the tip-position error of the
  /// discretisation is estimated (Richardson: one state-only integration with half the steps,
  /// carried through the shooting Jacobian) and a solve whose estimate exceeds
  /// accuracy_tolerance·L is reported as not converged ("more steps needed"). About 0.4 µs per
  /// solve for rk8 with 4 steps. 0 disables the check. Adaptive methods control their local error
  /// with `integrator.tolerance` instead.
  double accuracy_tolerance = 1e-5;
};

/// Result of one static solve. `converged` is true only when the final residual is finite and
/// below ShootingOptions::residual_tolerance.
struct RodSolution {
  bool converged = false;
  int iterations = 0;                    ///< Newton iterations (all attempts, continuation included)
  double residual = 0.0;                 ///< |log R(0)| [rad] of the returned state
  Mat3 tip_rotation = Mat3::Identity();  ///< tip frame in the base frame
  Vec3 tip_position = Vec3::Zero();      ///< [m], base frame
  double jacobian_det = 0.0;             ///< det ∂r/∂x of the shooting Jacobian (sign change = fold)
  int rhs_evaluations = 0;
  int continuation_steps = 0;  ///< 0 when Newton converged without load continuation
  std::string message;         ///< why it did not converge (empty when it did)
  int segments = 1;            ///< shooting segments of the returned solution (1 = single shooting)
  /// Estimated tip-position error of a fixed-step integration [m] (NaN when not estimated: adaptive
  /// integrators, multiple shooting, accuracy_tolerance = 0).
  double error_estimate = std::numeric_limits<double>::quiet_NaN();
  /// Sign changes of det ∂r/∂x between consecutive equilibria of this solve's load path (warm
  /// start or unloaded shape → continuation steps → result). Non-zero: the path crossed a fold or
  /// bifurcation; the result may lie on another branch than the start, or be unstable.
  int fold_crossings = 0;
  std::string warning;  ///< set with fold_crossings (empty otherwise)
};

/// J_q: 6 rows (tip body twist v, ω) × one column per actuator input.
using ActuationJacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxInputs>;

/// C^b (tip body wrench → tip body twist) and J_q at one equilibrium. Rows: tip body twist (v, ω).
struct Compliance {
  bool ok = false;
  Mat6 body = Mat6::Zero();                                     ///< C^b: columns (f_b, l_b) at the tip
  ActuationJacobian actuation = ActuationJacobian::Zero(6, 0);  ///< J_q [m/N; rad/N]: column i per unit input q_i
};

class RodSolver {
 public:
  /// The model must be valid (RodModel::validate() empty): std::invalid_argument naming the field otherwise.
  RodSolver(const RodModel& model, const ShootingOptions& options);
  ~RodSolver();
  RodSolver(const RodSolver& other);
  RodSolver& operator=(const RodSolver& other);

  /// Solves for actuator inputs q (input_count() entries, any value: bounds are the allocation's
  /// business) and an extra follower wrench at the tip (tip frame), warm-started from the last
  /// converged solution (or from the unloaded shape if none).
  RodSolution solve(const InputVector& q, const TipWrench& tip = TipWrench());
  /// The tip wrench alone (every input zero).
  RodSolution solve(const TipWrench& tip) { return solve(InputVector::Zero(input_count()), tip); }
  /// Forgets the warm start: the next solve starts cold from the unloaded (precurved) shape.
  void reset();

  /// C^b (eq. 19's C^b, Rucker & Webster 2011, with the follower-load term: not symmetric) and J_q at
  /// the last converged solution (implicit function theorem on the shooting residual).
  Compliance compliance();
  /// K+1 backbone points [m] from base to tip (base frame) at the last converged solution, at equal
  /// arc-length spacing over the whole rod.
  std::vector<Vec3> shape(int points_minus_one) const;
  /// The frame of the backbone at arc length s ∈ [0, L] (base frame) at the last converged solution.
  bool frame_at(double s, Mat3* R, Vec3* p) const;

  const RodModel& model() const { return model_; }
  const ShootingOptions& options() const { return options_; }
  /// A new model (validated as by the constructor) or new options: the stations, the compiled variant
  /// and the unloaded shape are recomputed (one integration); set_model() also forgets the warm start.
  void set_model(const RodModel& model);
  void set_options(const ShootingOptions& options);
  int input_count() const { return model_.input_count(); }
  bool has_solution() const { return have_solution_; }
  const RodSolution& last_solution() const { return last_; }
  /// The compiled right-hand-side variant in use, e.g. "kirchhoff+precurved" or "general".
  const char* variant_name() const;
  /// Estimated growth rate λL = L·√(|n|max / EI_min) of the shooting sensitivities for these loads
  /// (single shooting loses ~λL/ln 10 digits).
  double growth_estimate(const InputVector& q, const TipWrench& tip) const;
  double growth_estimate(const TipWrench& tip) const { return growth_estimate(InputVector::Zero(input_count()), tip); }
  /// Above this λL the automatic mode (shooting_segments = 0) starts with multiple shooting.
  static constexpr double kSingleShootingGrowthLimit = 12.0;

  /// What loads the rod at one solve: the tip wrench, the inputs, and a scale of the fixed loads
  /// (gravity, point loads) that load continuation ramps from 0 to 1.
  struct Load {
    TipWrench wrench;
    InputVector q;
    double gravity_scale = 1.0;
  };
  /// Where the rod is cut (exposed for tests and docs).
  struct Station {
    double s = 0.0;                                     ///< arc length [m]
    int segment_below = 0;                              ///< segment of the piece just below s (toward the base)
    Vec3 f_body = Vec3::Zero(), l_body = Vec3::Zero();  ///< fixed follower loads [N, N m], body frame
    Vec3 f_base = Vec3::Zero(), l_base = Vec3::Zero();  ///< fixed dead loads [N, N m], base frame
    double mass = 0.0;                                  ///< point masses here (tip mass at L) [kg]
    std::vector<int> actuators;                         ///< actuators applied here
  };
  /// Tip (s = L) first, then toward the base; s = 0 is not one.
  const std::vector<Station>& stations() const { return stations_; }

 private:
  /// One evaluation of single shooting at a tip orientation: the residual, its Jacobian, the base frame.
  struct Eval {
    Vec3 r = Vec3::Zero();  ///< residual log R(0)
    Mat3 J = Mat3::Zero();  ///< ∂r/∂x
    Mat3 R0 = Mat3::Identity();
    Vec3 p0 = Vec3::Zero();
    Mat3 dp0 = Mat3::Zero();  ///< δp(0) per x-direction
    bool ok = false;
  };
  /// The mutable memory of the solves (the model and the options are the read-only part): CVODE and
  /// KINSOL memories, created on first use. A copied solver starts with none.
  class Workspace {
   public:
    Workspace();
    ~Workspace();
    Workspace(const Workspace&) : Workspace() {}
    Workspace& operator=(const Workspace&) { return *this; }
    /// The CVODE memory for the cvode-* integrators (null for the others).
    CvodeWorkspace* cvode(IntegratorType type);
    KinsolWorkspace& kinsol();

   private:
    std::unique_ptr<CvodeWorkspace> cvode_;
    std::unique_ptr<KinsolWorkspace> kinsol_;
  };

  struct Shooting;  // single shooting posed for the load path (load_path.h)
  struct Nodes;     // multiple shooting's unknowns
  struct MultipleShooting;
  struct MsEval;
  /// The sweeps of one compiled variant (src/rod/kernels/): the Newton evaluation (3 directions),
  /// up to 6 compliance directions, the state alone (Richardson estimate, shape), the node sweeps.
  struct Kernels;

  // The model (read-only outside the constructor and set_options).
  void build_stations();
  void select_kernels();
  void update_unloaded_shape();
  Load no_load() const;
  double load_bound(const InputVector& q, const TipWrench& tip) const;

  // Single shooting (rod_solver.cpp, kinsol_newton.cpp).
  Eval evaluate(const Mat3& R_tip, const Load& load, int* rhs);
  double error_estimate(const Mat3& R_tip, const Load& load, const Eval& e);
  bool newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last);
  bool newton_kinsol(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last);
  bool finish(Shooting* p, bool ok, internal::FoldTracker* folds);
  bool accuracy_check_applies() const;
  bool accurate_enough(RodSolution* sol, int segments) const;
  double stability_indicator();
  void load_from_rest_if_unstable(const Load& target, RodSolution* sol);
  void commit(const Mat3& R_tip, const Load& load, const Eval& e, const RodSolution& sol);
  RodSolution remember(const RodSolution& sol);
  bool multiple_shooting_first(const Load& target) const;
  bool predict(const Load& target, Mat3* guess) const;

  // Multiple shooting (multiple_shooting.cpp).
  int auto_segments(const Load& load) const;
  bool ms_solve(const Load& target, int segments, RodSolution* sol);
  bool ms_nodes(const Mat3& R_tip, const Load& load, int M, Nodes* x);
  bool ms_evaluate(const Nodes& x, const Load& load, MsEval* e, int* rhs, int step_multiplier = 1);
  double ms_error_estimate(const Nodes& x, const Load& load);

  RodModel model_;
  ShootingOptions options_;
  std::vector<Station> stations_;
  const Kernels* kernels_ = nullptr;
  Mat3 unloaded_tip_ = Mat3::Identity();
  Vec3 unloaded_pos_ = Vec3::Zero();
  double unloaded_det_ = 0.0;
  Workspace workspace_;
  // The last converged equilibrium: the warm start of the next solve, and where compliance() and
  // shape() are evaluated.
  bool have_solution_ = false;
  Mat3 R_tip_ = Mat3::Identity();
  Load load_;
  Eval eval_;
  double det_ = 0.0;             ///< det ∂r/∂x of the stored solution (fold tracking)
  Vec3 tip_pos_ = Vec3::Zero();  ///< tip position of the stored solution (jump detection)
  RodSolution last_;             ///< the result of the last solve (converged or not)
  /// The tangent of the stored solution, from its compliance(): d x / d(f_b, l_b) and d x / dq, the
  /// tip rotation's change per unit load. The next warm solve starts from the first-order prediction.
  bool have_tangent_ = false;
  Eigen::Matrix<double, 3, 6> dx_dw_ = Eigen::Matrix<double, 3, 6>::Zero();
  Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxInputs> dx_dq_;
};

}  // namespace rod
}  // namespace hydrojet
