// Solves the rod boundary-value problem of §3 by shooting from the tip to the base, and computes
// the body compliance C^b of §4 from forward-mode sensitivities of the converged solve.
// ROS-free (Eigen; SUNDIALS behind the cvode-* integrators and the KINSOL Newton option).
// No heap allocation per single-shooting solve with the Eigen integrators (the shape output, the
// multiple-shooting fallback and the first use of a CVODE/KINSOL memory aside).
//
// Robustness ladder of solve(): damped Newton from the warm start (or the unloaded shape) →
// load continuation from the warm solution → load continuation from the unloaded shape →
// accuracy check → multiple shooting (shooting_segments = 0, automatic) on the same load path
// (src/rod/load_path.h) → fold/branch report. Multiple shooting cuts the rod into M segments
// whose node states (R_k, u_k) become unknowns, so that the exponential growth exp(λL),
// λ ≈ √(|n|/EI), of single shooting's sensitivities is split into exp(λL/M) pieces; long (L × 10)
// and very soft (EI × 1e-3) rods need it.
//
// The model (RodModel, ShootingOptions, the compiled variant, the unloaded shape) is read-only
// between set_model()/set_settings() calls; the integrator memories live in a workspace that only
// the non-const methods use, and const methods change nothing.
#pragma once

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
}

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
  /// Right-hand side compiled for the scene's terms only (RodTerms chosen by needed_terms()).
  /// false: the general variant (every term, Cosserat form) — for benchmarks and checks.
  bool specialize_model = true;
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

/// Body compliance and its pieces. Rows: tip body twist (v, ω); columns: body wrench (f_b, l_b).
struct Compliance {
  bool ok = false;
  Mat6 body = Mat6::Zero();  ///< C^b
};

class ShootingSolver {
 public:
  ShootingSolver(const RodModel& model, const ShootingOptions& settings);

  /// Solves for the given tip wrench, warm-started from the last converged solution (or from the
  /// unloaded shape if none). Falls back to load continuation when Newton does not converge.
  RodSolution solve(const TipWrench& wrench);
  /// Forgets the warm start: the next solve starts cold from the unloaded (precurved) shape.
  void reset();

  /// C^b at the last converged solution (eq. 19's C^b, Rucker & Webster 2011), including the
  /// follower-load term: not symmetric.
  Compliance compliance();
  /// K+1 backbone points [m] from base to tip (base frame) at the last converged solution.
  std::vector<Vec3> shape(int segments) const;

  const RodModel& model() const { return model_; }
  const ShootingOptions& settings() const { return settings_; }
  /// A new model or new settings: the compiled variant and the unloaded shape are recomputed (one
  /// integration); set_model() also forgets the warm start.
  void set_model(const RodModel& model);
  void set_settings(const ShootingOptions& settings);
  bool has_solution() const { return have_solution_; }
  const RodSolution& last_solution() const { return last_; }
  /// The compiled right-hand-side variant in use, e.g. "kirchhoff+precurved" or "general".
  const char* variant_name() const;
  /// Estimated growth rate λL = L·√(|n|max / EI_min) of the shooting sensitivities for a wrench
  /// (single shooting loses ~λL/ln 10 digits).
  double growth_estimate(const TipWrench& wrench) const;
  /// Above this λL the automatic mode (shooting_segments = 0) starts with multiple shooting.
  static constexpr double kSingleShootingGrowthLimit = 12.0;

 private:
  struct Load {
    TipWrench wrench;
    double gravity_scale = 1.0;
    static Load none() { return Load{TipWrench(), 0.0}; }
  };
  struct Eval {
    Vec3 r;  ///< residual log R(0)
    Mat3 J;  ///< ∂r/∂x
    Mat3 R0;
    Vec3 p0;
    Eigen::Matrix<double, 3, 3> deta0;  ///< η(0) per x-direction
    Eigen::Matrix<double, 3, 3> dp0;    ///< δp(0) per x-direction
    bool ok = false;
  };
  /// Multiple-shooting unknowns: node orientations and curvatures at s_k = k L / M (k = 1..M−1)
  /// and the tip orientation R[M].
  struct Nodes {
    int segments = 0;
    std::vector<Mat3> R;
    std::vector<Vec3> u;
  };
  struct MsEval;
  /// Single and multiple shooting posed for the shared load path (src/rod/load_path.h).
  struct SingleShooting;
  struct MultipleShooting;
  /// The unloaded equilibrium (zero load, u(s) = ũ), where every cold load path starts. Part of the
  /// model: computed by the constructor, set_model and set_settings.
  struct UnloadedShape {
    Mat3 tip_rotation = Mat3::Identity();  ///< exp(L ũ^)
    Vec3 tip_position = Vec3::Zero();
    double det = 0.0;  ///< det ∂r/∂x (NaN if the evaluation failed)
  };
  /// Function table of one compiled model variant (src/rod/kernels/, chosen with the model).
  struct Kernels {
    Eval (ShootingSolver::*evaluate)(const Mat3& R_tip, const Load& load, int* rhs);
    bool (ShootingSolver::*compliance)(Mat6* C);
    double (ShootingSolver::*error)(const Mat3& R_tip, const Load& load, const Eval& e);
    const char* name;
  };
  /// The mutable memory of the solves (the model and the settings are the read-only part): CVODE
  /// and KINSOL memories, created on first use. A copied solver starts with none.
  class Workspace {
   public:
    Workspace();
    ~Workspace();
    Workspace(const Workspace&) : Workspace() {}
    Workspace& operator=(const Workspace&) { return *this; }
    /// Integrates a RodOde from s0 to s1 with the integrator of `is` (src/rod/solver_templates.h).
    template <class Ode>
    IntegrationStats integrate(const Ode& ode, double s0, double s1, typename Ode::State* y,
                               const IntegratorOptions& is);
    KinsolWorkspace& kinsol();

   private:
    std::unique_ptr<CvodeWorkspace> cvode_;
    std::unique_ptr<KinsolWorkspace> kinsol_;
  };

  // The steps of solve() (shooting_solver.cpp).
  RodSolution remember(const RodSolution& sol);
  static RodSolution non_finite_wrench();
  bool multiple_shooting_first(const TipWrench& wrench) const;
  int first_segments(const Load& target) const;
  bool fall_back_to_multiple(const Load& target, RodSolution* sol);
  bool accuracy_check_applies() const;
  bool accurate_enough(RodSolution* sol, int segments) const;
  bool converged(bool ok, const RodSolution& sol) const;
  static const RodSolution& report_folds(const internal::FoldTracker& folds, RodSolution* sol);
  double stability_indicator();
  void load_from_rest_if_unstable(const Load& target, RodSolution* sol);
  Vec6 softest_push(const Mat6& compliance_body, const Load& target) const;

  // Single shooting (shooting_solver.cpp, kinsol_newton.cpp, kernels/).
  Eval evaluate(const Mat3& R_tip, const Load& load, int* rhs) { return (this->*kernels_->evaluate)(R_tip, load, rhs); }
  template <class T>
  Eval evaluate_t(const Mat3& R_tip, const Load& load, int* rhs);
  template <class T>
  bool compliance_t(Mat6* C);
  template <class T>
  double error_t(const Mat3& R_tip, const Load& load, const Eval& e);
  bool newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last);
  bool newton_kinsol(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last);
  void commit_single(const Mat3& R_tip, const Load& load, const Eval& e, const RodSolution& sol);
  template <class Ode>
  void setup_ode(Ode* ode, const Mat3& R_tip, const Load& load) const;
  void select_kernels();
  void update_unloaded_shape();

  // Multiple shooting (multiple_shooting.cpp).
  int auto_segments(const Load& load) const;
  bool ms_solve(const Load& target, int segments, RodSolution* sol);
  Nodes ms_stored_nodes(int segments);
  bool ms_newton(Nodes* x, const Load& load, RodSolution* sol, double* det);
  template <bool kWithWrench>
  bool ms_assemble(const Nodes& x, const Load& load, MsEval* e, int* rhs, int steps_per_segment = 0);
  double ms_error_estimate(const Nodes& x, const Load& load);
  bool ms_compliance(Mat6* C);
  void commit_multiple(const Nodes& x, const Load& load, double det, const RodSolution& sol);
  Nodes ms_unloaded_nodes(int segments) const;
  Nodes ms_nodes_from_tip(const Mat3& R_tip, const Load& load, int segments);
  Nodes ms_resample(const Nodes& x, const Load& load, int segments);

  // The model (read-only outside the constructor, set_model and set_settings).
  RodModel model_;
  ShootingOptions settings_;
  const Kernels* kernels_ = nullptr;
  UnloadedShape unloaded_;
  // The workspace.
  Workspace workspace_;
  // The last converged equilibrium: the warm start of the next solve, and where compliance() and
  // shape() are evaluated.
  bool have_solution_ = false;
  Mat3 R_tip_ = Mat3::Identity();
  Load load_;
  Eval eval_;
  double det_ = 0.0;             ///< det ∂r/∂x of the stored solution (fold tracking)
  Vec3 tip_pos_ = Vec3::Zero();  ///< tip position of the stored solution (jump detection)
  bool multiple_ = false;        ///< the stored solution came from multiple shooting (nodes_ holds it)
  Nodes nodes_;
  RodSolution last_;  ///< the result of the last solve (converged or not)
};

}  // namespace rod
}  // namespace hydrojet
