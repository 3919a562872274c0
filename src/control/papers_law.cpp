#include "hydrojet_control/control/papers_law.h"

#include <stdexcept>

namespace hydrojet {
namespace control {

PapersLaw::PapersLaw(const PdOptions& pd) { set_pd(pd); }

void PapersLaw::set_pd(const PdOptions& pd) {
  if (std::string err = pd.validate(); !err.empty()) throw std::invalid_argument("pd/" + err);
  options_ = pd;
}

double PapersLaw::fast_path_weight() const { return control::fast_path_weight(pd_.speed(), options_.fast_path_rate); }

}  // namespace control
}  // namespace hydrojet
