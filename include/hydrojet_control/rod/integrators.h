// Explicit Runge–Kutta integrators on fixed-size Eigen vectors: no heap allocation per call.
//   - rk4:    classic 4th-order method, N equal steps.
//   - rk8:    the 8th-order solution of Dormand & Prince's DOP853 tableau (Hairer, Nørsett & Wanner,
//             "Solving ODEs I", §II.10), N equal steps. The paper (§7.2) integrates with an
//             8th-order Runge–Kutta method.
//   - dopri5: Dormand–Prince 5(4) embedded pair with adaptive step size (local extrapolation, FSAL).
//   - cvode-adams, cvode-bdf: SUNDIALS CVODE(S), see cvode_integrator.h (the shooting solver owns
//             their memory and dispatches them; integrate() below covers the Eigen methods).
// The ODE is a functor `void f(double s, const Vec& y, Vec& dy)`; s may run backwards (s1 < s0).
// ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

namespace hydrojet {
namespace rod {

enum class IntegratorType { kRk4, kRk8, kDopri5, kCvodeAdams, kCvodeBdf };

/// Name used on the command line and in scene files ("rk4", "rk8", "dopri5", "cvode-adams",
/// "cvode-bdf").
const char* integrator_name(IntegratorType t);
/// Parses a name; returns false for an unknown one.
bool parse_integrator(const std::string& name, IntegratorType* out);
/// The accepted names, for error messages: "rk4, rk8, dopri5, cvode-adams, cvode-bdf".
const char* integrator_names();
/// True for the adaptive methods (dopri5 and the CVODE ones), which use `tolerance`, not `steps`.
inline bool is_adaptive(IntegratorType t) { return t != IntegratorType::kRk4 && t != IntegratorType::kRk8; }

struct IntegratorOptions {
  IntegratorType type = IntegratorType::kRk8;
  int steps = 4;            ///< equal steps over the rod for rk4 / rk8
  double tolerance = 1e-9;  ///< relative and absolute local error tolerance for adaptive methods
  int max_steps = 100000;   ///< adaptive methods give up (and report failure) past this many steps
  /// CVODE methods only: carry the sensitivities with CVODES' forward sensitivity analysis instead
  /// of integrating them as part of the state. Measured slower on every scene here (docs/
  /// work_precision.md), so off by default.
  bool cvodes_sensitivities = false;
};

/// Work counters of one integration.
struct IntegrationStats {
  int rhs_evaluations = 0;
  int steps = 0;
  int rejected_steps = 0;
  bool ok = true;                   ///< false when an adaptive method hit max_steps or the state became non-finite
  int sensitivity_evaluations = 0;  ///< CVODES sensitivity right-hand sides (all directions at once)
  int jacobian_evaluations = 0;     ///< CVODE BDF Jacobian evaluations
};

namespace detail {
// DOP853 coefficients (the 8th-order solution, stages 1–12).
struct Dop853 {
  static constexpr double c2 = 0.526001519587677318785587544488e-01;
  static constexpr double c3 = 0.789002279381515978178381316732e-01;
  static constexpr double c4 = 0.118350341907227396726757197510e+00;
  static constexpr double c5 = 0.281649658092772603273242802490e+00;
  static constexpr double c6 = 0.333333333333333333333333333333e+00;
  static constexpr double c7 = 0.25e+00;
  static constexpr double c8 = 0.307692307692307692307692307692e+00;
  static constexpr double c9 = 0.651282051282051282051282051282e+00;
  static constexpr double c10 = 0.6e+00;
  static constexpr double c11 = 0.857142857142857142857142857142e+00;

  static constexpr double a21 = 5.26001519587677318785587544488e-2;
  static constexpr double a31 = 1.97250569845378994544595329183e-2;
  static constexpr double a32 = 5.91751709536136983633785987549e-2;
  static constexpr double a41 = 2.95875854768068491816892993775e-2;
  static constexpr double a43 = 8.87627564304205475450678981324e-2;
  static constexpr double a51 = 2.41365134159266685502369798665e-1;
  static constexpr double a53 = -8.84549479328286085344864962717e-1;
  static constexpr double a54 = 9.24834003261792003115737966543e-1;
  static constexpr double a61 = 3.7037037037037037037037037037e-2;
  static constexpr double a64 = 1.70828608729473871279604482173e-1;
  static constexpr double a65 = 1.25467687566822425016691814123e-1;
  static constexpr double a71 = 3.7109375e-2;
  static constexpr double a74 = 1.70252211019544039314978060272e-1;
  static constexpr double a75 = 6.02165389804559606850219397283e-2;
  static constexpr double a76 = -1.7578125e-2;
  static constexpr double a81 = 3.70920001185047927108779319836e-2;
  static constexpr double a84 = 1.70383925712239993810214054705e-1;
  static constexpr double a85 = 1.07262030446373284651809199168e-1;
  static constexpr double a86 = -1.53194377486244017527936158236e-2;
  static constexpr double a87 = 8.27378916381402288758473766002e-3;
  static constexpr double a91 = 6.24110958716075717114429577812e-1;
  static constexpr double a94 = -3.36089262944694129406857109825e0;
  static constexpr double a95 = -8.68219346841726006818189891453e-1;
  static constexpr double a96 = 2.75920996994467083049415600797e1;
  static constexpr double a97 = 2.01540675504778934086186788979e1;
  static constexpr double a98 = -4.34898841810699588477366255144e1;
  static constexpr double a101 = 4.77662536438264365890433908527e-1;
  static constexpr double a104 = -2.48811461997166764192642586468e0;
  static constexpr double a105 = -5.90290826836842996371446475743e-1;
  static constexpr double a106 = 2.12300514481811942347288949897e1;
  static constexpr double a107 = 1.52792336328824235832596922938e1;
  static constexpr double a108 = -3.32882109689848629194453265587e1;
  static constexpr double a109 = -2.03312017085086261358222928593e-2;
  static constexpr double a111 = -9.3714243008598732571704021658e-1;
  static constexpr double a114 = 5.18637242884406370830023853209e0;
  static constexpr double a115 = 1.09143734899672957818500254654e0;
  static constexpr double a116 = -8.14978701074692612513997267357e0;
  static constexpr double a117 = -1.85200656599969598641566180701e1;
  static constexpr double a118 = 2.27394870993505042818970056734e1;
  static constexpr double a119 = 2.49360555267965238987089396762e0;
  static constexpr double a1110 = -3.0467644718982195003823669022e0;
  static constexpr double a121 = 2.27331014751653820792359768449e0;
  static constexpr double a124 = -1.05344954667372501984066689879e1;
  static constexpr double a125 = -2.00087205822486249909675718444e0;
  static constexpr double a126 = -1.79589318631187989172765950534e1;
  static constexpr double a127 = 2.79488845294199600508499808837e1;
  static constexpr double a128 = -2.85899827713502369474065508674e0;
  static constexpr double a129 = -8.87285693353062954433549289258e0;
  static constexpr double a1210 = 1.23605671757943030647266201528e1;
  static constexpr double a1211 = 6.43392746015763530355970484046e-1;

  static constexpr double b1 = 5.42937341165687622380535766363e-2;
  static constexpr double b6 = 4.45031289275240888144113950566e0;
  static constexpr double b7 = 1.89151789931450038304281599044e0;
  static constexpr double b8 = -5.8012039600105847814672114227e0;
  static constexpr double b9 = 3.1116436695781989440891606237e-1;
  static constexpr double b10 = -1.52160949662516078556178806805e-1;
  static constexpr double b11 = 2.01365400804030348374776537501e-1;
  static constexpr double b12 = 4.47106157277725905176885569043e-2;
};
}  // namespace detail

/// Classic RK4 with n equal steps from s0 to s1; y is advanced in place.
template <class F, class Vec>
IntegrationStats integrate_rk4(F& f, double s0, double s1, int n, Vec& y) {
  IntegrationStats st;
  const double h = (s1 - s0) / n;
  Vec k1, k2, k3, k4, t;
  double s = s0;
  for (int i = 0; i < n; ++i) {
    f(s, y, k1);
    t = y + (0.5 * h) * k1;
    f(s + 0.5 * h, t, k2);
    t = y + (0.5 * h) * k2;
    f(s + 0.5 * h, t, k3);
    t = y + h * k3;
    f(s + h, t, k4);
    y += (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4);
    s = s0 + (i + 1) * h;
  }
  st.rhs_evaluations = 4 * n;
  st.steps = n;
  st.ok = y.allFinite();
  return st;
}

/// One step of the DOP853 8th-order solution (12 RHS evaluations). Kept out of line: inlined into
/// its caller, GCC 12 produced code up to 15% slower for some right-hand-side variants.
template <class F, class Vec>
[[gnu::noinline]] void rk8_step(F& f, double s, double h, Vec& y) {
  using C = detail::Dop853;
  Vec k1, k4, k5, k6, k7, k8, k9, k10, k11, k12, t;
  // k2 and k3 only feed stages 3–4; reuse k11/k12 storage for them.
  Vec& k2 = k11;
  Vec& k3 = k12;
  f(s, y, k1);
  t = y + h * C::a21 * k1;
  f(s + C::c2 * h, t, k2);
  t = y + h * (C::a31 * k1 + C::a32 * k2);
  f(s + C::c3 * h, t, k3);
  t = y + h * (C::a41 * k1 + C::a43 * k3);
  f(s + C::c4 * h, t, k4);
  t = y + h * (C::a51 * k1 + C::a53 * k3 + C::a54 * k4);
  f(s + C::c5 * h, t, k5);
  t = y + h * (C::a61 * k1 + C::a64 * k4 + C::a65 * k5);
  f(s + C::c6 * h, t, k6);
  t = y + h * (C::a71 * k1 + C::a74 * k4 + C::a75 * k5 + C::a76 * k6);
  f(s + C::c7 * h, t, k7);
  t = y + h * (C::a81 * k1 + C::a84 * k4 + C::a85 * k5 + C::a86 * k6 + C::a87 * k7);
  f(s + C::c8 * h, t, k8);
  t = y + h * (C::a91 * k1 + C::a94 * k4 + C::a95 * k5 + C::a96 * k6 + C::a97 * k7 + C::a98 * k8);
  f(s + C::c9 * h, t, k9);
  t = y + h * (C::a101 * k1 + C::a104 * k4 + C::a105 * k5 + C::a106 * k6 + C::a107 * k7 + C::a108 * k8 + C::a109 * k9);
  f(s + C::c10 * h, t, k10);
  t = y + h * (C::a111 * k1 + C::a114 * k4 + C::a115 * k5 + C::a116 * k6 + C::a117 * k7 + C::a118 * k8 + C::a119 * k9 +
               C::a1110 * k10);
  f(s + C::c11 * h, t, k11);
  t = y + h * (C::a121 * k1 + C::a124 * k4 + C::a125 * k5 + C::a126 * k6 + C::a127 * k7 + C::a128 * k8 + C::a129 * k9 +
               C::a1210 * k10 + C::a1211 * k11);
  f(s + h, t, k12);
  y +=
      h * (C::b1 * k1 + C::b6 * k6 + C::b7 * k7 + C::b8 * k8 + C::b9 * k9 + C::b10 * k10 + C::b11 * k11 + C::b12 * k12);
}

/// Fixed-step 8th-order integration with n equal steps.
template <class F, class Vec>
IntegrationStats integrate_rk8(F& f, double s0, double s1, int n, Vec& y) {
  IntegrationStats st;
  const double h = (s1 - s0) / n;
  for (int i = 0; i < n; ++i) rk8_step(f, s0 + i * h, h, y);
  st.rhs_evaluations = 12 * n;
  st.steps = n;
  st.ok = y.allFinite();
  return st;
}

/// Dormand–Prince 5(4) with adaptive steps; error norm is the RMS over all components of
/// |err_i| / (tol + tol·|y_i|). Reports failure (ok = false) instead of looping forever.
template <class F, class Vec>
IntegrationStats integrate_dopri5(F& f, double s0, double s1, double tol, int max_steps, Vec& y) {
  IntegrationStats st;
  const double span = s1 - s0;
  const double dir = span >= 0.0 ? 1.0 : -1.0;
  double h = dir * std::min(std::abs(span), std::abs(span) * 0.1);
  double s = s0;
  Vec k1, k2, k3, k4, k5, k6, k7, t, y5, err;
  f(s, y, k1);
  st.rhs_evaluations = 1;
  while (dir * (s1 - s) > 1e-15 * std::abs(span)) {
    if (st.steps + st.rejected_steps >= max_steps) {
      st.ok = false;
      return st;
    }
    if (dir * (s + h - s1) > 0.0) h = s1 - s;
    t = y + h * (1.0 / 5.0) * k1;
    f(s + h / 5.0, t, k2);
    t = y + h * (3.0 / 40.0 * k1 + 9.0 / 40.0 * k2);
    f(s + 0.3 * h, t, k3);
    t = y + h * (44.0 / 45.0 * k1 - 56.0 / 15.0 * k2 + 32.0 / 9.0 * k3);
    f(s + 0.8 * h, t, k4);
    t = y + h * (19372.0 / 6561.0 * k1 - 25360.0 / 2187.0 * k2 + 64448.0 / 6561.0 * k3 - 212.0 / 729.0 * k4);
    f(s + 8.0 / 9.0 * h, t, k5);
    t = y + h * (9017.0 / 3168.0 * k1 - 355.0 / 33.0 * k2 + 46732.0 / 5247.0 * k3 + 49.0 / 176.0 * k4 -
                 5103.0 / 18656.0 * k5);
    f(s + h, t, k6);
    y5 = y +
         h * (35.0 / 384.0 * k1 + 500.0 / 1113.0 * k3 + 125.0 / 192.0 * k4 - 2187.0 / 6784.0 * k5 + 11.0 / 84.0 * k6);
    f(s + h, y5, k7);
    st.rhs_evaluations += 6;
    err = h * (71.0 / 57600.0 * k1 - 71.0 / 16695.0 * k3 + 71.0 / 1920.0 * k4 - 17253.0 / 339200.0 * k5 +
               22.0 / 525.0 * k6 - 1.0 / 40.0 * k7);
    const double e = std::sqrt((err.array() / (tol + tol * y.array().abs().max(y5.array().abs()))).square().mean());
    if (!std::isfinite(e)) {
      st.ok = false;
      return st;
    }
    if (e <= 1.0) {
      s += h;
      y = y5;
      k1 = k7;  // first same as last
      ++st.steps;
    } else {
      ++st.rejected_steps;
    }
    const double fac = e == 0.0 ? 5.0 : std::min(5.0, std::max(0.2, 0.9 * std::pow(e, -0.2)));
    h *= fac;
  }
  st.ok = y.allFinite();
  return st;
}

/// Runs the integrator chosen in `settings` from s0 to s1 (Eigen methods only; SUNDIALS methods are
/// dispatched by the caller, which owns their memory).
template <class F, class Vec>
IntegrationStats integrate(const IntegratorOptions& settings, F& f, double s0, double s1, Vec& y) {
  switch (settings.type) {
    case IntegratorType::kRk4: return integrate_rk4(f, s0, s1, settings.steps, y);
    case IntegratorType::kRk8: return integrate_rk8(f, s0, s1, settings.steps, y);
    case IntegratorType::kDopri5: return integrate_dopri5(f, s0, s1, settings.tolerance, settings.max_steps, y);
    default: {
      IntegrationStats st;
      st.ok = false;
      return st;
    }
  }
}

}  // namespace rod
}  // namespace hydrojet
