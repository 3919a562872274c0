// Names of the integrators (integrators.h), as the configuration files and tools spell them.
#include "hydrojet_control/rod/integrators.h"

namespace hydrojet {
namespace rod {

const char* integrator_name(IntegratorType t) {
  switch (t) {
    case IntegratorType::kRk4: return "rk4";
    case IntegratorType::kRk8: return "rk8";
    case IntegratorType::kDopri5: return "dopri5";
    case IntegratorType::kCvodeAdams: return "cvode-adams";
    case IntegratorType::kCvodeBdf: return "cvode-bdf";
  }
  return "unknown";
}

const char* integrator_names() { return "rk4, rk8, dopri5, cvode-adams, cvode-bdf"; }

bool parse_integrator(const std::string& name, IntegratorType* out) {
  for (IntegratorType t : {IntegratorType::kRk4, IntegratorType::kRk8, IntegratorType::kDopri5,
                           IntegratorType::kCvodeAdams, IntegratorType::kCvodeBdf}) {
    if (name == integrator_name(t)) {
      *out = t;
      return true;
    }
  }
  return false;
}

}  // namespace rod
}  // namespace hydrojet
