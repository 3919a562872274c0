// Solves the rod boundary-value problem of §3 by shooting from the tip to the base, and computes
// the body compliance C^b of §4 from forward-mode sensitivities of the converged solve.
// ROS-free (Eigen only). No heap allocation per solve (the shape output aside).
#pragma once

#include <string>
#include <vector>

#include "hydrojet_control/rod/integrators.h"
#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace rod {

struct ShootingSettings {
  IntegratorSettings integrator;
  double residual_tolerance = 1e-10;  ///< |log R(0)| [rad] at which the solve counts as converged
  int max_iterations = 30;            ///< Newton iterations per attempt
  double max_step = 0.8;              ///< largest Newton step in the tip rotation [rad]
  int max_continuation_steps = 256;   ///< load-continuation steps allowed when a start fails
};

/// Result of one static solve. `converged` is true only when the final residual is finite and
/// below ShootingSettings::residual_tolerance.
struct RodSolution {
  bool converged = false;
  int iterations = 0;           ///< Newton iterations (all attempts, continuation included)
  double residual = 0.0;        ///< |log R(0)| [rad] of the returned state
  Mat3 tip_rotation = Mat3::Identity();   ///< tip frame in the base frame
  Vec3 tip_position = Vec3::Zero();       ///< [m], base frame
  double jacobian_det = 0.0;    ///< det ∂r/∂x of the shooting Jacobian (sign change = fold)
  int rhs_evaluations = 0;
  int continuation_steps = 0;   ///< 0 when Newton converged without load continuation
  std::string message;          ///< why it did not converge (empty when it did)
};

/// Body compliance and its pieces. Rows: tip body twist (v, ω); columns: body wrench (f_b, l_b).
struct Compliance {
  bool ok = false;
  Mat6 body = Mat6::Zero();  ///< C^b
};

class ShootingSolver {
 public:
  ShootingSolver(const RodModel& model, const ShootingSettings& settings);

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
  const ShootingSettings& settings() const { return settings_; }
  void set_model(const RodModel& model);
  void set_settings(const ShootingSettings& settings) { settings_ = settings; }
  bool has_solution() const { return have_solution_; }
  const RodSolution& last_solution() const { return last_; }

 private:
  struct Load {
    TipWrench wrench;
    double gravity_scale = 1.0;
  };
  struct Eval {
    Vec3 r;      ///< residual log R(0)
    Mat3 J;      ///< ∂r/∂x
    Mat3 R0;
    Vec3 p0;
    Eigen::Matrix<double, 3, 3> deta0;  ///< η(0) per x-direction
    Eigen::Matrix<double, 3, 3> dp0;    ///< δp(0) per x-direction
    bool ok = false;
  };

  Eval evaluate(const Mat3& R_tip, const Load& load, int* rhs) const;
  bool newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last) const;
  template <int D>
  void setup_ode(RodOde<D>* ode, const Mat3& R_tip, const Load& load) const;
  Mat3 unloaded_tip_rotation() const;

  RodModel model_;
  ShootingSettings settings_;
  bool have_solution_ = false;
  Mat3 R_tip_ = Mat3::Identity();
  Load load_;
  Eval eval_;
  RodSolution last_;
};

}  // namespace rod
}  // namespace hydrojet
