#include "hydrojet_control/control/direction_law.h"

#include <stdexcept>

#include "hydrojet_control/control/modal_law.h"
#include "hydrojet_control/control/papers_law.h"

namespace hydrojet {
namespace control {

const char* to_string(ControlLaw l) { return l == ControlLaw::kModal ? "modal" : "papers"; }

void DirectionLaw::set_pd(const PdOptions& pd) {
  if (std::string err = pd.validate(); !err.empty()) throw std::invalid_argument("pd/" + err);
  pd_options_ = pd;
}

double DirectionLaw::fast_path_weight() const {
  return control::fast_path_weight(pd_.speed(), pd_options_.fast_path_rate);
}

std::unique_ptr<DirectionLaw> make_direction_law(ControlLaw law, const PdOptions& pd, const ModalLawOptions& modal,
                                                 double sample_period) {
  if (law == ControlLaw::kModal) return std::make_unique<ModalLaw>(pd, modal, sample_period);
  return std::make_unique<PapersLaw>(pd);
}

}  // namespace control
}  // namespace hydrojet
