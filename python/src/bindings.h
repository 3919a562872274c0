// Shared pieces of the hydrojet._core bindings: conversions between the core's bounded input
// vectors and numpy, and the checks that turn bad input into ValueError naming the argument.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace python {

namespace nb = nanobind;

/// The core's input vector (bounded size) as a numpy-convertible dynamic vector.
inline Eigen::VectorXd to_dynamic(const rod::InputVector& q) { return Eigen::VectorXd(q); }

/// A numpy vector as the core's input vector: `n` finite entries, else ValueError naming `what`.
inline rod::InputVector to_inputs(const Eigen::VectorXd& v, int n, const std::string& what) {
  if (v.size() != n)
    throw std::invalid_argument(what + ": expects " + std::to_string(n) + " entries, got " + std::to_string(v.size()));
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(v[i]))
      throw std::invalid_argument(what + "[" + std::to_string(i) + "]: must be finite, got " + std::to_string(v[i]));
  return rod::InputVector(v);
}

/// A numpy vector as the core's input vector, as it is (sensor readings may be anything the rig can
/// send), but no longer than the core's bound kMaxInputs; else ValueError naming `what`.
inline rod::InputVector to_bounded(const Eigen::VectorXd& v, const std::string& what) {
  if (v.size() > rod::kMaxInputs)
    throw std::invalid_argument(what + ": at most " + std::to_string(rod::kMaxInputs) + " entries, got " +
                                std::to_string(v.size()));
  return rod::InputVector(v);
}

/// A finite time [s], else ValueError naming `what`.
inline double finite_time(double t, const std::string& what) {
  if (!std::isfinite(t)) throw std::invalid_argument(what + ": must be a finite time in seconds");
  return t;
}

/// A finite 3-vector, else ValueError naming `what`.
inline rod::Vec3 finite3(const rod::Vec3& v, const std::string& what) {
  if (!v.allFinite()) throw std::invalid_argument(what + ": must be finite");
  return v;
}

void bind_scene(nb::module_& m);
void bind_loop(nb::module_& m);
void bind_env(nb::module_& m);

}  // namespace python
}  // namespace hydrojet
