// Single-shooting kernels for RodTerms<false, false, false> (kirchhoff); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(false, false, false)
