// The table of compiled kernel variants (see kernel_impl.h) and the choice of the scene's variant.
#include "hydrojet_control/rod/shooting_solver.h"

namespace hydrojet {
namespace rod {

void ShootingSolver::select_kernels() {
#define HJ_KERNEL(C, W, P, NAME)                                                                      \
  Kernels {                                                                                           \
    &ShootingSolver::evaluate_t<RodTerms<C, W, P>>, &ShootingSolver::compliance_t<RodTerms<C, W, P>>, \
        &ShootingSolver::error_t<RodTerms<C, W, P>>, NAME                                             \
  }
  static const Kernels table[8] = {
      HJ_KERNEL(false, false, false, "kirchhoff"),       HJ_KERNEL(false, false, true, "kirchhoff+precurved"),
      HJ_KERNEL(false, true, false, "kirchhoff+weight"), HJ_KERNEL(false, true, true, "kirchhoff+weight+precurved"),
      HJ_KERNEL(true, false, false, "cosserat"),         HJ_KERNEL(true, false, true, "cosserat+precurved"),
      HJ_KERNEL(true, true, false, "cosserat+weight"),   HJ_KERNEL(true, true, true, "cosserat+weight+precurved"),
  };
  static const Kernels general = HJ_KERNEL(true, true, true, "general");
#undef HJ_KERNEL
  if (!settings_.specialize_model) {
    kernels_ = &general;
    return;
  }
  const RodTermSet t = needed_terms(model_);
  kernels_ = &table[(t.cosserat ? 4 : 0) + (t.distributed_load ? 2 : 0) + (t.precurved ? 1 : 0)];
}

const char* ShootingSolver::variant_name() const { return kernels_->name; }

}  // namespace rod
}  // namespace hydrojet
