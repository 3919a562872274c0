// The table of compiled model variants (sweep.h) and the choice of the model's variant.
#include "../sweep.h"

namespace hydrojet {
namespace rod {

void RodSolver::select_kernels() {
  using internal::Sweep;
#define HJ_KERNEL(C, W, P, NAME)                                                                              \
  Kernels {                                                                                                   \
    {&Sweep<0, RodTerms<C, W, P>>::run, &Sweep<3, RodTerms<C, W, P>>::run, &Sweep<6, RodTerms<C, W, P>>::run, \
     &Sweep<9, RodTerms<C, W, P>>::run, NAME},                                                                \
  }
  static const Kernels table[8] = {
      HJ_KERNEL(false, false, false, "kirchhoff"),       HJ_KERNEL(false, false, true, "kirchhoff+precurved"),
      HJ_KERNEL(false, true, false, "kirchhoff+weight"), HJ_KERNEL(false, true, true, "kirchhoff+weight+precurved"),
      HJ_KERNEL(true, false, false, "cosserat"),         HJ_KERNEL(true, false, true, "cosserat+precurved"),
      HJ_KERNEL(true, true, false, "cosserat+weight"),   HJ_KERNEL(true, true, true, "cosserat+weight+precurved"),
  };
  static const Kernels general = HJ_KERNEL(true, true, true, "general");
#undef HJ_KERNEL
  if (!options_.specialise_model) {
    kernels_ = &general;
    return;
  }
  const RodTermSet t = needed_terms(model_);
  kernels_ = &table[(t.cosserat ? 4 : 0) + (t.distributed_load ? 2 : 0) + (t.precurved ? 1 : 0)];
}

const char* RodSolver::variant_name() const { return kernels_->name; }

}  // namespace rod
}  // namespace hydrojet
