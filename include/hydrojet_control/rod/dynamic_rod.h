// Dynamic Cosserat rod of the simulated HydroJet plant, after Till, Aloi & Rucker, "Real-time
// dynamics of soft and continuum robots based on Cosserat rod models", IJRR 38(6), 2019
// (referred to below as "Till"). ROS-free (Eigen only).
//
// Model (Till's Cosserat rod PDEs), s ∈ [0, L], t = time. Global (base-frame) internal force n and
// moment m; body-frame strains v, u, velocity q and angular velocity ω:
//   p_s = R v                        R_s = R û
//   n_s = R(ρA(ω̂ q + q_t) + c_d(q) q) − ρA g            (linear + quadratic drag, body frame)
//   m_s = R(ω̂ ρJ ω + ρJ ω_t) − p_s × n
//   q_s = v_t − û q + ω̂ v           ω_s = u_t − û ω       (kinematic compatibility)
// with Till's Kelvin–Voigt viscoelastic constitutive law (here B = τ_kv K)
//   n = R(K_se(v − e_z) + B_se v_t),  m = R(K_bt(u − ũ) + B_bt u_t),
//   K_se = diag(GA, GA, EA), K_bt = diag(EI_x, EI_y, GJ), B_se = τ_kv K_se, B_bt = τ_kv K_bt.
// Base (s = 0) clamped and at rest: p = 0, R = I, q = ω = 0.
// Tip (s = L): the capsule, a rigid body (mass m_t, tip-frame inertia J_t, centre at p(L)) under
// the follower wrench (f_b, l_b), gravity and drag:
//   n(L) = R f_b + m_t g − m_t R(ω̂ q + q_t) − R c_t(q) q
//   m(L) = R l_b − R(ω̂ J_t ω + J_t ω_t) − R c_ω ω
//
// Time discretisation: Till's BDF-α formula. For every variable y with a time derivative (here
// z = [v, u, q, ω], 12 numbers) at every spatial evaluation point,
//   y_t(i) ≈ c0 y(i) + y_h,   y_h = c1 y(i−1) + c2 y(i−2) + d1 y_t(i−1),
//   c0 = (1.5 + α)/(Δt(1 + α)), c1 = −2/Δt, c2 = (0.5 + α)/(Δt(1 + α)), d1 = α/(1 + α).
// α = 0 is BDF2 (L-stable), α = −0.5 the trapezoidal rule (no numerical dissipation); Till uses
// α = −0.2, which damps the highest frequencies by |d1| = 0.25 per step while second-order accurate.
// Substituting y_t into the PDEs gives Till's semi-discretised system, an ODE in s per time step;
// the strains follow from the internal forces by the diagonal linear solve
//   v = (K_se + c0 B_se)⁻¹(Rᵀn + K_se e_z − B_se v_h),  u = (K_bt + c0 B_bt)⁻¹(Rᵀm + K_bt ũ − B_bt u_h).
// BDF-α assumes equal steps; a step whose Δt differs from the previous one uses the one-step
// θ-method with the same high-frequency damping, θ = 1/(1 − d1) (first order for that one step).
//
// Space: a fixed grid of N nodes (N − 1 classic RK4 steps). The history is stored at every RK4
// stage point (4 per step, plus the tip), so each stage sees its own consistent time history. RK4
// (rather than Till's explicit Euler) is 4th order: with N = 21 the static HydroJet tip agrees with
// a fine solution to ≈1e-7 m and ≈1e-6 rad even when strongly bent (≈2e-5 rad with N = 11).
//
// Shooting (as in Till): unknowns n(0), m(0) (6); residual: the tip boundary condition above (6).
// Newton with a finite-difference Jacobian that is kept across time steps and refined by Broyden
// rank-one updates (refreshed when the contraction is poor), damped by a residual/natural-
// monotonicity line search, warm-started by extrapolating the previous steps' base values
// (quadratically at constant Δt; the linear extrapolation and the previous values are tried when
// that start is poor). If a step still fails, the interval is retried as 2, 4, ..., 16 substeps.
// No heap allocation per step: all arrays are sized in the constructor.
//
// Any follower-actuated rod: DynamicRodModel::rod gives segments (each with its own
// stiffness, precurvature and ρA), point loads and actuators. The grid then has a node on every
// segment end, load and actuator (the pieces between them get steps in proportion to their length,
// about `nodes` − 1 in all), and at such a node s_k the internal force and moment drop by the
// wrench applied there (as the static solver's jump conditions, with the point mass's inertia):
//   n(s_k⁺) = n(s_k⁻) − F_k,  m(s_k⁺) = m(s_k⁻) − M_k,
//   F_k = R (f_body + Σ q_i d_i) + f_base + m_k (g − R(ω̂q + q_t)),  M_k = R (l_body + Σ q_i p_i × d_i) + l_base;
// at the tip F_L, M_L join the capsule's boundary condition. Actuator inputs q: set_inputs().
//
// Static limit: with all time derivatives zero this is the static Cosserat rod; as EA, GA → ∞ it is
// the Kirchhoff rod of rod_model.h (RodSolver). The tip-position difference is about
// L·|n|/min(GA, EA) (shear + extension), ≈ 1.5e-7 m for the HydroJet at 0.16 N with the defaults.
//
// Dynamic stability (a property of the model, converged in N and Δt): the follower jet force can
// make the loaded equilibrium flutter. For the HydroJet (paper's Table 1, hanging, ρA = 0) with
// τ_kv = 0.01 s a tip-frame force above ≈0.2 N (any direction in the x–y plane) gives a growing
// oscillation that saturates in a whirling limit cycle (tip speeds 3–5 m/s); the threshold rises
// with damping (≈0.25 N at τ_kv = 0.02 s, ≈0.35 N at 0.03 s). Such steps then never settle to the
// RodSolver equilibrium. With τ_kv = 0 and violent forcing, the per-step problem can fail to
// converge (step() returns false); τ_kv ≥ 1e-3 s is recommended.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <string>
#include <vector>

#include "hydrojet_control/rod/rod_model.h"
#include "hydrojet_control/rod/rod_solver.h"

namespace hydrojet {
namespace rod {

/// The dynamic rod: its statics and what the dynamics add (damping, drag, inertia), and the
/// numerics of its time stepping. SI units. Defaults a plant file can set: config/plant.yaml. The RodModel supplies L,
/// EI_x, EI_y, GJ, ũ, ρA (used for both the body weight and the body's translational inertia), m_t and g, exactly as in
/// the quasi-static RodSolver, so both models share one static equilibrium (up to shear/extension).
///
/// ρA = 0 (the paper's massless body) is supported: the body is then a (visco)elastic spring
/// slaved to the capsule, whose mass and tip_inertia carry the dynamics. A small positive ρA (e.g.
/// 1e-3 kg/m) adds the body's own (higher) modes; either way the per-step problem is well posed.
struct DynamicRodModel {
  /// The robot's statics: segments (geometry, stiffness, ũ, ρA), point loads, actuators, m_t, gravity.
  rod::RodModel rod;
  double shear_stiffness = 1e5;  ///< GA [N]; stiff by default (≈1e6·EI/L² for HydroJet)
  double axial_stiffness = 1e5;  ///< EA [N]; stiff by default (nearly inextensible)
  /// τ_kv [s]: B_se = τ_kv K_se, B_bt = τ_kv K_bt. Mode damping ratio ζ ≈ τ_kv ω/2: with 0.01 s
  /// the HydroJet's first mode (≈5 Hz) has ζ ≈ 0.15, with the default 0.03 s (config/plant.yaml)
  /// ζ ≈ 0.5 (see the flutter note above for large forces).
  double kelvin_voigt_time = 0.03;
  double linear_drag = 0.0;         ///< c_lin, body drag [N s/m per m of rod] (body frame)
  double quadratic_drag = 0.0;      ///< c_quad, body drag [N s²/m² per m]: force −c_quad|q|q
  double tip_drag = 0.0;            ///< c_t, capsule linear drag [N s/m]
  double tip_quadratic_drag = 0.0;  ///< capsule quadratic drag [N s²/m²]: force −c|q|q
  double tip_angular_drag = 0.0;    ///< c_ω, capsule rotational drag [N m s/rad]
  /// J_t, capsule inertia about its centre, tip frame, diagonal [kg m²]. Default: a 2.58 g
  /// cylinder of radius ≈7 mm and length ≈15 mm (an estimate; the paper does not give it).
  Vec3 tip_inertia = Vec3(8e-8, 8e-8, 6e-8);
  /// ρI [kg m]: body rotational inertia per length; ρJ = ρI·diag(1, 1, 2). 0 = none.
  double rotational_inertia_per_length = 0.0;
  int nodes = 21;       ///< N spatial nodes (N − 1 RK4 steps), 2 ≤ N ≤ 2000
  double alpha = -0.2;  ///< BDF-α parameter in [−0.5, 0] (Till: −0.2)
  /// Newton stops when |residual| ≤ tolerance·F0, F0 = max(EI, GJ)/L² [N] (the residual is the tip
  /// force error [N] and the tip moment error / L), or at its round-off floor (1e-13 of the size of
  /// its terms) if that is larger.
  double tolerance = 1e-9;
  int max_iterations = 15;  ///< Newton iterations per attempt
  /// When a step's boundary-value problem does not converge, step() retries the interval as 2, 4,
  /// ..., 2^max_substep_halvings equal substeps (same wrench) before reporting failure. 0..10.
  int max_substep_halvings = 4;

  /// Empty if valid, otherwise a message naming the first bad field (e.g. "shear_stiffness ...").
  std::string validate() const;
};

/// Dynamic Cosserat rod with BDF-α time stepping and per-step shooting. Not thread-safe.
class DynamicRod {
 public:
  /// Throws std::invalid_argument with DynamicRodModel::validate()'s message if invalid.
  /// The rod starts at rest at the static equilibrium under a zero tip wrench (reset_to_static is
  /// called); if that fails, last_error() says so and step() refuses until a reset succeeds.
  explicit DynamicRod(const DynamicRodModel& model);

  /// Puts the rod at rest in the static equilibrium under the tip wrench `w` (same model, same
  /// grid, all velocities zero, history consistent with rest) and sets time() to 0. Initialised
  /// from the quasi-static rod::RodSolver, then refined on this model (finite GA, EA).
  /// Returns false (state unchanged) and sets last_error() if no equilibrium was found.
  bool reset_to_static(const rod::TipWrench& w);

  /// Advances by dt [s] under the tip wrench w (held over the step; implicit: w is the wrench at
  /// the end of the step). Returns false and sets last_error() if the wrench or dt is invalid or
  /// the boundary-value problem did not converge; the state is then unchanged.
  bool step(const rod::TipWrench& w, double dt);

  Mat3 tip_rotation() const;           ///< R(L), tip frame in the base frame (orthonormalised)
  Vec3 tip_position() const;           ///< p(L) [m], base frame
  Vec3 tip_velocity() const;           ///< R(L) q(L) [m/s], base frame
  Vec3 tip_angular_velocity() const;   ///< R(L) ω(L) [rad/s], base frame
  std::vector<Vec3> backbone() const;  ///< the node positions [m], base to tip, base frame
  Vec3 base_force() const;             ///< n(0) [N], base frame: force the rod exerts on the mount
  Vec3 base_moment() const;            ///< m(0) [N m], base frame: moment on the mount

  /// Actuator inputs q [N], one per body.actuators in order, held from the next step (or reset) on.
  /// False (inputs unchanged, last_error() says why) for a wrong count or a non-finite entry.
  bool set_inputs(const rod::InputVector& q);

  /// Sets g [m/s²] in the base frame (a tilted base); takes effect from the next step. A
  /// non-finite vector is ignored and reported through last_error().
  void set_gravity(const Vec3& g);
  Vec3 gravity() const { return model_.rod.gravity; }

  int last_iterations() const { return last_iterations_; }    ///< Newton iterations, last call
  int last_substeps() const { return last_substeps_; }        ///< substeps the last step() used
  int last_evaluations() const { return last_evaluations_; }  ///< shooting passes, last solve
  std::string last_error() const { return last_error_; }      ///< empty after a success
  double time() const { return time_; }                       ///< [s] since the last reset
  const DynamicRodModel& model() const { return model_; }

 private:
  using Vec12 = Eigen::Matrix<double, 12, 1>;
  using Vec24 = Eigen::Matrix<double, 24, 1>;
  using Mat12X = Eigen::Matrix<double, 12, Eigen::Dynamic>;

  struct Coefficients {
    double c0 = 0.0;
    double c1 = 0.0;
    double c2 = 0.0;
    double d1 = 0.0;
  };

  template <bool kRecord>
  void rhs(const Vec24& y, int slot, Vec24& dy, Mat12X* rec) const;
  /// One shooting pass from the base with unknowns x = [n(0); m(0)/L]; returns the scaled tip
  /// residual. Records z at every slot into `rec` and node states into `nodes` when non-null.
  Vec6 pass(const Vec6& x, const rod::TipWrench& w, Mat12X* rec, std::vector<Vec24>* nodes);
  /// Newton–Broyden solve of the base unknowns x for the current step (quasi-Newton: the Jacobian
  /// of earlier steps is kept while c0 is unchanged, unless full_newton). False with last_error().
  bool newton(Vec6* x, const rod::TipWrench& w, bool full_newton, const Vec6* alternatives = nullptr,
              int n_alternatives = 0);
  // Newton's steps.
  /// The residual r at *x, or at the best of the alternatives when *x is a poor predictor (*x then
  /// becomes it); returns |r|, *scale the size of the residual's terms there.
  double best_start(Vec6* x, const rod::TipWrench& w, const Vec6* alternatives, int n_alternatives, Vec6* r,
                    double* scale);
  /// Convergence tolerance [N] for a residual whose terms have size `scale` [N].
  double newton_tolerance(double scale) const;
  /// Refreshes the Jacobian unless the one of earlier steps can be reused.
  bool prepare_jacobian(const Vec6& x, const Vec6& r, const rod::TipWrench& w, bool full_newton);
  /// Forward-difference Jacobian at x (residual r) and its LU; false (last_error()) when singular.
  bool refresh_jacobian(const Vec6& x, const Vec6& r, const rod::TipWrench& w);
  /// Damped Newton step along dx from x: true with the accepted trial *xt, its residual *rt and
  /// damping *lambda; false when no trial passes (or the Jacobian is outdated and should be refreshed).
  bool line_search(const Vec6& x, const Vec6& dx, double rn, const rod::TipWrench& w, Vec6* xt, Vec6* rt,
                   double* lambda);
  /// Broyden rank-one update of the Jacobian with the accepted step x → xt.
  void broyden_update(const Vec6& x, const Vec6& xt, const Vec6& r, const Vec6& rt);
  /// Sets last_error() and returns false.
  bool fail(const std::string& message);
  /// One implicit time step of size dt; commits the state only on success.
  bool advance(const rod::TipWrench& w, double dt);
  void set_coefficients(const Coefficients& c);
  Vec6 static_guess(const rod::TipWrench& w, bool* ok);
  /// The grid: pieces between segment ends, loads and actuators; the loads at the nodes.
  void build_grid();
  /// ρA g [N/m] of every piece for the current gravity.
  void update_distributed_weight();

  /// Uniform material of the steps between two load nodes.
  struct Piece {
    Vec3 k_bt, kbt_ustar, b_bt, inv_bt;
    double rho_a = 0.0;
    Vec3 dist_weight = Vec3::Zero();  ///< ρA g [N/m], base frame, for the current solve
  };
  /// What acts at one node besides the rod: point loads and actuators.
  struct NodeLoad {
    double mass = 0.0;
    Vec3 f_body = Vec3::Zero(), l_body = Vec3::Zero(), f_base = Vec3::Zero(), l_base = Vec3::Zero();
    std::vector<int> actuators;  ///< indices into body.actuators
  };
  /// The wrench (F, M) [N, N m], base frame, that `load` applies at a node in state y (slot: its
  /// history for the point mass's acceleration).
  void node_wrench(const NodeLoad& load, const Vec24& y, int slot, Vec3* F, Vec3* M) const;

  DynamicRodModel model_;
  // Derived constants.
  double length_ = 0.0, force_scale_ = 1.0;
  int steps_ = 0, slots_ = 0;
  Vec3 k_se_, kse_vstar_, b_se_, inv_se_, rho_j_;
  std::vector<Piece> pieces_;
  std::vector<int> step_piece_;  ///< piece of each step
  std::vector<double> step_h_;   ///< length of each step [m]
  std::vector<double> node_s_;   ///< arc length of each node [m]
  std::vector<int> node_load_;   ///< per node: index into node_loads_, or −1
  std::vector<NodeLoad> node_loads_;
  rod::InputVector inputs_;
  double residual_scale_ = 0.0;  // magnitude of the terms in the last residual [N]
  bool drag_active_ = false;
  Coefficients coef_;

  // History per evaluation slot (columns): z = [v, u, q, ω] at t(i−1), t(i−2), z_t at t(i−1), and
  // the current step's y_h.
  Mat12X z1_, z2_, zt1_, zh_;
  Mat12X rec_, rec_trial_;  // z of the accepted / trial pass in the current solve
  std::vector<Vec24> nodes_, nodes_solve_, nodes_trial_;
  Mat12X snap_z1_, snap_z2_, snap_zt1_;  // state snapshot for the substepping fallback
  std::vector<Vec24> snap_nodes_;
  bool at_rest_history_ = true;            // z1 == z2, zt1 == 0: valid for any dt
  double dt_prev_ = 0.0, dt_prev2_ = 0.0;  // the last two step sizes [s] (0: at rest, any)

  // Base unknowns [n(0); m(0)/L] now, one and two steps back (warm start).
  Vec6 x_ = Vec6::Zero(), x_prev_ = Vec6::Zero(), x_prev2_ = Vec6::Zero();
  bool initialised_ = false;

  // Shooting Jacobian (scaled), kept across steps while c0 is unchanged.
  Mat6 jac_ = Mat6::Identity();
  Eigen::PartialPivLU<Mat6> lu_;
  bool jac_valid_ = false;
  bool jac_fresh_ = false;
  double jac_c0_ = -1.0;

  double time_ = 0.0;
  int last_iterations_ = 0;
  int last_evaluations_ = 0;
  int last_substeps_ = 1;
  std::string last_error_;
};

}  // namespace rod
}  // namespace hydrojet
